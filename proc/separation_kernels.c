/* The separation's hot fold loops, kept apart so they can be built for the auto-vectoriser
 * (proc/CMakeLists.txt) and, on x86-64, also for AVX2, picked at load time: frames fold at
 * memory speed. Contiguous arrays, restrict pointers, selects instead of branches. */
#include <float.h>
#include <math.h>
#include <string.h>

#include "proc/separation_internal.h"
#include "proc/simd.h"

#define DEFINE_INT_KERNELS(T, NAME)                                                               \
  DS_CLONES void ds_fold_first_##NAME (const T *restrict in, guint16 *restrict mx,                \
                                       guint16 *restrict mn, guint32 *restrict sum, gsize w)      \
  {                                                                                               \
    for (gsize x = 0; x < w; x++)                                                                 \
      mx[x] = mn[x] = in[x];                                                                      \
    if (sum)                                                                                      \
      for (gsize x = 0; x < w; x++)                                                               \
        sum[x] = in[x];                                                                           \
  }                                                                                               \
  DS_CLONES void ds_fold_extrema_##NAME (const T *restrict in, guint16 *restrict mx,              \
                                         guint16 *restrict mn, gsize w)                           \
  {                                                                                               \
    for (gsize x = 0; x < w; x++) {                                                               \
      guint16 v = in[x];                                                                          \
      mx[x] = v > mx[x] ? v : mx[x];                                                              \
      mn[x] = v < mn[x] ? v : mn[x];                                                              \
    }                                                                                             \
  }                                                                                               \
  DS_CLONES void ds_fold_extrema_sum_##NAME (const T *restrict in, guint16 *restrict mx,          \
                                             guint16 *restrict mn, guint32 *restrict sum,         \
                                             gsize w)                                             \
  {                                                                                               \
    for (gsize x = 0; x < w; x++) {                                                               \
      guint16 v = in[x];                                                                          \
      mx[x] = v > mx[x] ? v : mx[x];                                                              \
      mn[x] = v < mn[x] ? v : mn[x];                                                              \
      sum[x] += v;                                                                                \
    }                                                                                             \
  }                                                                                               \
  DS_CLONES_WIDE void ds_fold_harmonic_fix_##NAME (const T *restrict in, gint32 c, gint32 s,     \
                                                   gint64 *restrict cs, gint64 *restrict sn,      \
                                                   gboolean first, gsize w)                       \
  {                                                                                               \
    /* 32 x 32 -> 64-bit products: one widening multiply per lane */                             \
    if (first)                                                                                    \
      for (gsize x = 0; x < w; x++) {                                                             \
        cs[x] = (gint64) c * (gint32) in[x];                                                      \
        sn[x] = (gint64) s * (gint32) in[x];                                                      \
      }                                                                                           \
    else                                                                                          \
      for (gsize x = 0; x < w; x++) {                                                             \
        cs[x] += (gint64) c * (gint32) in[x];                                                     \
        sn[x] += (gint64) s * (gint32) in[x];                                                     \
      }                                                                                           \
  }                                                                                               \
  DS_CLONES_WIDE void ds_fold_harmonic_##NAME (const T *restrict in, double c, double s,           \
                                               double *restrict cs, double *restrict sn,          \
                                               gboolean first, gsize w)                           \
  {                                                                                               \
    if (first)                                                                                    \
      for (gsize x = 0; x < w; x++) {                                                             \
        cs[x] = c * in[x];                                                                        \
        sn[x] = s * in[x];                                                                        \
      }                                                                                           \
    else                                                                                          \
      for (gsize x = 0; x < w; x++) {                                                             \
        cs[x] += c * in[x];                                                                       \
        sn[x] += s * in[x];                                                                       \
      }                                                                                           \
  }                                                                                               \
  DS_CLONES void ds_fold_sumsq_##NAME (const T *restrict in, double *restrict sq, gboolean first, \
                                       gsize w)                                                   \
  {                                                                                               \
    if (first)                                                                                    \
      for (gsize x = 0; x < w; x++)                                                               \
        sq[x] = (double) in[x] * in[x];                                                           \
    else                                                                                          \
      for (gsize x = 0; x < w; x++)                                                               \
        sq[x] += (double) in[x] * in[x];                                                          \
  }                                                                                               \
  DS_CLONES void ds_copy_plane_##NAME (const T *restrict in, float *restrict out, gsize w)        \
  {                                                                                               \
    for (gsize x = 0; x < w; x++)                                                                 \
      out[x] = in[x];                                                                             \
  }                                                                                               \
  DS_CLONES void ds_widen_##NAME (const T *restrict in, guint16 *restrict out, gsize w)           \
  {                                                                                               \
    for (gsize x = 0; x < w; x++)                                                                 \
      out[x] = in[x];                                                                             \
  }

