#include "proc/single_frame.h"

#include <math.h>
#include <string.h>

#include "proc/harmonic_gain.h"
#include "proc/proc_error.h"
#include "proc/separation_internal.h" /* ds_count_mask_row */
#include "proc/simd.h"
#include "proc/worker_pool.h"

struct DsSingleFrame {
  DsEstimator estimator;
  double period, duty, b, m, h;
  double saturation_param; /* params->saturation_level: 0 means the frame's full scale */
  guint width, height, window, half;
  /* sine: cos and sin of 2 pi x/P per absolute column x. The window starting at column s sees
   * the basis of the window starting at 0 rotated by 2 pi s/P, so its normal matrix is that
   * window's rotated: one inverse (g, 6 entries of a symmetric 3x3) serves every window once
   * the window's sums are rotated back by the table's angle at s. */
  float *cos_x, *sin_x;
  float g[6];
  /* The window's normal matrix is isotropic (diag(l, l/2, l/2): the window is a whole number of
   * periods, as at an integer P), so its inverse commutes with the rotation: the fit needs no
   * rotation and the amplitude is g[3] |(sum v cos, sum v sin)|. */
  gboolean isotropic;
  guint threads;
  DsWorkerPool *pool;     /* made on first use when threads > 1 */
  gsize tile;             /* sine: window starts per tile of a row */
  float *scratch;         /* threads x scratch_floats */
  gsize scratch_floats;
};

/* Inverse of the symmetric 3x3 matrix (a00 a01 a02; a11 a12; a22) into out[6] (same order).
 * FALSE when it is singular against its own scale. */
static gboolean
invert_sym3 (const double a[6], double out[6])
{
  double c00 = a[3] * a[5] - a[4] * a[4];
  double c01 = a[2] * a[4] - a[1] * a[5];
  double c02 = a[1] * a[4] - a[2] * a[3];
  double det = a[0] * c00 + a[1] * c01 + a[2] * c02;
  double scale = a[0] * a[3] * a[5];
  if (!(fabs (det) > 1e-12 * fabs (scale)))
    return FALSE;
  out[0] = c00 / det;
  out[1] = c01 / det;
  out[2] = c02 / det;
  out[3] = (a[0] * a[5] - a[2] * a[2]) / det;
  out[4] = (a[1] * a[2] - a[0] * a[4]) / det;
  out[5] = (a[0] * a[3] - a[1] * a[1]) / det;
  return TRUE;
}

static gboolean
plan_sine (DsSingleFrame *sf, GError **error)
{
  guint w = sf->width, l = sf->window;
  double period = sf->period;
  sf->cos_x = g_new (float, w);
  sf->sin_x = g_new (float, w);
  for (guint x = 0; x < w; x++) {
    /* The phase reduced to one period first: cos of a large argument loses digits. */
    double u = fmod ((double) x, period) / period;
    sf->cos_x[x] = (float) cos (2 * G_PI * u);
    sf->sin_x[x] = (float) sin (2 * G_PI * u);
  }
  double g[6] = { 0 }, inv[6];
  for (guint k = 0; k < l; k++) {
    double c = cos (2 * G_PI * k / period), sn = sin (2 * G_PI * k / period);
    g[0] += 1;
    g[1] += c;
    g[2] += sn;
    g[3] += c * c;
    g[4] += c * sn;
    g[5] += sn * sn;
  }
  if (!invert_sym3 (g, inv)) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_ILL_CONDITIONED,
                 "single-frame sine: a window of %u columns cannot resolve period %g px", l, period);
    return FALSE;
  }
  for (guint i = 0; i < 6; i++)
    sf->g[i] = (float) inv[i];
  /* isotropic when the terms the rotation would mix are zero to well below float rounding */
  double scale = fmax (fabs (inv[0]), fabs (inv[3]));
  sf->isotropic = fabs (inv[1]) <= 1e-9 * scale && fabs (inv[2]) <= 1e-9 * scale && fabs (inv[4]) <= 1e-9 * scale &&
                  fabs (inv[3] - inv[5]) <= 1e-9 * scale;
  return TRUE;
}

static gboolean
check_params (const DsSeparationParams *params, guint width, GError **error)
{
  double period = params->geometry.period_px;
  if (params->estimator != DS_ESTIMATOR_MAXMIN && params->estimator != DS_ESTIMATOR_SINE) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_INVALID_ARGUMENT,
                 "single-frame estimator: %s needs more samples per level than one period offers (use maxmin or sine)",
                 ds_estimator_name (params->estimator));
    return FALSE;
  }
  double min_period = params->estimator == DS_ESTIMATOR_SINE ? 3 : 2;
  if (!(period >= min_period && period <= 4096) || (params->estimator == DS_ESTIMATOR_MAXMIN && period == 2)) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_INVALID_ARGUMENT,
                 "single-frame %s: stripe period %g px outside %s%g, 4096] (the window is one period)",
                 ds_estimator_name (params->estimator), period, params->estimator == DS_ESTIMATOR_SINE ? "[" : "(",
                 min_period);
    return FALSE;
  }
  if (!(params->duty > 0 && params->duty < 1) || !(params->black_level >= 0 && params->black_level < 1)) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_INVALID_ARGUMENT,
                 "single-frame: duty %g outside (0, 1) or black level %g outside [0, 1)", params->duty,
                 params->black_level);
    return FALSE;
  }
  guint window = ds_single_frame_window_px (period);
  if (width < window) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_INVALID_ARGUMENT,
                 "single-frame: the frame is %u px wide, narrower than the window of one period (%u px)", width,
                 window);
    return FALSE;
  }
  return TRUE;
}

