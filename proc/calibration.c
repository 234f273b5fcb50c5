/* Calibration of the stripe illuminator from a reference phase set (calibration.h). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "proc/calibration.h"
#include "proc/calibration_period.h"
#include "proc/harmonic_gain.h"
#include "proc/proc_error.h"
#include "proc/separation_internal.h"
#include "proc/stripe_period.h"
#include "proc/stripe_phase.h"

struct DsCalibrator {
  guint n, w, h;
  gsize npix;
  double *sum;        /* n planes of summed frames */
  guint *count;       /* frames per phase */
  float *rawmax;      /* largest raw sample per pixel */
  gboolean typed;
  DsSampleType type;
  guint bit_depth;
  float *dark;
};

void
ds_calibration_hints_init (DsCalibrationHints *hints)
{
  memset (hints, 0, sizeof *hints);
  hints->pattern = DS_PATTERN_SQUARE;
  hints->pixel_aperture = 1.0;
}

DsCalibrator *
ds_calibrator_new (guint n, guint width, guint height, GError **error)
{
  if (n < 3 || n > DS_MAX_PHASES || width == 0 || height == 0 || width > DS_IMAGE_MAX_SIDE ||
      height > DS_IMAGE_MAX_SIDE) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_INVALID_ARGUMENT,
                 "calibration needs 3..%u phases of frames 1..%u pixels on a side (got N = %u, %ux%u)",
                 DS_MAX_PHASES, DS_IMAGE_MAX_SIDE, n, width, height);
    return NULL;
  }
  gsize npix = (gsize) width * height, bytes;
  if (!g_size_checked_mul (&bytes, npix, (gsize) n * sizeof (double))) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_TOO_LARGE, "calibration state of %u x %ux%u overflows", n,
                 width, height);
    return NULL;
  }
  DsCalibrator *c = g_new0 (DsCalibrator, 1);
  c->n = n;
  c->w = width;
  c->h = height;
  c->npix = npix;
  c->sum = g_try_malloc0 (bytes);
  c->rawmax = g_try_new (float, npix);
  c->count = g_new0 (guint, n);
  if (!c->sum || !c->rawmax) {
    ds_calibrator_free (c);
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_TOO_LARGE, "cannot allocate %zu bytes of calibration state",
                 bytes);
    return NULL;
  }
  for (gsize i = 0; i < npix; i++)
    c->rawmax[i] = -INFINITY;
  return c;
}

void
ds_calibrator_free (DsCalibrator *c)
{
  if (!c)
    return;
  g_free (c->sum);
  g_free (c->rawmax);
  g_free (c->count);
  g_free (c->dark);
  g_free (c);
}

static double
sample (const DsImage *img, guint x, guint y)
{
  const void *row = ds_image_row (img, y);
  return img->type == DS_SAMPLE_U8    ? ((const guint8 *) row)[x]
         : img->type == DS_SAMPLE_U16 ? ((const guint16 *) row)[x]
                                      : ((const float *) row)[x];
}

static gboolean
check_shape (const DsCalibrator *c, const DsImage *img, const char *what, GError **error)
{
  if (img->width != c->w || img->height != c->h || (c->typed && img->type != c->type)) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_SIZE_MISMATCH,
                 "calibration: %s is %ux%u %s, the set is %ux%u%s%s", what, img->width, img->height,
                 ds_sample_type_name (img->type), c->w, c->h, c->typed ? " " : "",
                 c->typed ? ds_sample_type_name (c->type) : "");
    return FALSE;
  }
  return TRUE;
}

