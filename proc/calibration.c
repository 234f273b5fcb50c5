/* Calibration of the stripe illuminator from a reference phase set (calibration.h). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "proc/calibration.h"
#include "proc/clip_level.h"
#include "proc/calibration_fit.h"
#include "proc/calibration_period.h"
#include "proc/calibration_sine.h"
#include "proc/calibration_steps.h"
#include "proc/harmonic_gain.h"
#include "proc/image_stats.h"
#include "proc/lit_level.h"
#include "proc/proc_error.h"
#include "proc/separation_internal.h"
#include "proc/stripe_period.h"
#include "proc/stripe_phase.h"

/* A clip below the format's top is a pile of 1 % of a frame's samples at its top: a reference
 * clips over its lit stripes, a share of tens of percent; an unclipped frame's top holds 1 % of
 * its samples only if nothing lies above 2.3 standard deviations of its brightest part, which
 * noise spreads further. Clips of fewer pixels are left in, their few samples low. */
#define DS_CALIBRATION_CLIP_PERCENTILE 99.0

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
  double pile_top;    /* the lowest top of a frame whose samples pile up there (clip_level.h) */
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
  c->pile_top = INFINITY;
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
  /* A sensor whose full well fills before its ADC's last code clips below the format's top (a
   * 12-bit sensor in Mono16 at 4095, say): its frames pile samples at that level. The dark frame,
   * which would vouch for the sensor's noise, may come later: each frame's own noise does. A
   * pixel is left out where its largest sample over the set reaches the level, so the pile must
   * be one no noise makes (DS_CALIBRATION_CLIP_PERCENTILE): the last code of a noise tail holds a
   * few samples of a frame (all of them in a small frame), and taking it for a clip would leave
   * out every pixel whose maximum over N frames reaches it. */
  double top;
  if (ds_clip_level_pile_top (frame, DS_CALIBRATION_CLIP_PERCENTILE, TRUE, &top))
    c->pile_top = MIN (c->pile_top, top);
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
                   "calibration: no stripes at any period from 2.5 to %.4g px: the strongest line in the "
                   "spectrum of phase 0 less phase %u is %.1f standard deviations of its noise, where 8 are "
                   "needed. Is the illuminator on and lighting the camera's view, and the reference clear? "
                   "Give the period if it is known",
                   c->w / 2.0, n / 2, snr);
      return FALSE;
    }
    out->period_measured = TRUE;
  }
  if (out->period_measured || hints->period_estimated)
    out->period_px = ds_calibration_period_refine ((DsImage *const *) means->pdata, n, out->period_px);
  double period = out->period_px;

  /* The stripes must step by 1/N of the period from one phase to the next: a period is found in
   * any picture that moves by itself (calibration_steps.h). */
  g_autofree DsStripePhase *sp = g_new (DsStripePhase, n);
  for (guint k = 0; k < n; k++)
    if (!ds_stripe_phase_measure (means->pdata[k], period, NULL, &sp[k], error))
      return FALSE;
  DsStripeSteps steps;
  if (!ds_stripe_steps_check (sp, n, period,
                              out->period_measured ? "measured" : hints->period_estimated ? "estimated" : "given",
                              &steps, error)) {
    g_prefix_error (error, "calibration: ");
    return FALSE;
  }

  /* Where phase 0 falls: the mean over phases of (measured phase - k/N), as a circular mean. */
  if (hints->phase_offset_known) {
    out->phase_offset_cycles = hints->phase_offset_cycles - floor (hints->phase_offset_cycles);
  } else {
    for (guint k = 0; k < n; k++)
      if (!sp[k].reliable) {
        g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_EMPTY,
                     "calibration: phase %u shows no measurable stripes at %g px (snr %.1f)", k, period, sp[k].snr);
        return FALSE;
      }
    double cs = 0, sn = 0;
    g_autofree double *off = g_new (double, n);
    for (guint k = 0; k < n; k++) {
      off[k] = sp[k].phase - (double) k / n;
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
  /* a pile-up above the dark level (light piles there, the dark frame's offset does not) */
  double dark_mean = 0;
  for (gsize i = 0; c->dark && i < c->npix; i++)
    dark_mean += c->dark[i] / c->npix;
  if (c->pile_top < sat && c->pile_top > dark_mean)
    sat = c->pile_top;
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
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_EMPTY,
                 "calibration: every pixel clips (at %.0f DN) in its lit phase or is not finite: lower the exposure "
                 "or the gain", sat);
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
  g_autofree double *profile = g_new0 (double, (gsize) DS_CALIBRATION_BINS * n);
  g_autofree double *profile_sq = g_new0 (double, (gsize) DS_CALIBRATION_BINS * n);
  g_autofree guint *filled = g_new0 (guint, DS_CALIBRATION_BINS);
  g_autofree double *position = g_new0 (double, DS_CALIBRATION_BINS);
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
      guint bin = (guint) ((pos - floor (pos)) * DS_CALIBRATION_BINS) % DS_CALIBRATION_BINS;
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
  for (guint j = 0; j < DS_CALIBRATION_BINS; j++) {
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
  DsCalibrationFit f = { .n = n, .profile = profile, .profile_sq = profile_sq, .filled = filled,
                         .position = position, .offset = out->phase_offset_cycles };
  ds_separation_params_init (&f.p, n);
  f.p.geometry.period_px = period;
  f.p.geometry.pixel_aperture = hints->pixel_aperture > 0 ? hints->pixel_aperture : 1.0;
  DsPatternCheck *pc = &out->pattern_check;
  pc->expected = hints->pattern;
  pc->detected = !hints->pattern_forced;
  double xq[3] = { 0.5, 0, 0 }, noise = 0, unused;
  if (pc->detected || hints->pattern == DS_PATTERN_SQUARE) {
    ds_calibration_fit_square (&f, a0, b0, xq);
    ds_calibration_fit_residual (&f, xq, &pc->square_residual, &noise);
    pc->square_blur_px = xq[2];
  } else {
    f.p.pattern = DS_PATTERN_SQUARE;
    ds_calibration_fit_residual (&f, xq, &unused, &noise);
  }
  if (pc->detected || hints->pattern == DS_PATTERN_SINE)
    pc->sine_residual = ds_calibration_fit_sine_residual (&f);
  pc->noise = noise;
  out->pattern = pc->detected ? ds_calibration_pattern_decide (pc) : hints->pattern;
  out->contrast = sum_a / sum_m;
  if (out->pattern == DS_PATTERN_SINE) {
    /* the profile's shape holds nothing but c = k g (calibration_sine.h): b stays what is known
     * until a second period tells it apart from the blur */
    out->duty = 0.5;
    out->black_level = CLAMP (hints->black_level, 0.0, 0.95);
    out->black_level_measured = FALSE;
    out->edge_blur_px = 0;
  } else {
    out->duty = xq[0];
    out->black_level = xq[1];
    out->black_level_measured = TRUE;
    out->edge_blur_px = xq[2] < 1e-3 ? 0 : xq[2];
  }
  out->harmonic_gain = ds_pattern_mean (out->pattern, out->duty, out->black_level) * out->contrast;
  /* the open field's lit level: the bright quantile of the pixels' levels the scene probe takes of
   * the scene's (DS_LIT_LEVEL_QUANTILE, proc/lit_level.h); brightness is NaN where not used */
  out->lit_level_dn = ds_finite_quantile (brightness, c->npix, DS_LIT_LEVEL_QUANTILE, 1) /
                      ds_pattern_mean (out->pattern, out->duty, out->black_level);
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

gboolean
ds_calibration_wants_second_period (const DsCalibration *cal)
{
  return cal->pattern == DS_PATTERN_SINE && !cal->black_level_measured;
}

void
ds_calibration_hints_second_period (DsCalibrationHints *hints, double second_period_px)
{
  hints->pattern = DS_PATTERN_SINE;
  hints->pattern_forced = TRUE;
  hints->period_px = second_period_px;
  hints->period_estimated = TRUE;
}

gboolean
ds_calibration_add_second_period (DsCalibration *cal, const DsCalibration *second, double pixel_aperture,
                                  GError **error)
{
  DsSineLevels lv;
  if (cal->pattern != DS_PATTERN_SINE ||
      !ds_sine_levels_from_contrasts (cal->period_px, cal->contrast, second->period_px, second->contrast, &lv)) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_INVALID_ARGUMENT,
                 "calibration: a second period tells a sine's black level from its blur only for sine stripes at "
                 "periods at least 1.25 x apart, each showing stripes (%s stripes, %.4g px with contrast %.4f and "
                 "%.4g px with %.4f)",
                 cal->pattern == DS_PATTERN_SINE ? "sine" : "square", cal->period_px, cal->contrast,
                 second->period_px, second->contrast);
    return FALSE;
  }
  cal->black_level = lv.black_level;
  cal->black_level_measured = TRUE;
  cal->second_period_px = second->period_px;
  cal->second_contrast = second->contrast;
  double w = pixel_aperture > 0 ? pixel_aperture : 1.0, s2 = lv.blur_px * lv.blur_px - w * w / 12;
  cal->edge_blur_px = s2 > 1e-6 ? sqrt (s2) : 0;
  cal->harmonic_gain = ds_pattern_mean (DS_PATTERN_SINE, 0.5, cal->black_level) * cal->contrast;
  cal->harmonic_gain_theory = ds_harmonic_gain_theory (DS_PATTERN_SINE, 0.5, cal->black_level);
  return TRUE;
}