guint
ds_single_frame_window_px (double period_px)
{
  return (guint) ceil (period_px - 1e-9);
}

void
ds_single_frame_free (DsSingleFrame *sf)
{
  if (!sf)
    return;
  g_clear_pointer (&sf->pool, ds_worker_pool_free);
  g_free (sf->cos_x);
  g_free (sf->sin_x);
  g_free (sf->scratch);
  g_free (sf);
}

/* Per-thread scratch, in floats: the row, its products with the basis, two levels of three
 * series and the three window sums (sine; maxmin uses five rows of it), then two rows of
 * counts. */
#define ROWS_PER_THREAD 12u

DsSingleFrame *
ds_single_frame_new (const DsSeparationParams *params, guint width, guint height, GError **error)
{
  g_return_val_if_fail (params, NULL);
  if (!check_params (params, width, error))
    return NULL;
  if (height == 0) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_INVALID_ARGUMENT, "single-frame: the frame has no rows");
    return NULL;
  }
  g_autoptr (DsSingleFrame) sf = g_new0 (DsSingleFrame, 1);
  sf->estimator = params->estimator;
  sf->period = params->geometry.period_px;
  sf->duty = params->duty;
  sf->width = width;
  sf->height = height;
  sf->window = ds_single_frame_window_px (sf->period);
  sf->half = sf->window / 2;
  sf->b = params->black_level;
  sf->m = ds_pattern_mean (params->pattern, params->duty, sf->b);
  sf->h = params->harmonic_gain > 0 ? params->harmonic_gain
                                    : ds_harmonic_gain_theory (params->pattern, params->duty, sf->b);
  sf->saturation_param = params->saturation_level;
  double cond = sf->estimator == DS_ESTIMATOR_SINE ? fmax (1 / sf->m, 1 / sf->h) : fmax (1 / (1 - sf->b), 1 / sf->m);
  if (!(cond <= DS_MAX_CONDITION)) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_ILL_CONDITIONED,
                 "single-frame %s: the pattern (black level %g, duty %g) amplifies noise %.3g times, above %g",
                 ds_estimator_name (sf->estimator), sf->b, params->duty, cond, DS_MAX_CONDITION);
    return NULL;
  }
  if (sf->estimator == DS_ESTIMATOR_SINE && !plan_sine (sf, error))
    return NULL;
  guint t = params->threads ? params->threads : (guint) g_get_num_processors ();
  sf->threads = (gsize) width * height >= DS_SINGLE_FRAME_THREADED_PIXELS ? CLAMP (t, 1u, DS_MAX_THREADS) : 1;
  sf->tile = MAX (512u, 4 * sf->window);
  /* Rows a multiple of 16 floats apart, so that two rows never share a cache line, plus about
   * half a page: at widths of a power of two the rows would otherwise start one line apart
   * modulo 4096 bytes, and a pass's loads from one row would wait on its stores to the next
   * (a false dependency on x86). The sine's levels and sums use a tile's worth of each. */
  gsize row = (((gsize) width + 1 + 15) & ~(gsize) 15) + 528;
  sf->scratch_floats = row * (ROWS_PER_THREAD + 2);
  sf->scratch = g_malloc ((gsize) sf->threads * sf->scratch_floats * sizeof (float));
  return g_steal_pointer (&sf);
}

DsSingleFrameInfo
ds_single_frame_info (const DsSingleFrame *sf)
{
  return (DsSingleFrameInfo) { .period_px = sf->period, .window_px = sf->window };
}

/* ---- Row kernels: restrict parameters, inlined into each clone (proc/simd.h). ---- */

#define DECLARE_READ_INT(T, NAME)                                                                    \
  DS_KERNEL guint read_##NAME (const T *restrict in, float *restrict v, gsize w, guint threshold)  \
  {                                                                                                  \
    guint n = 0;                                                                                     \
    for (gsize x = 0; x < w; x++) {                                                                  \
      v[x] = in[x];                                                                                  \
      n += in[x] >= threshold;                                                                       \
    }                                                                                                \
    return n;                                                                                        \
  }
DECLARE_READ_INT (guint16, u16)
DECLARE_READ_INT (guint8, u8)