gboolean
ds_calibrator_add (DsCalibrator *c, guint phase, const DsImage *frame, GError **error)
{
  if (phase >= c->n) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_INVALID_ARGUMENT, "calibration: phase %u of N = %u", phase,
                 c->n);
    return FALSE;
  }
  g_autofree char *what = g_strdup_printf ("the frame of phase %u", phase);
  if (!check_shape (c, frame, what, error))
    return FALSE;
  c->typed = TRUE;
  c->type = frame->type;
  c->bit_depth = frame->bit_depth;
  double *plane = c->sum + (gsize) phase * c->npix;
  for (guint y = 0; y < c->h; y++)
    for (guint x = 0; x < c->w; x++) {
      gsize i = (gsize) y * c->w + x;
      double v = sample (frame, x, y);
      plane[i] += v; /* NaN stays NaN: the pixel is left out */
      c->rawmax[i] = v > c->rawmax[i] || isnan (v) ? (float) v : c->rawmax[i];
    }
  c->count[phase]++;
  return TRUE;
}

gboolean
ds_calibrator_set_dark (DsCalibrator *c, const DsImage *dark, GError **error)
{
  if (!check_shape (c, dark, "the dark frame", error))
    return FALSE;
  if (!c->dark)
    c->dark = g_new (float, c->npix);
  for (guint y = 0; y < c->h; y++)
    for (guint x = 0; x < c->w; x++)
      c->dark[(gsize) y * c->w + x] = (float) sample (dark, x, y);
  return TRUE;
}

/* Phase k's mean frame, dark subtracted, as a float image for the stripe measurements. */
static DsImage *
phase_mean (const DsCalibrator *c, guint k)
{
  DsImage *img = ds_image_new (DS_SAMPLE_F32, c->w, c->h, NULL);
  const double *s = c->sum + (gsize) k * c->npix;
  for (guint y = 0; y < c->h; y++) {
    float *row = ds_image_row (img, y);
    for (guint x = 0; x < c->w; x++) {
      gsize i = (gsize) y * c->w + x;
      row[x] = (float) (s[i] / c->count[k] - (c->dark ? c->dark[i] : 0.0));
    }
  }
  return img;
}

static int
compare_doubles (gconstpointer a, gconstpointer b)
{
  double x = *(const double *) a, y = *(const double *) b;
  return x < y ? -1 : x > y;
}

/* Mean of the middle 80 % (sorts v). */
static double
trimmed_mean (double *v, gsize n)
{
  qsort (v, n, sizeof (double), compare_doubles);
  gsize lo = n / 10, hi = n - n / 10;
  double s = 0;
  for (gsize i = lo; i < hi; i++)
    s += v[i];
  return hi > lo ? s / (hi - lo) : NAN;
}

/* The phase profile of the lit pixels, binned by where a pixel sits in the period: bin j holds
 * the mean over its pixels of V_k / mean_k V (the pixel's own brightness divides out). */
#define N_BINS 48u

typedef struct {
  DsSeparationParams p;       /* pattern, period, aperture; duty, b, blur are the unknowns */
  guint n;
  const double *profile;      /* N_BINS x n */
  const guint *filled;        /* pixels per bin */
  const double *position;     /* mean position of the bin's pixels in the period, [0, 1) */
  double offset;              /* cycles */
} FitData;

/* Sum of squared differences between the binned profile and the model at (a, b, sigma). */
static double
fit_cost (const FitData *f, const double x[3])
{
  DsSeparationParams p = f->p;
  p.duty = x[0];
  p.black_level = x[1];
  p.geometry.edge_blur_px = x[2];
  if (!(x[0] > 0.02 && x[0] < 0.98 && x[1] >= 0 && x[1] < 0.95 && x[2] >= 0 && x[2] < p.geometry.period_px))
    return INFINITY;
  double period = p.geometry.period_px, cost = 0, b = x[1];
  g_autofree double *model = g_new (double, f->n);
  for (guint j = 0; j < N_BINS; j++) {
    if (!f->filled[j])
      continue;
    double pos = f->position[j], mean = 0;
    for (guint k = 0; k < f->n; k++) {
      /* distance of the bin's pixels from the centre of phase k's stripe */
      double d = ds_stripe_phase_diff (pos, (double) k / f->n + f->offset) * period;
      model[k] = b + (1 - b) * ds_sampling_profile (&p, d);
      mean += model[k] / f->n;
    }
    for (guint k = 0; k < f->n; k++) {
      double r = f->profile[j * f->n + k] - model[k] / mean;
      cost += r * r;
    }
  }
  return cost;
}

