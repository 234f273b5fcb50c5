/* The finalize's row kernels (separation_rows.h): load, estimator, common tail. */
#include <float.h>
#include <math.h>
#include <string.h>

#include "proc/separation_rows.h"
#include "proc/separation_internal.h"

void
ds_row_buffers_init (DsRowBuffers *rb, double *s, gsize w)
{
  double **planes[] = { &rb->hi_raw, &rb->lo_raw, &rb->mean_raw, &rb->rmax, &rb->ld, &rb->lg,
                        &rb->lev_hi, &rb->lev_lo, &rb->amp, &rb->mean, &rb->cs, &rb->sn,
                        &rb->best_hi, &rb->best_lo };
  gsize i = 0;
  for (; i < G_N_ELEMENTS (planes); i++)
    *planes[i] = s + i * w;
  rb->start_hi = (guint32 *) (s + i++ * w); /* two u32 rows in one double row */
  rb->start_lo = rb->start_hi + w;
  rb->dark_zero = (float *) (s + i++ * w);  /* half a row: w floats */
  for (guint k = 0; k < G_N_ELEMENTS (rb->sink); k++)
    rb->sink[k] = (float *) (s + i * w) + k * w; /* 5 float rows in 2.5 double rows */
  i += 3;
  rb->bad = (guint8 *) (s + i++ * w); /* four u8 rows in one double row */
  rb->flags_zero = rb->bad + w;
  rb->motion = rb->bad + 2 * w;
  rb->flags = rb->bad + 3 * w;
  rb->sumsq = s + i++ * w;
  g_assert (i == DS_ROW_DOUBLES);
  memset (rb->dark_zero, 0, w * sizeof (float));
  memset (rb->flags_zero, 0, w);
}

DS_KERNEL void
load_fast (const guint16 *restrict mx, const guint16 *restrict mn, double *restrict hi,
           double *restrict lo, double *restrict rm, guint8 *restrict bad, gsize w)
{
  for (gsize x = 0; x < w; x++) {
    hi[x] = rm[x] = mx[x];
    lo[x] = mn[x];
    bad[x] = 0; /* integer input, integer dark: always finite */
  }
}

DS_KERNEL void
load_mean (const guint32 *restrict sum, double dn, double *restrict me, gsize w)
{
  for (gsize x = 0; x < w; x++)
    me[x] = sum[x] / dn;
}

DS_KERNEL void
fill_nan (double *restrict v, gsize w)
{
  for (gsize x = 0; x < w; x++)
    v[x] = NAN;
}

DS_CLONES_WIDE void
ds_row_load_fast (const guint16 *mx, const guint16 *mn, const guint32 *sum, guint n,
                  DsRowBuffers *rb, gsize w)
{
  load_fast (mx, mn, rb->hi_raw, rb->lo_raw, rb->rmax, rb->bad, w);
  if (sum)
    load_mean (sum, n, rb->mean_raw, w);
  else
    fill_nan (rb->mean_raw, w);
}

DS_KERNEL void
load_float_extrema (const float *restrict mx, const float *restrict mn, const double *restrict sum,
                    double dn, double *restrict hi, double *restrict lo, double *restrict me, gsize w)
{
  for (gsize x = 0; x < w; x++) {
    hi[x] = mx[x];
    lo[x] = mn[x];
    me[x] = sum[x] / dn;
  }
}

DS_KERNEL void
load_bad (const guint8 *restrict nonfinite, const float *restrict dark, guint8 *restrict bad, gsize w)
{
  for (gsize x = 0; x < w; x++)
    bad[x] = (guint8) (nonfinite[x] | !isfinite (dark[x]));
}

DS_CLONES_WIDE void
ds_row_load_float (const float *mx, const float *mn, const double *sum, const float *rawmax,
                   const guint8 *nonfinite, guint n, const float *dark, DsRowBuffers *rb, gsize w)
{
  if (mx)
    load_float_extrema (mx, mn, sum, n, rb->hi_raw, rb->lo_raw, rb->mean_raw, w);
  /* the raw maximum: the largest sample (averaging), or the largest phase value */
  if (rawmax)
    for (gsize x = 0; x < w; x++)
      rb->rmax[x] = rawmax[x];
  else if (mx)
    memcpy (rb->rmax, rb->hi_raw, w * sizeof (double));
  load_bad (nonfinite ? nonfinite : rb->flags_zero, dark, rb->bad, w);
}