/* The sine's three series (v, v cos, v sin) are summed one at a time: each pass then keeps
 * two pointers (which the row loops hold in registers, where three series' six spilled), and
 * the products v cos and v sin are made once per column instead of once per window level.
 * The products and the pairwise order of the sums are those of summing the products in
 * place, so the result is the same. */

/* o[x] = a[x], x < n. */
DS_KERNEL void
copy1 (const float *restrict a, float *restrict o, gsize n)
{
  memcpy (o, a, n * sizeof (float));
}

/* One doubling step: o[x] = a[x] + a[x + shift], x < n (onto o when add: a call site passes a
 * constant, so each loop is compiled without the other). */
DS_KERNEL void
pair_sums1 (const float *restrict a, float *restrict o, gsize n, gsize shift, gboolean add)
{
  for (gsize x = 0; x < n; x++) {
    float v = a[x] + a[x + shift];
    o[x] = add ? o[x] + v : v;
  }
}

/* Two doubling steps in one pass: o[x] = (a[x] + a[x + shift]) + (a[x + 2 shift] + a[x + 3 shift]),
 * the same sums in the same order, x < n. */
DS_KERNEL void
quad_sums1 (const float *restrict a, float *restrict o, gsize n, gsize shift)
{
  for (gsize x = 0; x < n; x++)
    o[x] = (a[x] + a[x + shift]) + (a[x + 2 * shift] + a[x + 3 * shift]);
}

/* t[x] += a[x], x < n. */
DS_KERNEL void
add1 (const float *restrict a, float *restrict t, gsize n)
{
  for (gsize x = 0; x < n; x++)
    t[x] += a[x];
}

/* The products of the row with the basis: pc[x] = v[x] cos, ps[x] = v[x] sin, x < n. */
DS_KERNEL void
basis_products (const float *restrict v, const float *restrict c, const float *restrict sn, float *restrict pc,
                float *restrict ps, gsize n)
{
  for (gsize x = 0; x < n; x++) {
    pc[x] = v[x] * c[x];
    ps[x] = v[x] * sn[x];
  }
}

/* One doubling step of the extremes: o[x] = max/min (a[x], a[x + shift]), x < n. */
DS_KERNEL void
pair_extremes (const float *restrict amax, const float *restrict amin, float *restrict omax, float *restrict omin,
               gsize n, gsize shift)
{
  for (gsize x = 0; x < n; x++) {
    float p = amax[x], q = amax[x + shift], r = amin[x], s = amin[x + shift];
    omax[x] = p > q ? p : q;
    omin[x] = r < s ? r : s;
  }
}

typedef struct {
  float g[6];
  float inv_h, inv_m;
} SineConsts;

/* The fit of n consecutive windows from their sums (t*) and the basis angle at their starts
 * (c, s): the sums rotated into the first window's basis, then its inverse normal matrix. */
DS_KERNEL guint
fit_sine (const float *restrict t0, const float *restrict tc, const float *restrict ts, const float *restrict c,
          const float *restrict s, float *restrict ld, float *restrict lg, guint8 *restrict mk, gsize n,
          SineConsts k)
{
  guint negative = 0;
  for (gsize x = 0; x < n; x++) {
    float u = c[x] * tc[x] + s[x] * ts[x];
    float v = c[x] * ts[x] - s[x] * tc[x];
    float mean = k.g[0] * t0[x] + k.g[1] * u + k.g[2] * v;
    float a = k.g[1] * t0[x] + k.g[3] * u + k.g[4] * v;
    float b = k.g[2] * t0[x] + k.g[4] * u + k.g[5] * v;
    float d = sqrtf (a * a + b * b) * k.inv_h;
    float g = mean * k.inv_m - d;
    ld[x] = d;
    lg[x] = g;
    mk[x] = g < 0 ? DS_MASK_NEGATIVE : 0;
    negative += g < 0;
  }
  return negative;
}

/* fit_sine for an isotropic window: M = g0 t0 and |(a, b)| = g3 |(tc, ts)| in any basis. */
DS_KERNEL guint
fit_sine_isotropic (const float *restrict t0, const float *restrict tc, const float *restrict ts, float *restrict ld,
                    float *restrict lg, guint8 *restrict mk, gsize n, float g0, float amp, float inv_m)
{
  guint negative = 0;
  for (gsize x = 0; x < n; x++) {
    float d = sqrtf (tc[x] * tc[x] + ts[x] * ts[x]) * amp;
    float g = g0 * t0[x] * inv_m - d;
    ld[x] = d;
    lg[x] = g;
    mk[x] = g < 0 ? DS_MASK_NEGATIVE : 0;
    negative += g < 0;
  }
  return negative;
}

