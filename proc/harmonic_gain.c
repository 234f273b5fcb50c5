/* Pattern mean and first-harmonic gain: theory and calibration on a non-scattering reference. */
#include <math.h>

#include "proc/harmonic_gain.h"
#include "proc/proc_error.h"

double
ds_pattern_mean (DsPatternKind pattern, double duty, double black_level)
{
  if (pattern == DS_PATTERN_SINE)
    return black_level + (1.0 - black_level) * 0.5;
  return duty + black_level * (1.0 - duty);
}

double
ds_harmonic_gain_theory (DsPatternKind pattern, double duty, double black_level)
{
  if (pattern == DS_PATTERN_SINE)
    return (1.0 - black_level) * 0.5;
  return (1.0 - black_level) * (2.0 / G_PI) * sin (G_PI * duty);
}

double
ds_harmonic_gain_sampled (DsPatternKind pattern, double duty, double black_level, guint n_phases)
{
  double lit = duty * n_phases;
  if (pattern != DS_PATTERN_SQUARE || n_phases < 2 || fabs (lit - round (lit)) > 1e-9 || round (lit) < 1)
    return ds_harmonic_gain_theory (pattern, duty, black_level);
  return (1.0 - black_level) * 2.0 * sin (G_PI * round (lit) / n_phases) /
         (n_phases * sin (G_PI / n_phases));
}

gboolean
ds_harmonic_gain_from_separation (const DsSeparation *ref, double *h_out, GError **error)
{
  if (!ref || ref->meta.estimator != DS_ESTIMATOR_SINE || !ref->mean) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_INVALID_ARGUMENT,
                 "harmonic gain calibration needs a separation made with the sine estimator and "
                 "keep_extrema (got %s%s)",
                 ref ? ds_estimator_name (ref->meta.estimator) : "none",
                 ref && !ref->mean ? ", no mean" : "");
    return FALSE;
  }
  double sum_a = 0, sum_m = 0;
  guint64 used = 0;
  for (guint y = 0; y < ref->mask->height; y++) {
    const guint8 *mk = ds_image_row (ref->mask, y);
    const float *ld = ds_image_row (ref->transmissive, y);
    const float *mean = ds_image_row (ref->mean, y);
    for (guint x = 0; x < ref->mask->width; x++)
      /* Lg of a reference is ~0 and may come out slightly negative: not a reason to skip */
      if ((mk[x] & ~DS_MASK_NEGATIVE) == 0 && mean[x] > 0) {
        sum_a += (double) ld[x] * ref->meta.harmonic_gain;
        sum_m += mean[x];
        used++;
      }
  }
  if (!used || !(sum_m > 0)) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_EMPTY,
                 "harmonic gain calibration: no pixel of the %ux%u reference is unflagged and lit",
                 ref->mask->width, ref->mask->height);
    return FALSE;
  }
  *h_out = ref->meta.pattern_mean * sum_a / sum_m;
  return TRUE;
}

gboolean
ds_harmonic_gain_calibrate (const DsImage *const *frames, guint n_phases, const DsImage *dark,
                            DsPatternKind pattern, double duty, double black_level, double *h_out,
                            GError **error)
{
  if (!frames || n_phases == 0 || !frames[0]) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_EMPTY, "harmonic gain calibration: no frames");
    return FALSE;
  }
  DsSeparationParams p;
  ds_separation_params_init (&p, n_phases);
  p.estimator = DS_ESTIMATOR_SINE;
  p.pattern = pattern;
  p.duty = duty;
  p.black_level = black_level;
  p.keep_extrema = TRUE;
  g_autoptr (DsPhaseSet) set = ds_phase_set_new (&p, frames[0]->width, frames[0]->height, error);
  if (!set)
    return FALSE;
  if (dark && !ds_phase_set_set_dark (set, dark, error))
    return FALSE;
  for (guint k = 0; k < n_phases; k++) {
    if (!frames[k]) {
      g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_EMPTY,
                   "harmonic gain calibration: frame of phase %u missing", k);
      return FALSE;
    }
    if (!ds_phase_set_accumulate (set, k, frames[k], error))
      return FALSE;
  }
  g_autoptr (DsSeparation) sep = ds_phase_set_finalize (set, error);
  return sep && ds_harmonic_gain_from_separation (sep, h_out, error);
}