DEFINE_INT_KERNELS (guint8, u8)
DEFINE_INT_KERNELS (guint16, u16)

/* Float input: NaN and Inf are replaced by 0 in the sums and flagged, so one bad sample
 * cannot poison the arithmetic (the pixel's outputs are then 0, see docs/estimators.md). */
DS_CLONES void
ds_clean_row_f32 (const float *restrict in, float *restrict out, guint8 *restrict nf, gboolean first,
                  gsize w)
{
  for (gsize x = 0; x < w; x++) {
    float v = in[x];
    guint8 bad = !isfinite (v);
    out[x] = bad ? 0.0f : v;
    nf[x] = first ? bad : (guint8) (nf[x] | bad);
  }
}

DS_CLONES void
ds_fold_float_row (const float *restrict v, float *restrict mx, float *restrict mn,
                   double *restrict sum, gboolean first, gsize w)
{
  if (first) {
    for (gsize x = 0; x < w; x++) {
      mx[x] = mn[x] = v[x];
      sum[x] = v[x];
    }
    return;
  }
  for (gsize x = 0; x < w; x++) {
    mx[x] = v[x] > mx[x] ? v[x] : mx[x];
    mn[x] = v[x] < mn[x] ? v[x] : mn[x];
    sum[x] += v[x];
  }
}

DS_CLONES_WIDE void
ds_fold_harmonic_f32 (const float *restrict v, double c, double s, double *restrict cs,
                      double *restrict sn, gboolean first, gsize w)
{
  if (first)
    for (gsize x = 0; x < w; x++) {
      cs[x] = c * v[x];
      sn[x] = s * v[x];
    }
  else
    for (gsize x = 0; x < w; x++) {
      cs[x] += c * v[x];
      sn[x] += s * v[x];
    }
}

DS_CLONES void
ds_fold_sumsq_f32 (const float *restrict v, double *restrict sq, gboolean first, gsize w)
{
  if (first)
    for (gsize x = 0; x < w; x++)
      sq[x] = (double) v[x] * v[x];
  else
    for (gsize x = 0; x < w; x++)
      sq[x] += (double) v[x] * v[x];
}

DS_CLONES void
ds_fold_average_row (const float *restrict v, double *restrict ps, float *restrict rm,
                     gboolean first_of_phase, gboolean first_of_set, gsize w)
{
  for (gsize x = 0; x < w; x++) {
    ps[x] = (first_of_phase ? 0.0 : ps[x]) + v[x];
    rm[x] = first_of_set || v[x] > rm[x] ? v[x] : rm[x];
  }
}

/* maxmin on the integer fast path, one row: the outputs, the mask and its counts in one pass. src selects where the extrema come from: the set's state (finalize),
 * or the state and the set's last frame, u16 or u8 (the last frame folded and finalized at
 * once, its extrema written back so that the state is what folding it would leave). The
 * callers pass constants for src and has_dark: each combination is its own loop, with no test
 * per pixel. Every test is a compare turned into a bit; the counts are vector sums. */
enum { FAST_FROM_STATE, FAST_FROM_U16, FAST_FROM_U8 };