/* Nelder-Mead over (a, b, sigma) from x; fixed[i] keeps coordinate i. */
static void
fit_minimise (const FitData *f, double x[3], const gboolean fixed[3])
{
  double simplex[4][3], cost[4];
  const double step[3] = { 0.05, 0.03, 0.3 };
  for (int v = 0; v < 4; v++) {
    for (int i = 0; i < 3; i++)
      simplex[v][i] = x[i] + (v == i + 1 && !fixed[i] ? step[i] : 0);
    cost[v] = fit_cost (f, simplex[v]);
  }
  for (int it = 0; it < 400; it++) {
    int hi = 0, lo = 0;
    for (int v = 1; v < 4; v++) {
      if (cost[v] > cost[hi])
        hi = v;
      if (cost[v] < cost[lo])
        lo = v;
    }
    int second = lo;
    for (int v = 0; v < 4; v++)
      if (v != hi && cost[v] > cost[second])
        second = v;
    if (cost[hi] - cost[lo] < 1e-14 * (1 + cost[lo]))
      break;
    double centre[3] = { 0, 0, 0 }, trial[3], expand[3];
    for (int v = 0; v < 4; v++)
      if (v != hi)
        for (int i = 0; i < 3; i++)
          centre[i] += simplex[v][i] / 3;
    for (int i = 0; i < 3; i++)
      trial[i] = fixed[i] ? x[i] : centre[i] + (centre[i] - simplex[hi][i]);
    double ct = fit_cost (f, trial);
    if (ct < cost[lo]) {
      for (int i = 0; i < 3; i++)
        expand[i] = fixed[i] ? x[i] : centre[i] + 2 * (centre[i] - simplex[hi][i]);
      double ce = fit_cost (f, expand);
      memcpy (simplex[hi], ce < ct ? expand : trial, sizeof trial);
      cost[hi] = MIN (ce, ct);
    } else if (ct < cost[second]) {
      memcpy (simplex[hi], trial, sizeof trial);
      cost[hi] = ct;
    } else {
      for (int i = 0; i < 3; i++)
        trial[i] = fixed[i] ? x[i] : centre[i] + 0.5 * (simplex[hi][i] - centre[i]);
      ct = fit_cost (f, trial);
      if (ct < cost[hi]) {
        memcpy (simplex[hi], trial, sizeof trial);
        cost[hi] = ct;
      } else {
        for (int v = 0; v < 4; v++)
          if (v != lo) {
            for (int i = 0; i < 3; i++)
              simplex[v][i] = fixed[i] ? x[i] : 0.5 * (simplex[v][i] + simplex[lo][i]);
            cost[v] = fit_cost (f, simplex[v]);
          }
      }
    }
  }
  int lo = 0;
  for (int v = 1; v < 4; v++)
    if (cost[v] < cost[lo])
      lo = v;
  memcpy (x, simplex[lo], 3 * sizeof (double));
}

/* How well the model at x explains the binned profile: its rms residual and the profile's
 * standard error, both over the profile's range (0 when the profile is flat). */
static void
profile_residual (const FitData *f, const double x[3], const double *profile_sq, double *residual, double *noise)
{
  double lo = INFINITY, hi = -INFINITY, se2 = 0;
  guint entries = 0;
  *residual = *noise = 0;
  for (guint j = 0; j < N_BINS; j++) {
    if (!f->filled[j])
      continue;
    for (guint k = 0; k < f->n; k++) {
      double m = f->profile[j * f->n + k];
      lo = MIN (lo, m);
      hi = MAX (hi, m);
      se2 += MAX (0.0, profile_sq[j * f->n + k] - m * m) / f->filled[j];
      entries++;
    }
  }
  if (!entries || !(hi > lo))
    return;
  *residual = sqrt (fit_cost (f, x) / entries) / (hi - lo);
  *noise = sqrt (se2 / entries) / (hi - lo);
}

