#include "proc/single_frame.h"

#include <math.h>

#include "proc/harmonic_gain.h"
#include "proc/proc_error.h"
#include "proc/separation_internal.h" /* ds_count_mask_row */

/* The pattern's constants and the window, checked once per call. */
typedef struct {
  DsEstimator estimator;
  double b, m, h;
  double saturation;
  guint width, window;
  /* sine: cos and sin of 2 pi x/P per column, and per window start s the inverse of the
   * window's normal matrix [1 c s]^T [1 c s] (symmetric: 6 entries) */
  double *cos_x, *sin_x;
  double *ginv;      /* 6 planes of (width - window + 1): entry i of start s at i * starts + s */
  gsize starts;
} Plan;

static void
plan_clear (Plan *p)
{
  g_free (p->cos_x);
  g_free (p->sin_x);
  g_free (p->ginv);
}

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
plan_sine (Plan *p, double period, GError **error)
{
  guint w = p->width, l = p->window, starts = w - l + 1;
  p->cos_x = g_new (double, w);
  p->sin_x = g_new (double, w);
  p->ginv = g_new (double, (gsize) starts * 6);
  p->starts = starts;
  for (guint x = 0; x < w; x++) {
    /* The phase reduced to one period first: cos of a large argument loses digits. */
    double u = fmod ((double) x, period) / period;
    p->cos_x[x] = cos (2 * G_PI * u);
    p->sin_x[x] = sin (2 * G_PI * u);
  }
  for (guint s = 0; s < starts; s++) {
    double g[6] = { 0 };
    for (guint j = s; j < s + l; j++) {
      double c = p->cos_x[j], sn = p->sin_x[j];
      g[0] += 1;
      g[1] += c;
      g[2] += sn;
      g[3] += c * c;
      g[4] += c * sn;
      g[5] += sn * sn;
    }
    double inv[6];
    gboolean ok = invert_sym3 (g, inv);
    for (guint i = 0; i < 6; i++)
      p->ginv[i * (gsize) starts + s] = inv[i];
    if (!ok) {
      g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_ILL_CONDITIONED,
                   "single-frame sine: a window of %u columns cannot resolve period %g px", l, period);
      return FALSE;
    }
  }
  return TRUE;
}

static gboolean
plan_init (Plan *p, const DsImage *frame, const DsImage *dark, const DsSeparationParams *params, GError **error)
{
  double period = params->geometry.period_px;
  p->estimator = params->estimator;
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
  p->b = params->black_level;
  p->m = ds_pattern_mean (params->pattern, params->duty, p->b);
  p->h = params->harmonic_gain > 0 ? params->harmonic_gain
                                   : ds_harmonic_gain_theory (params->pattern, params->duty, p->b);
  double cond = p->estimator == DS_ESTIMATOR_SINE ? fmax (1 / p->m, 1 / p->h) : fmax (1 / (1 - p->b), 1 / p->m);
  if (!(cond <= DS_MAX_CONDITION)) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_ILL_CONDITIONED,
                 "single-frame %s: the pattern (black level %g, duty %g) amplifies noise %.3g times, above %g",
                 ds_estimator_name (p->estimator), p->b, params->duty, cond, DS_MAX_CONDITION);
    return FALSE;
  }
  p->width = frame->width;
  p->window = (guint) ceil (period - 1e-9);
  if (frame->width < p->window) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_INVALID_ARGUMENT,
                 "single-frame: the frame is %u px wide, narrower than the window of one period (%u px)",
                 frame->width, p->window);
    return FALSE;
  }
  if (dark && !ds_image_same_shape (frame, dark)) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_SIZE_MISMATCH,
                 "single-frame: the dark frame is %ux%u %s, the frame %ux%u %s", dark->width, dark->height,
                 ds_sample_type_name (dark->type), frame->width, frame->height, ds_sample_type_name (frame->type));
    return FALSE;
  }
  if (params->saturation_level > 0)
    p->saturation = params->saturation_level;
  else if (frame->type == DS_SAMPLE_F32)
    p->saturation = INFINITY;
  else
    p->saturation = ldexp (1, (int) frame->bit_depth) - 1;
  return p->estimator == DS_ESTIMATOR_SINE ? plan_sine (p, period, error) : TRUE;
}

/* Per-row scratch: the row's values, its flag prefix counts, and the estimator's own. */
typedef struct {
  float *v;
  guint *sat, *bad;          /* prefix counts: saturated, non-finite columns before x */
  gboolean any_sat, any_bad; /* the row has some: else the counts are not kept */
  double *s0, *sc, *ss;      /* sine: prefix sums of v, v cos, v sin */
  float *pre_max, *suf_max, *pre_min, *suf_min; /* maxmin: van Herk / Gil-Werman blocks */
} Rows;