DS_KERNEL void
maxmin_fast_kernel (int src, int has_dark, guint16 *restrict hi, guint16 *restrict lo,
                    const void *restrict in, const float *restrict dark, float *restrict t, float *restrict g,
                    guint8 *restrict mk, gsize w, const DsMaxminFast *k,
                    guint64 counts[DS_MASK_N_BITS + 1])
{
  const float inv1b = k->inv1b, b = k->b, invm = k->invm, m = k->m;
  const float sat = k->sat, floor_ = k->floor, lowmod = k->lowmod, exceed = k->exceed;
  const guint16 *in16 = in;
  const guint8 *in8 = in;
  guint32 c_ok = 0, c_sat = 0, c_dark = 0, c_low = 0, c_neg = 0, c_exc = 0;
  for (gsize x = 0; x < w; x++) {
    guint16 hv = hi[x], lv = lo[x];
    if (src != FAST_FROM_STATE) {
      guint16 v = src == FAST_FROM_U16 ? in16[x] : in8[x];
      hv = v > hv ? v : hv;
      lv = v < lv ? v : lv;
      hi[x] = hv;
      lo[x] = lv;
    }
    float h = hv, l = lv, d = has_dark ? dark[x] : 0.0f;
    float ld = (h - l) * inv1b;
    float lg = ((l - d) - b * ld) * invm;
    float mean = m * (ld + lg);
    /* each count from its test, not from the bits: one add per test */
    guint32 is_sat = h >= sat, is_dark = mean <= floor_, is_low = h - l < lowmod, is_neg = lg < 0;
    guint32 is_exc = d - l > exceed;
    guint32 bits = is_sat | (is_dark << 1) | (is_low << 2) | (is_neg << 4) | (is_exc << 5);
    t[x] = ld;
    g[x] = lg;
    mk[x] = (guint8) bits;
    c_ok += bits == 0;
    c_sat += is_sat;
    c_dark += is_dark;
    c_low += is_low;
    c_neg += is_neg;
    c_exc += is_exc;
  }
  counts[0] += c_ok;
  counts[1] += c_sat;
  counts[2] += c_dark;
  counts[3] += c_low;
  /* counts[4]: NONFINITE, never set on integer input */
  counts[5] += c_neg;
  counts[6] += c_exc;
}

/* The column flags (DS_MASK_UNDERSAMPLED or 0) or-ed into a counted mask row, the counts
 * corrected. A pass of its own over the row (still in L1): a byte read per pixel in the
 * kernel above would make GCC work on 64 pixels at a time and spill its registers. */
DS_KERNEL void
or_flags_kernel (guint8 *restrict mk, const guint8 *restrict flags, gsize w,
                 guint64 counts[DS_MASK_N_BITS + 1])
{
  guint32 lost = 0, under = 0;
  for (gsize x = 0; x < w; x++) {
    guint32 f = flags[x] >> 6;
    lost += (guint32) (mk[x] == 0) & f;
    under += f;
    mk[x] |= flags[x];
  }
  counts[0] -= lost;
  counts[7] += under;
}

DS_CLONES_WIDE void
ds_maxmin_fast_row (const DsMaxminFastRow *r, gsize w, const DsMaxminFast *k,
                    guint64 counts[DS_MASK_N_BITS + 1])
{
  /* counts[8]: MOTION, never judged on this path (detect_motion takes the general one) */
  G_STATIC_ASSERT (DS_MASK_N_BITS == 8);
  int src = r->in16 ? FAST_FROM_U16 : r->in8 ? FAST_FROM_U8 : FAST_FROM_STATE;
  const void *in = r->in16 ? (const void *) r->in16 : (const void *) r->in8;
#define FAST_CALL(SRC, DARK)                                                                        \
  maxmin_fast_kernel (SRC, DARK, r->hi, r->lo, in, r->dark, r->t, r->g, r->mk, w, k, counts)
  if (r->dark) {
    if (src == FAST_FROM_U16)
      FAST_CALL (FAST_FROM_U16, 1);
    else if (src == FAST_FROM_U8)
      FAST_CALL (FAST_FROM_U8, 1);
    else
      FAST_CALL (FAST_FROM_STATE, 1);
  } else {
    if (src == FAST_FROM_U16)
      FAST_CALL (FAST_FROM_U16, 0);
    else if (src == FAST_FROM_U8)
      FAST_CALL (FAST_FROM_U8, 0);
    else
      FAST_CALL (FAST_FROM_STATE, 0);
  }
#undef FAST_CALL
  if (r->flags)
    or_flags_kernel (r->mk, r->flags, w, counts);
}

