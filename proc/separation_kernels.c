/* The separation's hot fold loops, kept apart so they can be built for the auto-vectoriser
 * (proc/CMakeLists.txt) and, on x86-64, also for AVX2, picked at load time: frames fold at
 * memory speed. Contiguous arrays, restrict pointers, selects instead of branches. */
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
ds_fold_average_row (const float *restrict v, double *restrict ps, float *restrict rm,
                     gboolean first_of_phase, gboolean first_of_set, gsize w)
{
  for (gsize x = 0; x < w; x++) {
    ps[x] = (first_of_phase ? 0.0 : ps[x]) + v[x];
    rm[x] = first_of_set || v[x] > rm[x] ? v[x] : rm[x];
  }
}

DS_CLONES void
ds_or_mask_row (guint8 *restrict mk, const guint8 *restrict flags, gsize w)
{
  for (gsize x = 0; x < w; x++)
    mk[x] |= flags[x];
}

DS_CLONES_WIDE void
ds_maxmin_fast_row (const guint16 *restrict hi, const guint16 *restrict lo,
                    const float *restrict dark, float *restrict t, float *restrict g,
                    guint8 *restrict mk, gsize w, const DsMaxminFast *k)
{
  const float inv1b = k->inv1b, b = k->b, invm = k->invm, m = k->m;
  const float sat = k->sat, floor_ = k->floor, lowmod = k->lowmod, exceed = k->exceed;
  for (gsize x = 0; x < w; x++) {
    float h = hi[x], l = lo[x], d = dark[x];
    float ld = (h - l) * inv1b;
    float lg = ((l - d) - b * ld) * invm;
    float mean = m * (ld + lg);
    guint8 bits = (guint8) ((h >= sat ? DS_MASK_SATURATED : 0) | (d - l > exceed ? DS_MASK_DARK_EXCEEDS : 0) |
                            (mean <= floor_ ? DS_MASK_DARK : 0) |
                            (h - l < lowmod ? DS_MASK_LOW_MODULATION : 0) |
                            (lg < 0 ? DS_MASK_NEGATIVE : 0));
    t[x] = ld;
    g[x] = lg;
    mk[x] = bits;
  }
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