DS_KERNEL void
maxmin_row (double inv1b, double b, double m, const double *restrict hr, const double *restrict lr,
            const double *restrict mr, const float *restrict d, double *restrict ld,
            double *restrict lg, double *restrict lh, double *restrict ll, double *restrict me,
            double *restrict amp, gsize w)
{
  for (gsize x = 0; x < w; x++) {
    double hi = hr[x] - d[x], lo = lr[x] - d[x];
    double t = (hi - lo) * inv1b;
    double g = (lo - b * t) / m;
    ld[x] = t;
    lg[x] = g;
    lh[x] = hi;
    ll[x] = lo;
    amp[x] = 0;
    /* without a kept sum, the model mean m (Ld + Lg) */
    me[x] = isnan (mr[x]) ? m * (t + g) : mr[x] - d[x];
  }
}

DS_CLONES_WIDE void
ds_row_maxmin (const DsRowConsts *c, const float *dark, DsRowBuffers *rb, gsize w)
{
  maxmin_row (c->inv1b, c->b, c->m, rb->hi_raw, rb->lo_raw, rb->mean_raw, dark, rb->ld, rb->lg,
              rb->lev_hi, rb->lev_lo, rb->mean, rb->amp, w);
}

DS_KERNEL void
from_fix (const gint64 *restrict c64, const gint64 *restrict s64, double scale, double *restrict cs,
          double *restrict sn, gsize w)
{
  for (gsize x = 0; x < w; x++) {
    cs[x] = (double) c64[x] * scale;
    sn[x] = (double) s64[x] * scale;
  }
}

DS_CLONES_WIDE void
ds_row_harmonic_from_fix (const gint64 *c64, const gint64 *s64, guint bits, DsRowBuffers *rb, gsize w)
{
  from_fix (c64, s64, ldexp (1.0, -(int) bits), rb->cs, rb->sn, w);
}

DS_KERNEL void
sine_row (double k, double h, double m, const double *restrict cs, const double *restrict sn,
          const double *restrict mr, const float *restrict d, double *restrict ld,
          double *restrict lg, double *restrict lh, double *restrict ll, double *restrict me,
          double *restrict amp, gsize w)
{
  for (gsize x = 0; x < w; x++) {
    double a = k * sqrt (cs[x] * cs[x] + sn[x] * sn[x]);
    double mean = mr[x] - d[x];
    amp[x] = a;
    me[x] = mean;
    ld[x] = a / h;
    lg[x] = mean / m - a / h;
    lh[x] = ll[x] = 0;
  }
}

DS_CLONES_WIDE void
ds_row_sine (const DsRowConsts *c, const double *cs, const double *sn, const float *dark,
             DsRowBuffers *rb, gsize w)
{
  sine_row (2.0 / c->n, c->h, c->m, cs, sn, rb->mean_raw, dark, rb->ld, rb->lg, rb->lev_hi,
            rb->lev_lo, rb->mean, rb->amp, w);
}

DS_KERNEL void
motion_row (double n, double mean_scale, double kappa, double chi2, int model, double read_var,
            double gain, double inv_mf, double data_var, const double *restrict sq,
            const double *restrict sm, const double *restrict cs, const double *restrict sn,
            const double *restrict hr, const float *restrict d, guint8 *restrict out, gsize w)
{
  const double two_n = 2.0 / n;
  for (gsize x = 0; x < w; x++) {
    double mean = sm[x] * mean_scale;
    double h1 = two_n * (cs[x] * cs[x] + sn[x] * sn[x]);
    double e = sq[x] - n * mean * mean - h1;
    double sig = hr[x] - d[x];
    /* the largest sample's variance bounds every sample's (noise grows with the signal) */
    double var = model ? (read_var + gain * (sig > 0 ? sig : 0)) * inv_mf : data_var;
    double bound = sqrt (kappa * h1) + sqrt (chi2 * var);
    /* E is a difference of sums of squares: its rounding, ~1e-16 of them, must not count as
     * departure when there is no noise at all (noise-free or synthetic frames) */
    out[x] = (guint8) ((e > bound * bound + 1e-12 * sq[x]) << 7);
  }
}