/* n consecutive windows' max and min from two overlapping power-of-two extremes. */
DS_KERNEL guint
fit_maxmin (const float *restrict mx0, const float *restrict mx1, const float *restrict mn0,
            const float *restrict mn1, float *restrict ld, float *restrict lg, guint8 *restrict mk, gsize n,
            float inv_contrast, float inv_m, float b)
{
  guint negative = 0;
  for (gsize x = 0; x < n; x++) {
    float mx = mx0[x] > mx1[x] ? mx0[x] : mx1[x];
    float mn = mn0[x] < mn1[x] ? mn0[x] : mn1[x];
    float d = (mx - mn) * inv_contrast;
    float g = (mn - b * d) * inv_m;
    ld[x] = d;
    lg[x] = g;
    mk[x] = g < 0 ? DS_MASK_NEGATIVE : 0;
    negative += g < 0;
  }
  return negative;
}

/* Integer frames without a dark frame: the extremes in the samples' own type (two or four
 * times the lanes of float, no conversion pass), exact as the float path is. Levels go up
 * by four where the window allows (one pass of three compares instead of two passes). */
#define DECLARE_EXTREMES_INT(T, NAME)                                                                     \
  DS_KERNEL guint count_at_least_##NAME (const T *restrict in, gsize w, guint threshold)                \
  {                                                                                                       \
    guint n = 0;                                                                                          \
    for (gsize x = 0; x < w; x++)                                                                         \
      n += in[x] >= threshold;                                                                            \
    return n;                                                                                             \
  }                                                                                                       \
  DS_KERNEL void pair_extremes_##NAME (const T *restrict amax, const T *restrict amin, T *restrict omax, \
                                       T *restrict omin, gsize n, gsize shift)                            \
  {                                                                                                       \
    for (gsize x = 0; x < n; x++) {                                                                       \
      T p = amax[x], q = amax[x + shift], r = amin[x], s = amin[x + shift];                               \
      omax[x] = p > q ? p : q;                                                                            \
      omin[x] = r < s ? r : s;                                                                            \
    }                                                                                                     \
  }                                                                                                       \
  DS_KERNEL void quad_extremes_##NAME (const T *restrict amax, const T *restrict amin, T *restrict omax, \
                                       T *restrict omin, gsize n, gsize shift)                            \
  {                                                                                                       \
    for (gsize x = 0; x < n; x++) {                                                                       \
      T p = amax[x], q = amax[x + shift], u = amax[x + 2 * shift], v = amax[x + 3 * shift];               \
      p = p > q ? p : q;                                                                                  \
      u = u > v ? u : v;                                                                                  \
      omax[x] = p > u ? p : u;                                                                            \
      T r = amin[x], s = amin[x + shift], e = amin[x + 2 * shift], f = amin[x + 3 * shift];               \
      r = r < s ? r : s;                                                                                  \
      e = e < f ? e : f;                                                                                  \
      omin[x] = r < e ? r : e;                                                                            \
    }                                                                                                     \
  }                                                                                                       \
  DS_KERNEL guint fit_maxmin_##NAME (const T *restrict mx0, const T *restrict mx1, const T *restrict mn0, \
                                     const T *restrict mn1, float *restrict ld, float *restrict lg,       \
                                     guint8 *restrict mk, gsize n, float inv_contrast, float inv_m, float b) \
  {                                                                                                       \
    guint negative = 0;                                                                                   \
    for (gsize x = 0; x < n; x++) {                                                                       \
      T imx = mx0[x] > mx1[x] ? mx0[x] : mx1[x];                                                          \
      T imn = mn0[x] < mn1[x] ? mn0[x] : mn1[x];                                                          \
      float mn = imn;                                                                                     \
      float d = (float) (T) (imx - imn) * inv_contrast;                                                   \
      float g = (mn - b * d) * inv_m;                                                                     \
      ld[x] = d;                                                                                          \
      lg[x] = g;                                                                                          \
      mk[x] = g < 0 ? DS_MASK_NEGATIVE : 0;                                                               \
      negative += g < 0;                                                                                  \
    }                                                                                                     \
    return negative;                                                                                      \
  }                                                                                                       \
  /* Returns the pixels flagged negative, the only bit this path sets. */                                 \
  DS_KERNEL guint maxmin_row_##NAME (const DsSingleFrame *sf, const T *in, T *scratch[4], float *ld,        \
                                    float *lg, guint8 *mk)                                                \
  {                                                                                                       \
    gsize w = sf->width, l = sf->window, half = sf->half, starts = w - l + 1, len = 1;                   \
    const T *mx = in, *mn = in;                                                                           \
    T *next[2] = { scratch[0], scratch[1] }, *spare[2] = { scratch[2], scratch[3] };                      \
    while (len * 2 <= l) {                                                                                \
      gsize step = len * 4 <= l ? 4 : 2;                                                                  \
      if (step == 4)                                                                                      \
        quad_extremes_##NAME (mx, mn, next[0], next[1], w - 4 * len + 1, len);                            \
      else                                                                                                \
        pair_extremes_##NAME (mx, mn, next[0], next[1], w - 2 * len + 1, len);                            \
      len *= step;                                                                                        \
      mx = next[0];                                                                                       \
      mn = next[1];                                                                                       \
      T *t0 = next[0], *t1 = next[1];                                                                     \
      next[0] = spare[0];                                                                                 \
      next[1] = spare[1];                                                                                 \
      spare[0] = t0;                                                                                      \
      spare[1] = t1;                                                                                      \
    }                                                                                                     \
    gsize o = l - len;                                                                                    \
    float ic = (float) (1 / (1 - sf->b)), im = (float) (1 / sf->m), b = (float) sf->b;                    \
    guint negative = fit_maxmin_##NAME (mx, mx + o, mn, mn + o, ld + half, lg + half, mk + half, starts, ic, \
                                        im, b);                                                           \
    for (gsize x = 0; x < half; x++)                                                                      \
      negative += fit_maxmin_##NAME (mx, mx + o, mn, mn + o, ld + x, lg + x, mk + x, 1, ic, im, b);       \
    for (gsize x = starts + half; x < w; x++) {                                                           \
      gsize e = starts - 1;                                                                               \
      negative += fit_maxmin_##NAME (mx + e, mx + e + o, mn + e, mn + e + o, ld + x, lg + x, mk + x, 1, ic, \
                                     im, b);                                                              \
    }                                                                                                     \
    return negative;                                                                                      \
  }