/* A pure sinusoid's rms misfit over the profile's range: the profile (mean 1 per bin) against
 * 1 + c cos(2 pi (position - phase)), c by least squares (closed form), whatever the black level,
 * blur or pixel aperture that set c. */
static double
sine_residual (const FitData *f)
{
  double num = 0, den = 0, lo = INFINITY, hi = -INFINITY, ss = 0;
  guint entries = 0;
  for (int pass = 0; pass < 2; pass++)
    for (guint j = 0; j < N_BINS; j++) {
      if (!f->filled[j])
        continue;
      for (guint k = 0; k < f->n; k++) {
        double u = ds_stripe_phase_diff (f->position[j], (double) k / f->n + f->offset);
        double cs = cos (2 * G_PI * u), m = f->profile[j * f->n + k] - 1;
        if (pass == 0) {
          num += m * cs;
          den += cs * cs;
          lo = MIN (lo, m);
          hi = MAX (hi, m);
          entries++;
        } else {
          double r = m - num / den * cs;
          ss += r * r;
        }
      }
    }
  return entries && den > 0 && hi > lo ? sqrt (ss / entries) / (hi - lo) : 0;
}

/* Fits the pattern's model from the starting values; a sine has no duty, and contrast lost to
 * blur cannot be told from black level, so only b is free. */
static void
fit_pattern (FitData *f, DsPatternKind pattern, double a0, double b0, double x[3])
{
  f->p.pattern = pattern;
  gboolean sine = pattern == DS_PATTERN_SINE;
  gboolean fixed[3] = { sine, FALSE, sine };
  x[0] = sine ? 0.5 : a0;
  x[1] = b0;
  x[2] = sine ? 0 : 0.1;
  fit_minimise (f, x, fixed);
}