DS_CLONES_WIDE void
ds_row_motion (const DsRowConsts *c, const double *sumsq, const double *sum_or_mean, double mean_scale,
               const double *cs, const double *sn, const float *dark, DsRowBuffers *rb, gsize w)
{
  G_STATIC_ASSERT (DS_MASK_MOTION == 1 << 7);
  motion_row (c->n, mean_scale, c->motion_kappa, c->motion_chi2, c->model, c->read_var, c->gain,
              1.0 / c->m_frames, c->data_var_phase, sumsq, sum_or_mean, cs, sn, rb->hi_raw, dark,
              rb->motion, w);
}

DS_CLONES void
ds_row_or_motion (const guint8 *restrict motion, guint8 *restrict mk, gsize w, guint64 counts[DS_MASK_N_BITS + 1])
{
  guint32 lost = 0, moved = 0;
  for (gsize x = 0; x < w; x++) {
    guint8 m = (mk[x] & (DS_MASK_SATURATED | DS_MASK_DARK)) ? 0 : motion[x];
    lost += (guint32) ((mk[x] == 0) & (m != 0));
    moved += (guint32) (m != 0);
    mk[x] |= m;
  }
  counts[0] -= lost;
  counts[1 + 7] += moved;
}

const guint8 *
ds_row_motion_flags (DsRowBuffers *rb, const guint8 *column_flags, gsize w)
{
  const guint8 *cf = column_flags ? column_flags : rb->flags_zero;
  for (gsize x = 0; x < w; x++)
    rb->flags[x] = cf[x] | rb->motion[x];
  return rb->flags;
}

/* robust with motion: the phase values' sum of squares. */
#define DEFINE_ROBUST_SUMSQ(T, NAME)                                                              \
  DS_KERNEL void robust_sumsq_##NAME (const T *restrict v, double *restrict sq, gsize w)          \
  {                                                                                               \
    for (gsize x = 0; x < w; x++)                                                                 \
      sq[x] += (double) v[x] * v[x];                                                              \
  }
DEFINE_ROBUST_SUMSQ (guint16, u16)
DEFINE_ROBUST_SUMSQ (float, f32)

/* robust, step 1: one phase plane's row into the harmonic, sum and extrema. */
#define DEFINE_ROBUST_ACCUMULATE(T, NAME)                                                         \
  DS_KERNEL void robust_accumulate_##NAME (const T *restrict v, double ck, double sk,             \
                                           double *restrict cs, double *restrict sn,              \
                                           double *restrict sum, double *restrict hi,             \
                                           double *restrict lo, gsize w)                          \
  {                                                                                               \
    for (gsize x = 0; x < w; x++) {                                                               \
      double e = v[x];                                                                            \
      cs[x] += e * ck;                                                                            \
      sn[x] += e * sk;                                                                            \
      sum[x] += e;                                                                                \
      hi[x] = e > hi[x] ? e : hi[x];                                                              \
      lo[x] = e < lo[x] ? e : lo[x];                                                              \
    }                                                                                             \
  }
DEFINE_ROBUST_ACCUMULATE (guint16, u16)
DEFINE_ROBUST_ACCUMULATE (float, f32)

/* robust, step 3: the window sums (k - start wrapped to 0..n-1 in unsigned arithmetic). */
#define DEFINE_ROBUST_WINDOWS(T, NAME)                                                            \
  DS_KERNEL void robust_windows_##NAME (const T *restrict v, guint32 k, guint32 n, guint32 len_hi, \
                                        guint32 len_lo, const guint32 *restrict sh,               \
                                        const guint32 *restrict sl, double *restrict wh,          \
                                        double *restrict wl, gsize w)                             \
  {                                                                                               \
    for (gsize x = 0; x < w; x++) {                                                               \
      double e = v[x];                                                                            \
      guint32 dh = k - sh[x], dl = k - sl[x];                                                     \
      dh += dh >= n ? n : 0;                                                                      \
      dl += dl >= n ? n : 0;                                                                      \
      wh[x] += dh < len_hi ? e : 0.0;                                                             \
      wl[x] += dl < len_lo ? e : 0.0;                                                             \
    }                                                                                             \
  }