DECLARE_EXTREMES_INT (guint16, u16)
DECLARE_EXTREMES_INT (guint8, u8)

/* ---- One row ---- */

typedef struct {
  float *v, *pc, *ps;   /* the row; sine: its products with cos and sin */
  float *la[3], *lb[3]; /* two levels of three series (maxmin: max and min in la, lb) */
  float *t[3];          /* sine: the window sums, per window start */
  guint *sat, *bad;     /* prefix counts: saturated, non-finite columns before x */
} Rows;

static Rows
rows_of (const DsSingleFrame *sf, guint thread)
{
  gsize row = sf->scratch_floats / (ROWS_PER_THREAD + 2);
  float *f = sf->scratch + (gsize) thread * sf->scratch_floats;
  Rows r = { .v = f, .pc = f + row, .ps = f + 2 * row };
  for (guint i = 0; i < 3; i++) {
    r.la[i] = f + (3 + i) * row;
    r.lb[i] = f + (6 + i) * row;
    r.t[i] = f + (9 + i) * row;
  }
  r.sat = (guint *) (f + ROWS_PER_THREAD * row);
  r.bad = (guint *) (f + (ROWS_PER_THREAD + 1) * row);
  return r;
}

/* One thread's mask counts, padded so that no two threads write one cache line. */
typedef struct {
  guint64 c[DS_MASK_N_BITS + 1];
  guint64 pad[8];
} Counts;

typedef struct {
  const DsSingleFrame *sf;
  const DsImage *frame, *dark;
  DsSeparation *sep;
  double saturation;
  guint threshold; /* integer frames: samples at or above it are saturated */
  Counts *counted; /* per thread */
} Job;

/* The row as floats (dark subtracted); FALSE when no column is saturated or non-finite, else
 * the prefix counts are made and non-finite values replaced by 0. */
DS_KERNEL gboolean
read_row (const Job *job, guint y, Rows *r)
{
  const DsImage *frame = job->frame;
  gsize w = frame->width;
  const void *row = ds_image_row (frame, y);
  guint n_sat = 0, n_bad = 0;
  if (frame->type == DS_SAMPLE_U16) {
    n_sat = read_u16 (row, r->v, w, job->threshold);
  } else if (frame->type == DS_SAMPLE_U8) {
    n_sat = read_u8 (row, r->v, w, job->threshold);
  } else {
    const float *in = row;
    float sat_level = (float) fmin (job->saturation, G_MAXFLOAT);
    for (gsize x = 0; x < w; x++) {
      r->v[x] = in[x];
      n_sat += in[x] >= sat_level;
      n_bad += !isfinite (in[x]);
    }
  }
  if (job->dark) {
    const void *drow = ds_image_row (job->dark, y);
    for (gsize x = 0; x < w; x++)
      r->v[x] -= (float) ds_image_sample (job->dark, drow, x);
    for (gsize x = 0; x < w; x++)
      n_bad += !isfinite (r->v[x]);
  }
  if (n_sat == 0 && n_bad == 0)
    return FALSE;
  r->sat[0] = r->bad[0] = 0;
  for (gsize x = 0; x < w; x++) {
    double raw = ds_image_sample (frame, row, x);
    gboolean finite = isfinite (r->v[x]);
    r->sat[x + 1] = r->sat[x] + (finite && raw >= job->saturation);
    r->bad[x + 1] = r->bad[x] + !finite;
    if (!finite)
      r->v[x] = 0;
  }
  return TRUE;
}

