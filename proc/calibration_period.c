/* A detected stripe period refined on the whole phase set (calibration_period.h). */
#include <math.h>

#include "proc/calibration_period.h"
#include "proc/stripe_phase.h"

double
ds_calibration_period_refine (DsImage *const *means, guint n, double period)
{
  guint w = means[0]->width, h = means[0]->height;
  g_autofree double *re = g_new0 (double, w), *im = g_new0 (double, w);
  for (guint k = 0; k < n; k++) {
    double ck = cos (2 * G_PI * k / n), sk = sin (2 * G_PI * k / n);
    for (guint y = 0; y < h; y++) {
      const float *row = ds_image_row (means[k], y);
      for (guint x = 0; x < w; x++)
        if (isfinite (row[x])) {
          re[x] += row[x] * ck;
          im[x] += row[x] * sk;
        }
    }
  }
  /* r(x) = column phase - x / P: constant at the true period, a line of slope 1/P' - 1/P
   * otherwise; centred on its circular mean so that it does not wrap */
  double cs = 0, sn = 0;
  for (guint x = 0; x < w; x++) {
    double r = atan2 (im[x], re[x]) / (2 * G_PI) - x / period;
    double a = hypot (re[x], im[x]);
    cs += a * cos (2 * G_PI * r);
    sn += a * sin (2 * G_PI * r);
  }
  double centre = atan2 (sn, cs) / (2 * G_PI);
  double sw = 0, sx = 0, sr = 0, sxx = 0, sxr = 0;
  for (guint x = 0; x < w; x++) {
    double a = hypot (re[x], im[x]);
    if (!(a > 0) || !isfinite (a))
      continue;
    double r = ds_stripe_phase_diff (atan2 (im[x], re[x]) / (2 * G_PI) - x / period, centre);
    sw += a;
    sx += a * x;
    sr += a * r;
    sxx += a * x * x;
    sxr += a * x * r;
  }
  double den = sw * sxx - sx * sx;
  if (!(sw > 0) || !(den > 0))
    return period;
  double slope = (sw * sxr - sx * sr) / den;
  double refined = 1 / (1 / period + slope);
  return isfinite (refined) && fabs (refined / period - 1) < 0.02 ? refined : period;
}