DEFINE_ROBUST_WINDOWS (guint16, u16)
DEFINE_ROBUST_WINDOWS (float, f32)

DS_KERNEL void
robust_reset (double *restrict cs, double *restrict sn, double *restrict sum, double *restrict hi,
              double *restrict lo, gsize w)
{
  for (gsize x = 0; x < w; x++) {
    cs[x] = sn[x] = sum[x] = 0;
    hi[x] = -INFINITY;
    lo[x] = INFINITY;
  }
}

/* robust, step 2: the window whose centre is nearest the harmonic's phase (ds_robust_start:
 * largest projection, the first one on a tie). */
DS_KERNEL void
robust_argmax (guint32 j, double ch, double shj, double cl, double slj, const double *restrict cs,
               const double *restrict sn, double *restrict bh, double *restrict bl,
               guint32 *restrict sh, guint32 *restrict sl, gsize w)
{
  for (gsize x = 0; x < w; x++) {
    double vh = cs[x] * ch + sn[x] * shj, vl = cs[x] * cl + sn[x] * slj;
    gboolean take_h = vh > bh[x], take_l = vl > bl[x];
    bh[x] = take_h ? vh : bh[x];
    sh[x] = take_h ? j : sh[x];
    bl[x] = take_l ? vl : bl[x];
    sl[x] = take_l ? j : sl[x];
  }
}

DS_KERNEL void
robust_argmax_reset (double *restrict bh, double *restrict bl, guint32 *restrict sh,
                     guint32 *restrict sl, gsize w)
{
  for (gsize x = 0; x < w; x++) {
    bh[x] = bl[x] = -INFINITY;
    sh[x] = sl[x] = 0;
  }
}

DS_KERNEL void
robust_levels (double inv_hi, double inv_lo, double dn, double inv1b, double b, double m,
               double *restrict wh, double *restrict wl, const float *restrict d,
               double *restrict sum, double *restrict ld, double *restrict lg, double *restrict lh,
               double *restrict ll, double *restrict me, double *restrict amp, gsize w)
{
  for (gsize x = 0; x < w; x++) {
    double lit = wh[x] * inv_hi - d[x], unlit = wl[x] * inv_lo - d[x];
    double tr = (lit - unlit) * inv1b;
    double mean_raw = sum[x] / dn;
    sum[x] = mean_raw;
    ld[x] = tr;
    lg[x] = (unlit - b * tr) / m;
    lh[x] = lit;
    ll[x] = unlit;
    me[x] = mean_raw - d[x];
    amp[x] = 0;
  }
}

/* ds_row_robust without the motion test, over columns x0 .. x0 + w - 1 (planes and dark
 * already offset). */