/* One series' window sums, a[s] + ... + a[s + l - 1] for the window starts s < starts (a holds
 * columns [0, starts + l - 1)): into t, or left in a level buffer (la, lb) when the window is
 * one level (a power of two); returns where they are. The window is its length's binary
 * digits, low first: one and two columns from a, then levels of 4, 8, ... columns, each from
 * two of the level below, so every sum is pairwise. */
DS_KERNEL const float *
series_sums (const float *a, gsize starts, gsize l, float *t, float *la, float *lb)
{
  gsize w = starts + l - 1, off = 0;
  if (l & 1) {
    copy1 (a, t, starts);
    off = 1;
  }
  if (l & 2) {
    if (off)
      pair_sums1 (a + off, t, starts, 1, TRUE);
    else
      pair_sums1 (a, t, starts, 1, FALSE);
    off += 2;
  }
  if (l < 4)
    return t;
  float *level = la, *spare = lb;
  quad_sums1 (a, level, w - 3, 1);
  for (gsize len = 4;;) {
    if (l & len) {
      if (off) {
        add1 (level + off, t, starts);
      } else if (len * 2 > l) {
        return level; /* the window is this level alone: its sums as they stand */
      } else {
        memcpy (t, level, starts * sizeof (float));
      }
      off += len;
    }
    if (len * 2 > l)
      return t;
    /* the next level the window needs, from this one: valid for x + next <= w; a level the
     * window does not use is skipped (four of this level in one pass) */
    gsize next = len * 4 <= l && !(l & (len * 2)) ? len * 4 : len * 2;
    if (next == len * 4)
      quad_sums1 (level, spare, w - next + 1, len);
    else
      pair_sums1 (level, spare, w - next + 1, len, FALSE);
    float *tmp = level;
    level = spare;
    spare = tmp;
    len = next;
  }
}

/* The row in tiles of sf->tile window starts, so that the levels stay in the first-level
 * cache; a tile reads the l - 1 columns after it again. */
/* Returns the pixels flagged negative. */
DS_KERNEL guint
sine_row (const DsSingleFrame *sf, Rows *r, float *ld, float *lg, guint8 *mk)
{
  guint negative = 0;
  gsize w = sf->width, l = sf->window, half = sf->half, starts = w - l + 1;
  SineConsts k = { .inv_h = (float) (1 / sf->h), .inv_m = (float) (1 / sf->m) };
  memcpy (k.g, sf->g, sizeof k.g);
  basis_products (r->v, sf->cos_x, sf->sin_x, r->pc, r->ps, w);
  const float *series[3] = { r->v, r->pc, r->ps };
  for (gsize x0 = 0; x0 < starts; x0 += sf->tile) {
    gsize n = MIN (sf->tile, starts - x0);
    const float *c = sf->cos_x + x0, *s = sf->sin_x + x0, *sums[3];
    for (guint i = 0; i < 3; i++)
      sums[i] = series_sums (series[i] + x0, n, l, r->t[i], r->la[i], r->lb[i]);
    const float *t0 = sums[0], *tc = sums[1], *ts = sums[2];
    if (sf->isotropic) {
      float g0 = k.g[0], amp = k.g[3] * k.inv_h;
      negative += fit_sine_isotropic (t0, tc, ts, ld + half + x0, lg + half + x0, mk + half + x0, n, g0, amp, k.inv_m);
      for (gsize x = 0; x0 == 0 && x < half; x++)
        negative += fit_sine_isotropic (t0, tc, ts, ld + x, lg + x, mk + x, 1, g0, amp, k.inv_m);
      for (gsize x = starts + half; x0 + n == starts && x < w; x++) {
        gsize e = n - 1;
        negative += fit_sine_isotropic (t0 + e, tc + e, ts + e, ld + x, lg + x, mk + x, 1, g0, amp, k.inv_m);
      }
      continue;
    }
    /* pixel x's window starts at x - half, clamped to [0, starts - 1] */
    negative += fit_sine (t0, tc, ts, c, s, ld + half + x0, lg + half + x0, mk + half + x0, n, k);
    for (gsize x = 0; x0 == 0 && x < half; x++)
      negative += fit_sine (t0, tc, ts, c, s, ld + x, lg + x, mk + x, 1, k);
    for (gsize x = starts + half; x0 + n == starts && x < w; x++) {
      gsize e = n - 1;
      negative += fit_sine (t0 + e, tc + e, ts + e, c + e, s + e, ld + x, lg + x, mk + x, 1, k);
    }
  }
  return negative;
}

