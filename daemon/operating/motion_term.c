#include "daemon/operating/motion_term.h"

#include <gio/gio.h>
#include <math.h>

void
ds_motion_frame_times (const DsRigTiming *timing, guint width, guint height, guint n, guint m, double exposure_us,
                       double *times_s)
{
  /* The model's frame and settle times read off it as differences, so the two stay one model. */
  double one = ds_rig_timing_set_ms (timing, width, height, 1, 1, exposure_us, FALSE);
  double frame_ms = ds_rig_timing_set_ms (timing, width, height, 1, 2, exposure_us, FALSE) - one;
  double settle_ms = one - frame_ms;
  for (guint k = 0; k < n; k++)
    for (guint j = 0; j < m; j++)
      times_s[k * m + j] = (k * (settle_ms + m * frame_ms) + settle_ms + j * frame_ms) / 1e3 +
                           (timing->trigger_overhead_us + exposure_us / 2) / 1e6;
}

double
ds_motion_kappa (DsEstimator estimator)
{
  switch (estimator) {
  case DS_ESTIMATOR_SINE:
    /* (1/12 + 1/(2 pi^2)) / (1/4) */
    return 4.0 * (1.0 / 12.0 + 1.0 / (2.0 * G_PI * G_PI));
  case DS_ESTIMATOR_MAXMIN:
    /* (3/8) / (1/4) */
    return 1.5;
  default:
    return NAN;
  }
}

/* T at x - s along a row, linear between pixels, the edge pixel beyond the image. */
static inline double
shifted (const float *row, guint width, double x)
{
  if (x <= 0)
    return row[0];
  if (x >= width - 1)
    return row[width - 1];
  guint i = (guint) x;
  double f = x - i;
  return row[i] + f * ((double) row[i + 1] - row[i]);
}

gboolean
ds_motion_term (const DsImage *t, double speed, const double *times_s, guint n_times, DsEstimator estimator,
                double *term, GError **error)
{
  if (!t || t->type != DS_SAMPLE_F32 || !isfinite (speed) || n_times == 0) {
    g_set_error (error, G_IO_ERROR, G_IO_ERROR_INVALID_ARGUMENT,
                 "motion term: needs an f32 image, a finite speed and at least one frame time");
    return FALSE;
  }
  for (guint k = 0; k < n_times; k++)
    if (!isfinite (times_s[k])) {
      g_set_error (error, G_IO_ERROR, G_IO_ERROR_INVALID_ARGUMENT, "motion term: frame %u's time is not finite", k);
      return FALSE;
    }
  /* The middle between the first and the last frame: where the truth is taken. */
  double t_mid = (times_s[0] + times_s[n_times - 1]) / 2;
  double departure = 0, light = 0;
  for (guint y = 0; y < t->height; y++) {
    const float *row = ds_image_row (t, y);
    for (guint x = 0; x < t->width; x++) {
      double v = row[x], d = 0;
      for (guint k = 0; k < n_times; k++) {
        double e = shifted (row, t->width, x - speed * (times_s[k] - t_mid)) - v;
        d += e * e;
      }
      departure += d / n_times;
      light += v * v;
    }
  }
  if (!(light > 0)) {
    g_set_error (error, G_IO_ERROR, G_IO_ERROR_INVALID_ARGUMENT, "motion term: the image has no light");
    return FALSE;
  }
  *term = sqrt (ds_motion_kappa (estimator) * departure / light);
  return TRUE;
}

gboolean
ds_motion_apply (DsOperatingPoint *p, double speed_px_s, double term, guint64 motion_pixels, const char **why)
{
  const char *reason = NULL;
  if (isnan (speed_px_s)) {
    if (motion_pixels > 0)
      reason = "motion seen and no speed declared: the prediction assumes a still scene";
  } else if (isnan (term)) {
    reason = "a speed was declared, and this estimator's motion error has no model";
  } else {
    p->predicted_error = hypot (p->predicted_error, term);
    if (isfinite (p->predicted_error_upper))
      p->predicted_error_upper = hypot (p->predicted_error_upper, term);
  }
  if (why)
    *why = reason;
  if (!reason)
    return FALSE;
  p->lower_bound = TRUE;
  return TRUE;
}