gboolean
ds_calibrator_finish (DsCalibrator *c, const DsCalibrationHints *hints, DsCalibration *out, GError **error)
{
  memset (out, 0, sizeof *out);
  guint n = c->n;
  out->n_phases = n;
  out->frames_per_phase = G_MAXUINT;
  for (guint k = 0; k < n; k++) {
    if (c->count[k] == 0) {
      g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_NOT_ENOUGH_PHASES, "calibration: phase %u of N = %u has no frame",
                   k, n);
      return FALSE;
    }
    out->frames_per_phase = MIN (out->frames_per_phase, c->count[k]);
  }
  out->pattern = hints->pattern;
  g_autoptr (GPtrArray) means = g_ptr_array_new_with_free_func ((GDestroyNotify) ds_image_free);
  for (guint k = 0; k < n; k++)
    g_ptr_array_add (means, phase_mean (c, k));

  /* The period, from phases 0 and N/2 (their difference cancels the reference's own detail). */
  if (hints->period_px > 0) {
    out->period_px = hints->period_px;
  } else {
    double snr;
    GError *local = NULL;
    if (!ds_stripe_period_detect (means->pdata[0], means->pdata[n / 2], &out->period_px, &snr, &local) && local) {
      g_propagate_error (error, local);
      return FALSE;
    }
    if (isnan (out->period_px)) {
      g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_EMPTY,
                   "calibration: no stripes found (the strongest line is %.1f sigma); is the illuminator "
                   "on and the reference clear? Give the period if it is known",
                   snr);
      return FALSE;
    }
    out->period_measured = TRUE;
  }
  if (out->period_measured || hints->period_estimated)
    out->period_px = ds_calibration_period_refine ((DsImage *const *) means->pdata, n, out->period_px);
  double period = out->period_px;

  /* Where phase 0 falls: the mean over phases of (measured phase - k/N), as a circular mean. */
  if (hints->phase_offset_known) {
    out->phase_offset_cycles = hints->phase_offset_cycles - floor (hints->phase_offset_cycles);
  } else {
    double cs = 0, sn = 0;
    g_autofree double *off = g_new (double, n);
    for (guint k = 0; k < n; k++) {
      DsStripePhase sp;
      if (!ds_stripe_phase_measure (means->pdata[k], period, NULL, &sp, error))
        return FALSE;
      if (!sp.reliable) {
        g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_EMPTY,
                     "calibration: phase %u shows no measurable stripes at %g px (snr %.1f)", k, period, sp.snr);
        return FALSE;
      }
      off[k] = sp.phase - (double) k / n;
      cs += cos (2 * G_PI * off[k]);
      sn += sin (2 * G_PI * off[k]);
    }
    double o = atan2 (sn, cs) / (2 * G_PI);
    out->phase_offset_cycles = o - floor (o);
    double ss = 0;
    for (guint k = 0; k < n; k++) {
      double r = ds_stripe_phase_diff (off[k], out->phase_offset_cycles);
      ss += r * r;
    }
    out->offset_spread = sqrt (ss / n);
  }

  /* Per column, the phase whose stripe centre is nearest (lit) and the one nearest the middle
   * between stripes (dark). */
  g_autofree guint *k_lit = g_new (guint, c->w), *k_dark = g_new (guint, c->w);
  for (guint x = 0; x < c->w; x++) {
    double best_l = INFINITY, best_d = INFINITY;
    for (guint k = 0; k < n; k++) {
      double u = fabs (ds_stripe_phase_diff ((double) x / period, (double) k / n + out->phase_offset_cycles));
      if (u < best_l) {
        best_l = u;
        k_lit[x] = k;
      }
      if (fabs (u - 0.5) < best_d) {
        best_d = fabs (u - 0.5);
        k_dark[x] = k;
      }
    }
  }
  double sat = hints->saturation_level > 0 ? hints->saturation_level
               : c->type != DS_SAMPLE_F32  ? (double) ((1u << c->bit_depth) - 1u)
                                           : INFINITY;
  /* Lit pixels: above a quarter of the 90th percentile of the lit level, and never clipped. */
  g_autofree double *lit = g_new (double, c->npix);
  gsize nl = 0;
  for (guint y = 0; y < c->h; y++)
    for (guint x = 0; x < c->w; x++) {
      gsize i = (gsize) y * c->w + x;
      double v = ((const float *) ds_image_row (means->pdata[k_lit[x]], y))[x];
      if (isfinite (v) && c->rawmax[i] < sat)
        lit[nl++] = v;
    }
  if (nl == 0) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_EMPTY, "calibration: every pixel is clipped or not finite");
    return FALSE;
  }
  qsort (lit, nl, sizeof (double), compare_doubles);
  double threshold = 0.25 * lit[(gsize) (0.9 * (nl - 1))];
  g_autofree double *ratio_b = g_new (double, c->npix), *ratio_m = g_new (double, c->npix);
  g_autofree double *cos_k = g_new (double, n), *sin_k = g_new (double, n);
  for (guint k = 0; k < n; k++) {
    cos_k[k] = cos (2 * G_PI * k / n);
    sin_k[k] = sin (2 * G_PI * k / n);
  }
  gsize used = 0;
  double sum_a = 0, sum_m = 0;
  g_autofree double *profile = g_new0 (double, (gsize) N_BINS * n);
  g_autofree double *profile_sq = g_new0 (double, (gsize) N_BINS * n);
  g_autofree guint *filled = g_new0 (guint, N_BINS);
  g_autofree double *position = g_new0 (double, N_BINS);
  /* per pixel, for the scattering check: brightness (mean over phases) and off/lit fraction */
  g_autofree double *brightness = g_new (double, c->npix), *off = g_new (double, c->npix);
  for (gsize i = 0; i < c->npix; i++)
    brightness[i] = off[i] = NAN;
  for (guint y = 0; y < c->h; y++)
    for (guint x = 0; x < c->w; x++) {
      gsize i = (gsize) y * c->w + x;
      double vl = ((const float *) ds_image_row (means->pdata[k_lit[x]], y))[x];
      double vd = ((const float *) ds_image_row (means->pdata[k_dark[x]], y))[x];
      if (!(vl > threshold) || !(c->rawmax[i] < sat) || !isfinite (vd))
        continue;
      double cs = 0, sn = 0, mean = 0;
      for (guint k = 0; k < n; k++) {
        double v = ((const float *) ds_image_row (means->pdata[k], y))[x];
        cs += v * cos_k[k];
        sn += v * sin_k[k];
        mean += v / n;
      }
      if (!isfinite (mean))
        continue;
      brightness[i] = mean;
      off[i] = vd / vl;
      ratio_b[used] = vd / vl;
      ratio_m[used] = mean / vl;
      double pos = (double) x / period;
      guint bin = (guint) ((pos - floor (pos)) * N_BINS) % N_BINS;
      position[bin] += pos - floor (pos);
      for (guint k = 0; k < n; k++) {
        double v = ((const float *) ds_image_row (means->pdata[k], y))[x] / mean;
        profile[bin * n + k] += v;
        profile_sq[bin * n + k] += v * v;
      }
      filled[bin]++;
      sum_a += 2.0 / n * hypot (cs, sn);
      sum_m += mean;
      used++;
    }
  for (guint j = 0; j < N_BINS; j++) {
    for (guint k = 0; k < n && filled[j]; k++) {
      profile[j * n + k] /= filled[j];
      profile_sq[j * n + k] /= filled[j];
    }
    position[j] = filled[j] ? position[j] / filled[j] : 0;
  }
  if (used < 16 || !(sum_m > 0)) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_EMPTY,
                 "calibration: only %zu lit, unclipped pixels (need 16); expose longer or use a clearer reference",
                 (size_t) used);
    return FALSE;
  }
  out->pixels_used = used;
  /* Starting values from the lit and dark phases (exact for sharp stripes and point pixels) */
  double b0 = CLAMP (trimmed_mean (ratio_b, used), 0.0, 0.9);
  double m0 = trimmed_mean (ratio_m, used);
  double a0 = CLAMP ((m0 - b0) / (1 - b0), 0.05, 0.95);
  /* ... then a, b and the edge blur fitted to the phase profile binned by position in the period,
   * which blur and pixel integration shape (the lit phase is not fully lit then); both patterns
   * unless one is forced, and the profile decides (calibration_pattern.h). */
  FitData f = { .n = n, .profile = profile, .filled = filled, .position = position,
                .offset = out->phase_offset_cycles };
  ds_separation_params_init (&f.p, n);
  f.p.geometry.period_px = period;
  f.p.geometry.pixel_aperture = hints->pixel_aperture > 0 ? hints->pixel_aperture : 1.0;
  DsPatternCheck *pc = &out->pattern_check;
  pc->expected = hints->pattern;
  pc->detected = !hints->pattern_forced;
  double xs[3] = { 0.5, 0, 0 }, xq[3] = { 0.5, 0, 0 }, noise = 0;
  if (pc->detected || hints->pattern == DS_PATTERN_SINE) {
    fit_pattern (&f, DS_PATTERN_SINE, a0, b0, xs);
    profile_residual (&f, xs, profile_sq, &pc->sine_residual, &noise);
    pc->sine_residual = sine_residual (&f);
  }
  if (pc->detected || hints->pattern == DS_PATTERN_SQUARE) {
    fit_pattern (&f, DS_PATTERN_SQUARE, a0, b0, xq);
    profile_residual (&f, xq, profile_sq, &pc->square_residual, &noise);
    pc->square_blur_px = xq[2];
  }
  pc->noise = noise;
  out->pattern = pc->detected ? ds_calibration_pattern_decide (pc) : hints->pattern;
  const double *x = out->pattern == DS_PATTERN_SINE ? xs : xq;
  out->duty = x[0];
  out->black_level = x[1];
  out->edge_blur_px = x[2] < 1e-3 ? 0 : x[2];
  out->harmonic_gain = ds_pattern_mean (out->pattern, out->duty, out->black_level) * sum_a / sum_m;
  out->harmonic_gain_theory = ds_harmonic_gain_theory (out->pattern, out->duty, out->black_level);
  ds_calibration_scatter_check (brightness, off, c->w, c->h, period, &out->scatter);
  /* scattered light that keeps square stripes has tails no blurred edge has; a sine stays a sine */
  if (out->pattern == DS_PATTERN_SQUARE) {
    out->scatter.shape_residual = pc->square_residual;
    out->scatter.shape_noise = noise;
    if (pc->square_residual > 0)
      ds_calibration_scatter_shape (&out->scatter);
  }
  return TRUE;
}