/* A fixed-point harmonic sum as a float, from its two 32-bit halves (x86-64 before AVX-512 has
 * no vector conversion from 64-bit integers): v = hi 2^32 + lo, lo unsigned, converted as the
 * signed lo - 2^31. Within a few units of 2^-24 |v| plus 2^8 (2^-22 DN after the 2^-30 scale). */
DS_KERNEL float
fix_to_float (gint64 v)
{
  gint32 hi = (gint32) ((guint64) v >> 32);
  gint32 lo = (gint32) ((guint32) v ^ 0x80000000u);
  return (float) hi * 4294967296.0f + ((float) lo + 2147483648.0f);
}

DS_KERNEL void
sine_fast_kernel (int has_dark, int has_count, const gint64 *restrict c64, const gint64 *restrict s64,
                  const guint16 *restrict hi, const guint16 *restrict lo, const guint8 *restrict satn,
                  const guint32 *restrict sum,
                  const float *restrict dark, float *restrict t, float *restrict g, guint8 *restrict mk,
                  gsize w, const DsSineFast *k, guint64 counts[DS_MASK_N_BITS + 1])
{
  const float two_n = k->two_n, inv_n = k->inv_n, inv_h = k->inv_h, inv_m = k->inv_m;
  const float sat = k->sat, floor_ = k->floor, lowamp = k->lowamp, exceed = k->exceed;
  const float scale = 1.0f / (float) (1u << DS_HARMONIC_FIX_BITS);
  guint32 c_ok = 0, c_sat = 0, c_dark = 0, c_low = 0, c_nf = 0, c_neg = 0, c_exc = 0;
  for (gsize x = 0; x < w; x++) {
    float cs = fix_to_float (c64[x]) * scale, sn = fix_to_float (s64[x]) * scale;
    float a = two_n * sqrtf (cs * cs + sn * sn);
    float d = has_dark ? dark[x] : 0.0f;
    float mean = (float) (gint32) sum[x] * inv_n - d;
    float ld = a * inv_h;
    float lg = mean * inv_m - ld;
    /* the general tail's tests (separation_rows.c), each a compare turned into a bit. The max
     * is at least sat exactly when some sample is (counted in satn). Without a dark frame
     * d - l = -l <= 0 <= exceed (a non-negative quantile times a standard deviation): the
     * minimum cannot set DARK_EXCEEDS and is not read. */
    guint32 is_sat = has_count ? (guint32) (satn[x] != 0) : (guint32) ((float) hi[x] >= sat);
    guint32 is_dark = mean <= floor_, is_low = a < lowamp;
    guint32 is_neg = (ld < 0) | (lg < 0);
    guint32 is_exc = has_dark ? (guint32) (d - (float) lo[x] > exceed) : 0u;
    guint32 ok = (fabsf (ld) <= FLT_MAX) & (fabsf (lg) <= FLT_MAX);
    guint32 bits = is_sat | (is_dark << 1) | (is_low << 2) | (is_neg << 4) | (is_exc << 5);
    guint32 keep = 0u - ok;
    mk[x] = (guint8) ((bits & keep) | (DS_MASK_NONFINITE & ~keep));
    t[x] = ok ? ld : 0.0f;
    g[x] = ok ? lg : 0.0f;
    c_ok += (bits == 0) & ok;
    c_sat += is_sat & ok;
    c_dark += is_dark & ok;
    c_low += is_low & ok;
    c_nf += ok ^ 1u;
    c_neg += is_neg & ok;
    c_exc += is_exc & ok;
  }
  counts[0] += c_ok;
  counts[1] += c_sat;
  counts[2] += c_dark;
  counts[3] += c_low;
  counts[4] += c_nf;
  counts[5] += c_neg;
  counts[6] += c_exc;
}

