/* Sine stripes' black level and harmonic gain, told apart (calibration_sine.h). */
#include <math.h>

#include "proc/calibration_sine.h"

gboolean
ds_sine_levels_from_contrasts (double p1, double c1, double p2, double c2, DsSineLevels *out)
{
  if (!(p1 > 0 && p2 > 0) || !(c1 > 0 && c1 <= 1) || !(c2 > 0 && c2 <= 1) || MAX (p1, p2) / MIN (p1, p2) < 1.25)
    return FALSE;
  double f1 = 1 / (p1 * p1), f2 = 1 / (p2 * p2);
  double alpha = MAX (0.0, (log (c2) - log (c1)) / (f1 - f2));
  /* alpha clamped: both contrasts say the same k; the longer period's is the nearer to it */
  double k = MIN (1.0, alpha > 0 ? c1 * exp (alpha * f1) : MAX (c1, c2));
  out->black_level = (1 - k) / (1 + k);
  out->blur_px = sqrt (alpha / (2 * G_PI * G_PI));
  return TRUE;
}

double
ds_sine_gain_at_period (double g_from, double p_from, double p_to)
{
  if (!(g_from > 0) || !(p_from > 0) || !(p_to > 0))
    return g_from;
  return pow (MIN (g_from, 1.0), (p_from / p_to) * (p_from / p_to));
}