/* Returns the pixels flagged negative. */
DS_KERNEL guint
maxmin_row (const DsSingleFrame *sf, Rows *r, float *ld, float *lg, guint8 *mk)
{
  guint negative = 0;
  gsize w = sf->width, l = sf->window, half = sf->half, starts = w - l + 1, len = 1;
  const float *mx = r->v, *mn = r->v;
  float *next[2] = { r->la[0], r->la[1] }, *spare[2] = { r->lb[0], r->lb[1] };
  for (; len * 2 <= l; len <<= 1) {
    pair_extremes (mx, mn, next[0], next[1], w - 2 * len + 1, len);
    mx = next[0];
    mn = next[1];
    float *t0 = next[0], *t1 = next[1];
    next[0] = spare[0];
    next[1] = spare[1];
    spare[0] = t0;
    spare[1] = t1;
  }
  /* extremes over [s, s + len) and [s + l - len, s + l): together the window, len <= l < 2 len */
  gsize o = l - len;
  float ic = (float) (1 / (1 - sf->b)), im = (float) (1 / sf->m), b = (float) sf->b;
  negative += fit_maxmin (mx, mx + o, mn, mn + o, ld + half, lg + half, mk + half, starts, ic, im, b);
  for (gsize x = 0; x < half; x++)
    negative += fit_maxmin (mx, mx + o, mn, mn + o, ld + x, lg + x, mk + x, 1, ic, im, b);
  for (gsize x = starts + half; x < w; x++) {
    gsize e = starts - 1;
    negative += fit_maxmin (mx + e, mx + e + o, mn + e, mn + e + o, ld + x, lg + x, mk + x, 1, ic, im, b);
  }
  return negative;
}

/* Each pixel's window start: centred, clamped so that the window stays inside the row. */
static inline guint
window_start (const DsSingleFrame *sf, guint x)
{
  guint l = sf->window, s = x >= l / 2 ? x - l / 2 : 0;
  return MIN (s, sf->width - l);
}

/* A row's mask counts (as ds_count_mask_row) when `negative` pixels carry DS_MASK_NEGATIVE and
 * the others no bit. */
static inline void
count_negative (guint64 counts[DS_MASK_N_BITS + 1], gsize w, guint negative)
{
  G_STATIC_ASSERT (DS_MASK_NEGATIVE == 1 << 4); /* counts[1 + bit] */
  counts[0] += w - negative;
  counts[1 + 4] += negative;
}

/* Rows [y0, y1): read, separate, flag the windows that hold a saturated or non-finite
 * sample, count. */
DS_KERNEL void
rows (const Job *job, guint y0, guint y1, guint thread, gboolean sine)
{
  const DsSingleFrame *sf = job->sf;
  Rows r = rows_of (sf, thread);
  DsSampleType type = job->frame->type;
  gboolean raw = !sine && !job->dark && (type == DS_SAMPLE_U16 || type == DS_SAMPLE_U8);
  for (guint y = y0; y < y1; y++) {
    float *ld = ds_image_row (job->sep->transmissive, y), *lg = ds_image_row (job->sep->scattered, y);
    guint8 *mk = ds_image_row (job->sep->mask, y);
    const void *in = ds_image_row (job->frame, y);
    if (raw && type == DS_SAMPLE_U16 && count_at_least_u16 (in, sf->width, job->threshold) == 0) {
      guint16 *scratch[4] = { (guint16 *) r.la[0], (guint16 *) r.la[1], (guint16 *) r.lb[0], (guint16 *) r.lb[1] };
      count_negative (job->counted[thread].c, sf->width, maxmin_row_u16 (sf, in, scratch, ld, lg, mk));
      continue;
    }
    if (raw && type == DS_SAMPLE_U8 && count_at_least_u8 (in, sf->width, job->threshold) == 0) {
      guint8 *scratch[4] = { (guint8 *) r.la[0], (guint8 *) r.la[1], (guint8 *) r.lb[0], (guint8 *) r.lb[1] };
      count_negative (job->counted[thread].c, sf->width, maxmin_row_u8 (sf, in, scratch, ld, lg, mk));
      continue;
    }
    gboolean flagged = read_row (job, y, &r);
    guint negative = sine ? sine_row (sf, &r, ld, lg, mk) : maxmin_row (sf, &r, ld, lg, mk);
    if (!flagged) {
      count_negative (job->counted[thread].c, sf->width, negative);
      continue;
    }
    for (guint x = 0; x < sf->width; x++) {
      guint s = window_start (sf, x), e = s + sf->window;
      if (r.sat[e] > r.sat[s])
        mk[x] |= DS_MASK_SATURATED;
      if (r.bad[e] > r.bad[s])
        mk[x] |= DS_MASK_NONFINITE;
    }
    ds_count_mask_row (mk, sf->width, job->counted[thread].c);
  }
}

/* Float arithmetic throughout: the wide clone pays for sine, the memory-bound maxmin keeps
 * AVX2 (proc/simd.h). */
DS_CLONES_WIDE static void
sine_rows (gpointer data, guint y0, guint y1, guint thread)
{
  rows (data, y0, y1, thread, TRUE);
}

DS_CLONES static void
maxmin_rows (gpointer data, guint y0, guint y1, guint thread)
{
  rows (data, y0, y1, thread, FALSE);
}