char *
ds_calibration_pattern_notice (const DsCalibration *cal)
{
  const DsPatternCheck *p = &cal->pattern_check;
  if (!p->detected || cal->pattern == p->expected)
    return NULL;
  if (cal->pattern == DS_PATTERN_SQUARE)
    return g_strdup_printf ("the stripes are square, not sine: a sinusoid leaves %.2f %% of the stripe contrast "
                            "unexplained in the period profile, a blurred square (edge blur %.2f px) %.2f %%, where "
                            "the profile's own noise is %.2f %%. Configure pattern=square (the lines below)",
                            100 * p->sine_residual, p->square_blur_px, 100 * p->square_residual, 100 * p->noise);
  return g_strdup_printf ("the stripes are sine, not square: a sinusoid fits the period profile to %.2f %% of the "
                          "stripe contrast, where the profile's own noise is %.2f %%; %s (edge blur %.2f px, "
                          "residual %.2f %%). Configure pattern=sine (the lines below), so the separation uses the "
                          "sine estimator and its harmonic gain",
                          100 * p->sine_residual, 100 * p->noise,
                          p->square_fits ? "a blurred square fits only with a blur that erases every harmonic above "
                                           "the first: indistinguishable from a sine"
                                         : "no blurred square fits as well",
                          p->square_blur_px, 100 * p->square_residual);
}