/* Column flags into a counted mask row, but not where the pixel is NONFINITE (the general
 * tail gives such a pixel that bit alone). */
DS_KERNEL void
or_flags_finite_kernel (guint8 *restrict mk, const guint8 *restrict flags, gsize w,
                        guint64 counts[DS_MASK_N_BITS + 1])
{
  guint32 lost = 0, under = 0;
  for (gsize x = 0; x < w; x++) {
    guint32 f = (guint32) (flags[x] >> 6) & (guint32) (mk[x] != DS_MASK_NONFINITE);
    lost += (guint32) (mk[x] == 0) & f;
    under += f;
    mk[x] |= (guint8) (f << 6);
  }
  counts[0] -= lost;
  counts[7] += under;
}

DS_CLONES_WIDE void
ds_sine_fast_row (const DsSineFastRow *r, gsize w, const DsSineFast *k,
                  guint64 counts[DS_MASK_N_BITS + 1])
{
  G_STATIC_ASSERT (DS_MASK_UNDERSAMPLED == 1 << 6 && DS_MASK_NONFINITE == 1 << 3);
  if (r->dark && r->satn)
    sine_fast_kernel (1, 1, r->c64, r->s64, NULL, r->lo, r->satn, r->sum, r->dark, r->t, r->g, r->mk, w, k, counts);
  else if (r->dark)
    sine_fast_kernel (1, 0, r->c64, r->s64, r->hi, r->lo, NULL, r->sum, r->dark, r->t, r->g, r->mk, w, k, counts);
  else if (r->satn)
    sine_fast_kernel (0, 1, r->c64, r->s64, NULL, NULL, r->satn, r->sum, NULL, r->t, r->g, r->mk, w, k, counts);
  else
    sine_fast_kernel (0, 0, r->c64, r->s64, r->hi, NULL, NULL, r->sum, NULL, r->t, r->g, r->mk, w, k, counts);
  if (r->flags)
    or_flags_finite_kernel (r->mk, r->flags, w, counts);
}

/* Eight mask bytes at a time: most pixels of a usable image carry no flag, and a word of eight
 * clear bytes is one test; otherwise each bit's count is the population count of that bit of the
 * eight bytes. (Counting byte by byte cost more than the whole maxmin row.) */
DS_CLONES_WIDE void
ds_count_mask_row (const guint8 *restrict mk, gsize w, guint64 counts[DS_MASK_N_BITS + 1])
{
  const guint64 ones = 0x0101010101010101ull;
  guint64 c[DS_MASK_N_BITS + 1] = { 0 };
  gsize x = 0;
  for (; x + 8 <= w; x += 8) {
    guint64 v;
    memcpy (&v, mk + x, 8);
    if (v == 0) {
      c[0] += 8;
      continue;
    }
    /* Bit 0 of each byte becomes the OR of its eight bits (masks keep bytes apart). */
    guint64 any = v | ((v >> 4) & 0x0f0f0f0f0f0f0f0full);
    any |= (any >> 2) & 0x3333333333333333ull;
    any |= (any >> 1) & 0x5555555555555555ull;
    c[0] += 8 - (guint64) __builtin_popcountll (any & ones);
    for (int b = 0; b < DS_MASK_N_BITS; b++)
      c[1 + b] += (guint64) __builtin_popcountll ((v >> b) & ones);
  }
  for (; x < w; x++) {
    guint8 v = mk[x];
    c[0] += v == 0;
    for (int b = 0; b < DS_MASK_N_BITS; b++)
      c[1 + b] += (v >> b) & 1;
  }
  for (int i = 0; i <= DS_MASK_N_BITS; i++)
    counts[i] += c[i];
}