DS_KERNEL void
robust_block (guint32 n, const DsRobustTables *t, const guint16 *planes16, const float *planesf,
              gsize plane_stride, const float *dark, DsRowBuffers *rb, gsize x0, gsize w,
              const DsRowConsts *c)
{
  double *cs = rb->cs + x0, *sn = rb->sn + x0, *mean_raw = rb->mean_raw + x0;
  double *hi_raw = rb->hi_raw + x0, *lo_raw = rb->lo_raw + x0;
  double *best_hi = rb->best_hi + x0, *best_lo = rb->best_lo + x0;
  guint32 *start_hi = rb->start_hi + x0, *start_lo = rb->start_lo + x0;
  robust_reset (cs, sn, mean_raw, hi_raw, lo_raw, w);
  for (guint32 k = 0; k < n; k++) {
    if (planes16)
      robust_accumulate_u16 (planes16 + k * plane_stride, t->cos_k[k], t->sin_k[k], cs, sn,
                             mean_raw, hi_raw, lo_raw, w);
    else
      robust_accumulate_f32 (planesf + k * plane_stride, t->cos_k[k], t->sin_k[k], cs, sn,
                             mean_raw, hi_raw, lo_raw, w);
  }
  robust_argmax_reset (best_hi, best_lo, start_hi, start_lo, w);
  for (guint32 j = 0; j < n; j++)
    robust_argmax (j, t->c_hi[j], t->s_hi[j], t->c_lo[j], t->s_lo[j], cs, sn, best_hi, best_lo,
                   start_hi, start_lo, w);
  memset (cs, 0, w * sizeof (double));
  memset (sn, 0, w * sizeof (double));
  for (guint32 k = 0; k < n; k++) {
    if (planes16)
      robust_windows_u16 (planes16 + k * plane_stride, k, n, t->len_hi, t->len_lo, start_hi,
                          start_lo, cs, sn, w);
    else
      robust_windows_f32 (planesf + k * plane_stride, k, n, t->len_hi, t->len_lo, start_hi,
                          start_lo, cs, sn, w);
  }
  robust_levels (1.0 / t->len_hi, 1.0 / t->len_lo, n, c->inv1b, c->b, c->m, cs, sn, dark, mean_raw,
                 rb->ld + x0, rb->lg + x0, rb->lev_hi + x0, rb->lev_lo + x0, rb->mean + x0,
                 rb->amp + x0, w);
}

DS_CLONES_WIDE void
ds_row_robust (const DsRowConsts *c, const DsRobustTables *t, const guint16 *planes16,
               const float *planesf, gsize plane_stride, const float *dark, DsRowBuffers *rb,
               gsize w)
{
  const guint32 n = c->n;
  if (!c->motion) {
    /* Every step is per pixel, so the row may go in blocks of columns in any order: blocks small
     * enough that the step's rows of doubles stay in the core's first-level cache over the N
     * passes (a 1024-pixel row of them is 8 KiB each, nine of them). The same bits. */
    const gsize block = 256;
    for (gsize x0 = 0; x0 < w; x0 += block)
      robust_block (n, t, planes16 ? planes16 + x0 : NULL, planesf ? planesf + x0 : NULL,
                    plane_stride, dark + x0, rb, x0, MIN (block, w - x0), c);
    return;
  }
  robust_reset (rb->cs, rb->sn, rb->mean_raw, rb->hi_raw, rb->lo_raw, w);
  for (guint32 k = 0; k < n; k++) {
    if (planes16)
      robust_accumulate_u16 (planes16 + k * plane_stride, t->cos_k[k], t->sin_k[k], rb->cs, rb->sn,
                             rb->mean_raw, rb->hi_raw, rb->lo_raw, w);
    else
      robust_accumulate_f32 (planesf + k * plane_stride, t->cos_k[k], t->sin_k[k], rb->cs, rb->sn,
                             rb->mean_raw, rb->hi_raw, rb->lo_raw, w);
  }
  if (c->motion) {
    /* the harmonic and the sum are at hand here, before the window sums replace them */
    memset (rb->sumsq, 0, w * sizeof (double));
    for (guint32 k = 0; k < n; k++) {
      if (planes16)
        robust_sumsq_u16 (planes16 + k * plane_stride, rb->sumsq, w);
      else
        robust_sumsq_f32 (planesf + k * plane_stride, rb->sumsq, w);
    }
    ds_row_motion (c, rb->sumsq, rb->mean_raw, 1.0 / n, rb->cs, rb->sn, dark, rb, w);
  }
  robust_argmax_reset (rb->best_hi, rb->best_lo, rb->start_hi, rb->start_lo, w);
  for (guint32 j = 0; j < n; j++)
    robust_argmax (j, t->c_hi[j], t->s_hi[j], t->c_lo[j], t->s_lo[j], rb->cs, rb->sn, rb->best_hi,
                   rb->best_lo, rb->start_hi, rb->start_lo, w);
  /* the window sums replace the harmonic */
  memset (rb->cs, 0, w * sizeof (double));
  memset (rb->sn, 0, w * sizeof (double));
  for (guint32 k = 0; k < n; k++) {
    if (planes16)
      robust_windows_u16 (planes16 + k * plane_stride, k, n, t->len_hi, t->len_lo, rb->start_hi,
                          rb->start_lo, rb->cs, rb->sn, w);
    else
      robust_windows_f32 (planesf + k * plane_stride, k, n, t->len_hi, t->len_lo, rb->start_hi,
                          rb->start_lo, rb->cs, rb->sn, w);
  }
  robust_levels (1.0 / t->len_hi, 1.0 / t->len_lo, n, c->inv1b, c->b, c->m, rb->cs, rb->sn, dark,
                 rb->mean_raw, rb->ld, rb->lg, rb->lev_hi, rb->lev_lo, rb->mean, rb->amp, w);
}