char *
ds_calibration_scatter_warning (const DsCalibration *cal)
{
  const DsScatterCheck *s = &cal->scatter;
  if (!s->scattering)
    return NULL;
  GString *w = g_string_new ("the reference scatters: ");
  if (s->shape_misfit)
    g_string_append_printf (w,
                            "its light between the stripes is not the flat black level of blurred square stripes "
                            "(no blurred square fits the period profile better than %.1f %% of the stripe contrast, "
                            "where the profile's own noise is %.2f %%)",
                            100 * s->shape_residual, 100 * s->shape_noise);
  if (s->shape_misfit && s->spatial)
    g_string_append (w, ", and ");
  if (s->spatial)
    g_string_append_printf (w,
                            "its off-stripe light is %.3f of the lit level on its dim parts and %.3f on its bright "
                            "ones (brightness x%.1f apart relative to their surroundings), where a black level "
                            "would be the same fraction everywhere",
                            s->off_dim, s->off_bright, s->brightness_contrast);
  g_string_append_printf (w,
                          ". Scattered light is read as black level and harmonic gain, so duty, black level %.4f, "
                          "harmonic gain %.4f and edge blur %.2f px are not to be trusted (only the period and "
                          "phase offset are). Calibrate on a clear reference: no scattering medium, or a thin "
                          "clear sample",
                          cal->black_level, cal->harmonic_gain, cal->edge_blur_px);
  return g_string_free (w, FALSE);
}