/* The row as floats (dark subtracted), non-finite values as 0, and whether any column is
 * saturated or non-finite; the prefix counts only then. Written per sample type so that the
 * common loop has no branch per sample. */
static void
read_row (const Plan *p, const DsImage *frame, const DsImage *dark, guint y, Rows *r)
{
  guint w = p->width;
  const void *row = ds_image_row (frame, y);
  float sat_level = (float) fmin (p->saturation, G_MAXFLOAT);
  guint n_sat = 0, n_bad = 0;
  if (frame->type == DS_SAMPLE_U16) {
    const guint16 *in = row;
    for (guint x = 0; x < w; x++) {
      r->v[x] = in[x];
      n_sat += in[x] >= sat_level;
    }
  } else if (frame->type == DS_SAMPLE_U8) {
    const guint8 *in = row;
    for (guint x = 0; x < w; x++) {
      r->v[x] = in[x];
      n_sat += in[x] >= sat_level;
    }
  } else {
    const float *in = row;
    for (guint x = 0; x < w; x++) {
      r->v[x] = in[x];
      n_sat += in[x] >= sat_level;
      n_bad += !isfinite (in[x]);
    }
  }
  if (dark) {
    const void *drow = ds_image_row (dark, y);
    for (guint x = 0; x < w; x++)
      r->v[x] -= (float) ds_image_sample (dark, drow, x);
    for (guint x = 0; x < w; x++)
      n_bad += !isfinite (r->v[x]);
  }
  r->any_sat = n_sat > 0;
  r->any_bad = n_bad > 0;
  if (!r->any_sat && !r->any_bad)
    return;
  r->sat[0] = r->bad[0] = 0;
  for (guint x = 0; x < w; x++) {
    double raw = ds_image_sample (frame, row, x);
    gboolean finite = isfinite (r->v[x]);
    r->sat[x + 1] = r->sat[x] + (finite && raw >= p->saturation);
    r->bad[x + 1] = r->bad[x] + !finite;
    if (!finite)
      r->v[x] = 0;
  }
}

/* max and min over each window [s, s + L): blocks of L columns, a prefix extreme from each
 * block's start and a suffix extreme to its end; a window spans at most two blocks, so its
 * extreme is the suffix's at s and the prefix's at s + L - 1 (O(1) per pixel for any L). */
static void
extremes_row (const Plan *p, Rows *r)
{
  guint w = p->width, l = p->window;
  const float *v = r->v;
  for (guint b = 0; b < w; b += l) {
    guint e = MIN (b + l, w);
    float mx = v[b], mn = v[b];
    for (guint x = b; x < e; x++) {
      mx = v[x] > mx ? v[x] : mx;
      mn = v[x] < mn ? v[x] : mn;
      r->pre_max[x] = mx;
      r->pre_min[x] = mn;
    }
    mx = mn = v[e - 1];
    for (guint x = e; x-- > b;) {
      mx = v[x] > mx ? v[x] : mx;
      mn = v[x] < mn ? v[x] : mn;
      r->suf_max[x] = mx;
      r->suf_min[x] = mn;
    }
  }
}

static void
sums_row (const Plan *p, Rows *r)
{
  double a = 0, c = 0, sn = 0;
  r->s0[0] = r->sc[0] = r->ss[0] = 0;
  for (guint x = 0; x < p->width; x++) {
    a += r->v[x];
    c += r->v[x] * p->cos_x[x];
    sn += r->v[x] * p->sin_x[x];
    r->s0[x + 1] = a;
    r->sc[x + 1] = c;
    r->ss[x + 1] = sn;
  }
}

/* Each pixel's window start: centred, clamped so that the window stays inside the row. */
static inline guint
window_start (const Plan *p, guint x)
{
  guint l = p->window, s = x >= l / 2 ? x - l / 2 : 0;
  return MIN (s, p->width - l);
}