static inline gboolean
fits_float (double v)
{
  return fabs (v) <= FLT_MAX;
}

/* plain: no noise model, no extrema, no sigmas (compile-time 1 in ds_row_tail's copy for that
 * case, so that what only they need is neither computed nor stored); 0: c says which. The
 * values both compute are the same expressions, so the same bits. */
DS_KERNEL guint32
tail_row (int plain, const DsRowConsts *c, const double *restrict hr, const double *restrict lr,
          const double *restrict rmax, const float *restrict d, const double *restrict ld,
          const double *restrict lg, const double *restrict lh, const double *restrict ll,
          const double *restrict amp, const guint8 *restrict bad, const guint8 *restrict flags,
          double *restrict mean, float *restrict t, float *restrict g, guint8 *restrict mk,
          float *restrict mx, float *restrict mn, float *restrict me, float *restrict st,
          float *restrict sg, gsize w)
{
  const double read_var = c->read_var, gain = c->gain, inv_mf = 1.0 / c->m_frames;
  const double inv_sqrt_mf = sqrt (inv_mf), data_sigma = c->data_sigma, floor_ = c->floor;
  const double sat = c->sat, range_q = c->range_q, rayleigh = c->rayleigh;
  const double exceed_q = c->exceed_q, dark_var = c->dark_var, data_exceed_var = c->data_exceed_var;
  const double b = c->b, m = c->m, h = c->h, ib = 1.0 - c->b, n = c->n;
  const double vd = c->dark ? c->read_var : 0.0;
  const double inv_nh = 1.0 / c->len_hi, inv_nl = 1.0 / c->len_lo;
  const gboolean model = plain ? FALSE : c->model, sine = c->estimator == DS_ESTIMATOR_SINE;
  const gboolean extrema = plain ? FALSE : c->extrema, sigmas = plain ? FALSE : c->sigmas;
  guint32 ok_count = 0;
  /* Selects between booleans and loads under a condition defeat GCC 12's if-conversion: the
   * mask is built with bitwise operations only. */
  const int is_sine = sine, not_sine = !sine;
  const int want_x = extrema, want_s = sigmas;
  for (gsize x = 0; x < w; x++) {
    double hi = hr[x] - d[x], lo = lr[x] - d[x], mv = mean[x];
    double var_frame = read_var + gain * (mv > 0 ? mv : 0);
    double sig_phase = (model ? sqrt (var_frame) : data_sigma) * inv_sqrt_mf;
    int low_sine = amp[x] < rayleigh * sig_phase, low_range = (hr[x] - lr[x]) < range_q * sig_phase;
    int low = (is_sine & low_sine) | (not_sine & low_range);
    /* the darkest phase's noise (its own signal; none when the dark is above it) and the dark's */
    double var_lo = model ? (read_var + gain * (lo > 0 ? lo : 0)) * inv_mf + dark_var : data_exceed_var;
    int exceeds = -lo > exceed_q * sqrt (var_lo);
    guint32 bits = (guint32) (exceeds << 5) | (guint32) (rmax[x] >= sat) | (guint32) ((mv <= floor_) << 1) |
                   (guint32) (low << 2) | (guint32) (((ld[x] < 0) | (lg[x] < 0)) << 4);
    /* first-order propagation (docs/estimators.md, "Noise") */
    double vbar = var_frame * inv_mf, va = 2.0 * vbar / n, vm = vbar / n;
    double vh = (read_var + gain * (lh[x] > 0 ? lh[x] : 0)) * inv_mf * inv_nh;
    double vl = (read_var + gain * (ll[x] > 0 ? ll[x] : 0)) * inv_mf * inv_nl;
    double s_ld = sine ? sqrt (va) / h : sqrt (vh + vl) / ib;
    double s_lg = sine ? sqrt (vm / (m * m) + va / (h * h) + vd / (m * m))
                       : sqrt ((vl + b * b * vh) / (ib * ib * m * m) + vd / (m * m));
    int ok = (bad[x] == 0) & fits_float (ld[x]) & fits_float (lg[x]) &
             ((!want_x) | (fits_float (hi) & fits_float (lo) & fits_float (mv))) &
             ((!want_s) | (fits_float (s_ld) & fits_float (s_lg)));
    guint32 keep = 0u - (guint32) ok; /* all ones when ok */
    guint32 judged = 0u - (guint32) ((bits & (DS_MASK_SATURATED | DS_MASK_DARK)) == 0);
    guint32 all_bits = bits | (flags[x] & (judged | ~(guint32) DS_MASK_MOTION));
    mk[x] = (guint8) ((all_bits & keep) | (DS_MASK_NONFINITE & ~keep));
    t[x] = ok ? (float) ld[x] : 0.0f;
    g[x] = ok ? (float) lg[x] : 0.0f;
    if (!plain) {
      /* sink rows when not wanted (a plain row has none to write) */
      mx[x] = ok ? (float) hi : 0.0f;
      mn[x] = ok ? (float) lo : 0.0f;
      me[x] = ok ? (float) mv : 0.0f;
      st[x] = ok ? (float) s_ld : 0.0f;
      sg[x] = ok ? (float) s_lg : 0.0f;
    }
    mean[x] = ok ? mv : 0.0;
    ok_count += (guint32) ok;
  }
  return ok_count;
}