/* The caller's planes checked, the missing allocated, those this estimator does not make freed. */
static gboolean
prepare_planes (DsSeparation *sep, guint w, guint h, GError **error)
{
  DsImage **made[] = { &sep->transmissive, &sep->scattered, &sep->mask };
  const char *names[] = { "transmissive", "scattered", "mask" };
  for (guint i = 0; i < G_N_ELEMENTS (made); i++) {
    DsImage *p = *made[i];
    DsSampleType type = i == 2 ? DS_SAMPLE_U8 : DS_SAMPLE_F32;
    if (p && (p->type != type || p->width != w || p->height != h)) {
      g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_INVALID_ARGUMENT,
                   "result plane %s is %ux%u %s, the single-frame estimator makes %ux%u %s", names[i], p->width,
                   p->height, ds_sample_type_name (p->type), w, h, ds_sample_type_name (type));
      return FALSE;
    }
  }
  DsImage **unmade[] = { &sep->max, &sep->min, &sep->mean, &sep->sigma_transmissive, &sep->sigma_scattered };
  for (guint i = 0; i < G_N_ELEMENTS (unmade); i++)
    g_clear_pointer (unmade[i], ds_image_free);
  for (guint i = 0; i < G_N_ELEMENTS (made); i++)
    if (!*made[i] && !(*made[i] = ds_image_new (i == 2 ? DS_SAMPLE_U8 : DS_SAMPLE_F32, w, h, error)))
      return FALSE;
  return TRUE;
}

gboolean
ds_single_frame_separate_into (DsSingleFrame *sf, const DsImage *frame, const DsImage *dark, DsSeparation *sep,
                               GError **error)
{
  g_return_val_if_fail (sf && frame && sep, FALSE);
  if (frame->width != sf->width || frame->height != sf->height) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_INVALID_ARGUMENT,
                 "single-frame: the frame is %ux%u, the plan is for %ux%u", frame->width, frame->height, sf->width,
                 sf->height);
    return FALSE;
  }
  if (dark && !ds_image_same_shape (frame, dark)) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_SIZE_MISMATCH,
                 "single-frame: the dark frame is %ux%u %s, the frame %ux%u %s", dark->width, dark->height,
                 ds_sample_type_name (dark->type), frame->width, frame->height, ds_sample_type_name (frame->type));
    return FALSE;
  }
  if (!prepare_planes (sep, sf->width, sf->height, error))
    return FALSE;
  Job job = { .sf = sf, .frame = frame, .dark = dark, .sep = sep };
  if (sf->saturation_param > 0)
    job.saturation = sf->saturation_param;
  else if (frame->type == DS_SAMPLE_F32)
    job.saturation = INFINITY;
  else
    job.saturation = ldexp (1, (int) frame->bit_depth) - 1;
  /* integer samples: x >= level exactly when x >= ceil (level); above 65535 none is */
  job.threshold = (guint) fmin (ceil (job.saturation), 65536);
  g_autofree Counts *counted = g_malloc0_n (sf->threads, sizeof (Counts));
  job.counted = counted;
  if (sf->threads > 1 && !sf->pool)
    sf->pool = ds_worker_pool_new (sf->threads);
  ds_worker_pool_run (sf->pool, sf->height, sf->estimator == DS_ESTIMATOR_SINE ? sine_rows : maxmin_rows, &job);

  DsSeparationMeta *meta = &sep->meta;
  *meta = (DsSeparationMeta) { 0 };
  for (guint t = 0; t < sf->threads; t++) {
    meta->valid_pixels += counted[t].c[0];
    for (guint bit = 0; bit < DS_MASK_N_BITS; bit++)
      meta->flagged[bit] += counted[t].c[1 + bit];
  }
  meta->n_phases = sf->window;
  meta->frames_per_phase = 1;
  meta->estimator = sf->estimator;
  meta->duty = sf->duty;
  meta->black_level = sf->b;
  meta->pattern_mean = sf->m;
  meta->harmonic_gain = sf->h;
  meta->dark_subtracted = dark != NULL;
  meta->noise_dn = NAN;
  meta->saturation_level = isfinite (job.saturation) ? job.saturation : NAN;
  meta->phase_offset_cycles = NAN;
  return TRUE;
}

gboolean
ds_single_frame_separate (const DsImage *frame, const DsImage *dark, const DsSeparationParams *params,
                          DsSeparation **out, DsSingleFrameInfo *info, GError **error)
{
  g_return_val_if_fail (frame && params && out, FALSE);
  g_autoptr (DsSingleFrame) sf = ds_single_frame_new (params, frame->width, frame->height, error);
  if (!sf)
    return FALSE;
  g_autoptr (DsSeparation) sep = ds_separation_new ();
  if (!ds_single_frame_separate_into (sf, frame, dark, sep, error))
    return FALSE;
  if (info)
    *info = ds_single_frame_info (sf);
  *out = g_steal_pointer (&sep);
  return TRUE;
}