static void
separate_row (const Plan *p, const Rows *r, float *ld_row, float *lg_row, guint8 *mask_row)
{
  guint w = p->width, l = p->window;
  if (p->estimator == DS_ESTIMATOR_SINE) {
    const double *g0 = p->ginv, *g1 = g0 + p->starts, *g2 = g1 + p->starts, *g3 = g2 + p->starts,
                 *g4 = g3 + p->starts, *g5 = g4 + p->starts;
    double inv_h = 1 / p->h, inv_m = 1 / p->m;
    for (guint x = 0; x < w; x++) {
      guint s = window_start (p, x), e = s + l;
      double t0 = r->s0[e] - r->s0[s], tc = r->sc[e] - r->sc[s], ts = r->ss[e] - r->ss[s];
      double mean = g0[s] * t0 + g1[s] * tc + g2[s] * ts;
      double a = g1[s] * t0 + g3[s] * tc + g4[s] * ts;
      double b = g2[s] * t0 + g4[s] * tc + g5[s] * ts;
      double ld = sqrt (a * a + b * b) * inv_h;
      double lg = mean * inv_m - ld;
      ld_row[x] = (float) ld;
      lg_row[x] = (float) lg;
      mask_row[x] = lg < 0 ? DS_MASK_NEGATIVE : 0;
    }
  } else {
    float inv_contrast = (float) (1 / (1 - p->b)), inv_m = (float) (1 / p->m), b = (float) p->b;
    for (guint x = 0; x < w; x++) {
      guint s = window_start (p, x), e = s + l;
      float mx = r->suf_max[s] > r->pre_max[e - 1] ? r->suf_max[s] : r->pre_max[e - 1];
      float mn = r->suf_min[s] < r->pre_min[e - 1] ? r->suf_min[s] : r->pre_min[e - 1];
      float ld = (mx - mn) * inv_contrast;
      float lg = (mn - b * ld) * inv_m;
      ld_row[x] = ld;
      lg_row[x] = lg;
      mask_row[x] = lg < 0 ? DS_MASK_NEGATIVE : 0;
    }
  }
  if (!r->any_sat && !r->any_bad)
    return;
  for (guint x = 0; x < w; x++) {
    guint s = window_start (p, x), e = s + l;
    if (r->sat[e] > r->sat[s])
      mask_row[x] |= DS_MASK_SATURATED;
    if (r->bad[e] > r->bad[s])
      mask_row[x] |= DS_MASK_NONFINITE;
  }
}

gboolean
ds_single_frame_separate (const DsImage *frame, const DsImage *dark, const DsSeparationParams *params,
                          DsSeparation **out, DsSingleFrameInfo *info, GError **error)
{
  g_return_val_if_fail (frame && params && out, FALSE);
  Plan plan = { 0 };
  if (!plan_init (&plan, frame, dark, params, error)) {
    plan_clear (&plan);
    return FALSE;
  }
  g_autoptr (DsSeparation) sep = ds_separation_new ();
  sep->transmissive = ds_image_new (DS_SAMPLE_F32, frame->width, frame->height, error);
  sep->scattered = sep->transmissive ? ds_image_new (DS_SAMPLE_F32, frame->width, frame->height, error) : NULL;
  sep->mask = sep->scattered ? ds_image_new (DS_SAMPLE_U8, frame->width, frame->height, error) : NULL;
  if (!sep->mask) {
    plan_clear (&plan);
    return FALSE;
  }
  guint w = frame->width;
  g_autofree float *values = g_new (float, (gsize) 5 * (w + 1));
  g_autofree double *sums = plan.estimator == DS_ESTIMATOR_SINE ? g_new (double, (gsize) 3 * (w + 1)) : NULL;
  g_autofree guint *counts = g_new (guint, (gsize) 2 * (w + 1));
  Rows r = { .v = values, .sat = counts, .bad = counts + w + 1 };
  r.pre_max = values + (w + 1);
  r.suf_max = values + 2 * (gsize) (w + 1);
  r.pre_min = values + 3 * (gsize) (w + 1);
  r.suf_min = values + 4 * (gsize) (w + 1);
  if (sums) {
    r.s0 = sums;
    r.sc = sums + (w + 1);
    r.ss = sums + 2 * (gsize) (w + 1);
  }
  guint64 counted[DS_MASK_N_BITS + 1] = { 0 };
  DsSeparationMeta *meta = &sep->meta;
  for (guint y = 0; y < frame->height; y++) {
    read_row (&plan, frame, dark, y, &r);
    if (plan.estimator == DS_ESTIMATOR_SINE)
      sums_row (&plan, &r);
    else
      extremes_row (&plan, &r);
    guint8 *mk = ds_image_row (sep->mask, y);
    separate_row (&plan, &r, ds_image_row (sep->transmissive, y), ds_image_row (sep->scattered, y), mk);
    ds_count_mask_row (mk, w, counted);
  }
  meta->valid_pixels = counted[0];
  for (guint bit = 0; bit < DS_MASK_N_BITS; bit++)
    meta->flagged[bit] = counted[1 + bit];
  meta->n_phases = plan.window;
  meta->frames_per_phase = 1;
  meta->estimator = plan.estimator;
  meta->duty = params->duty;
  meta->black_level = plan.b;
  meta->pattern_mean = plan.m;
  meta->harmonic_gain = plan.h;
  meta->dark_subtracted = dark != NULL;
  meta->noise_dn = NAN;
  meta->saturation_level = isfinite (plan.saturation) ? plan.saturation : NAN;
  meta->phase_offset_cycles = NAN;
  if (info)
    *info = (DsSingleFrameInfo) { .period_px = params->geometry.period_px, .window_px = plan.window };
  plan_clear (&plan);
  *out = g_steal_pointer (&sep);
  return TRUE;
}