DS_KERNEL double
sum_row (const double *restrict v, gsize w)
{
  /* Eight running sums in a fixed order: vectorisable, and the same on every thread split. */
  double acc[8] = { 0 };
  gsize x = 0;
  for (; x + 8 <= w; x += 8)
    for (int j = 0; j < 8; j++)
      acc[j] += v[x + j];
  for (int j = 0; x < w; x++, j++)
    acc[j] += v[x];
  return ((acc[0] + acc[1]) + (acc[2] + acc[3])) + ((acc[4] + acc[5]) + (acc[6] + acc[7]));
}

DS_CLONES_WIDE void
ds_row_tail (const DsRowConsts *c, DsRowBuffers *rb, const float *dark, const guint8 *column_flags,
             const DsRowOutputs *o, gsize w, double *mean_sum, guint64 *mean_count,
             guint64 counts[DS_MASK_N_BITS + 1])
{
  const guint8 *flags = column_flags ? column_flags : rb->flags_zero;
  guint32 ok;
  if (!c->model && !c->extrema && !c->sigmas)
    ok = tail_row (1, c, rb->hi_raw, rb->lo_raw, rb->rmax, dark, rb->ld, rb->lg, rb->lev_hi,
                   rb->lev_lo, rb->amp, rb->bad, flags, rb->mean, o->t, o->g, o->mk, NULL, NULL,
                   NULL, NULL, NULL, w);
  else
    ok = tail_row (0, c, rb->hi_raw, rb->lo_raw, rb->rmax, dark, rb->ld, rb->lg, rb->lev_hi,
                   rb->lev_lo, rb->amp, rb->bad, flags, rb->mean, o->t, o->g, o->mk,
                   o->mx ? o->mx : rb->sink[0], o->mn ? o->mn : rb->sink[1],
                   o->me ? o->me : rb->sink[2], o->st ? o->st : rb->sink[3],
                   o->sg ? o->sg : rb->sink[4], w);
  *mean_sum += sum_row (rb->mean, w);
  *mean_count += ok;
  ds_count_mask_row (o->mk, w, counts);
}
