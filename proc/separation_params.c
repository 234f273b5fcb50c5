/* Separation parameters: names, defaults, validation; and freeing a result. */
#include <math.h>
#include <string.h>

#include "proc/harmonic_gain.h"
#include "proc/proc_error.h"
#include "proc/separation.h"

static const char *const estimator_names[] = { "maxmin", "sine", "robust" };
static const struct {
  const char *name;
  const char *meaning;
} mask_bits[DS_MASK_N_BITS] = {
  { "saturated", "some raw sample at or above the saturation level" },
  { "dark", "mean signal below the noise floor" },
  { "low_modulation", "stripe modulation not distinguishable from noise" },
  { "nonfinite", "NaN or Inf in an input frame, or an output beyond float32; the outputs of the pixel are 0" },
  { "negative", "a component came out below zero (noise); left unclipped" },
  { "dark_exceeds", "the dark frame is brighter than some phase at this pixel" },
  { "undersampled", "no phase lit the pixel fully or none left it fully dark (sampling precondition); the value is biased" },
  { "motion", "the phase samples depart from a still scene under the pattern by more than noise: the scene moved during the set" },
};

const char *
ds_mask_bit_name (guint bit)
{
  return bit < DS_MASK_N_BITS ? mask_bits[bit].name : NULL;
}

const char *
ds_mask_bit_meaning (guint bit)
{
  return bit < DS_MASK_N_BITS ? mask_bits[bit].meaning : NULL;
}

const char *
ds_estimator_name (DsEstimator estimator)
{
  if ((guint) estimator < G_N_ELEMENTS (estimator_names))
    return estimator_names[estimator];
  return "unknown";
}

gboolean
ds_estimator_from_name (const char *name, DsEstimator *out)
{
  for (guint i = 0; name && i < G_N_ELEMENTS (estimator_names); i++)
    if (g_ascii_strcasecmp (name, estimator_names[i]) == 0) {
      *out = (DsEstimator) i;
      return TRUE;
    }
  return FALSE;
}

void
ds_separation_params_init (DsSeparationParams *params, guint n_phases)
{
  memset (params, 0, sizeof *params);
  params->estimator = DS_ESTIMATOR_MAXMIN;
  params->pattern = DS_PATTERN_SQUARE;
  params->n_phases = n_phases;
  params->duty = 0.5;
  params->black_level = 0.0;
  params->threads = 0;
  params->geometry.pixel_aperture = 1.0;
}

static gboolean
check_range (const char *what, double v, double lo, double hi, gboolean lo_open, gboolean hi_open,
             GError **error)
{
  gboolean ok = isfinite (v) && (lo_open ? v > lo : v >= lo) && (hi_open ? v < hi : v <= hi);
  if (!ok)
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_INVALID_ARGUMENT,
                 "%s = %g is outside its range %c%g, %g%c", what, v, lo_open ? '(' : '[', lo, hi,
                 hi_open ? ')' : ']');
  return ok;
}

gboolean
ds_separation_params_validate (const DsSeparationParams *p, GError **error)
{
  if ((guint) p->estimator > DS_ESTIMATOR_ROBUST) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_INVALID_ARGUMENT,
                 "estimator %d is not one of maxmin, sine, robust", (int) p->estimator);
    return FALSE;
  }
  if ((guint) p->pattern > DS_PATTERN_SINE) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_INVALID_ARGUMENT,
                 "pattern %d is not one of square, sine", (int) p->pattern);
    return FALSE;
  }
  guint need = p->estimator == DS_ESTIMATOR_SINE ? 3 : 2;
  if (p->n_phases < need) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_NOT_ENOUGH_PHASES,
                 "the %s estimator needs at least %u phases, got N = %u",
                 ds_estimator_name (p->estimator), need, p->n_phases);
    return FALSE;
  }
  if (p->n_phases > DS_MAX_PHASES) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_INVALID_ARGUMENT,
                 "N = %u phases exceeds the limit of %u", p->n_phases, DS_MAX_PHASES);
    return FALSE;
  }
  if (!check_range ("duty a", p->duty, 0, 1, TRUE, TRUE, error) ||
      !check_range ("black level b", p->black_level, 0, 1, FALSE, TRUE, error) ||
      !check_range ("harmonic_gain h", p->harmonic_gain, 0, 1, FALSE, FALSE, error) ||
      !check_range ("saturation_level", p->saturation_level, 0, G_MAXFLOAT, FALSE, FALSE, error) ||
      !check_range ("system_gain K", p->system_gain, 0, 1e6, FALSE, FALSE, error) ||
      !check_range ("read_noise_dn", p->read_noise_dn, 0, 1e9, FALSE, FALSE, error) ||
      !check_range ("stripe period_px", p->geometry.period_px, 0, 1e6, FALSE, FALSE, error) ||
      !check_range ("edge_blur_px", p->geometry.edge_blur_px, 0, 1e4, FALSE, FALSE, error) ||
      !check_range ("pixel_aperture", p->geometry.pixel_aperture, 0, 64, FALSE, FALSE, error) ||
      (p->geometry.phase_offset_known &&
       !check_range ("phase_offset_cycles", p->geometry.phase_offset_cycles, -1e6, 1e6, FALSE, FALSE, error)))
    return FALSE;
  if (p->geometry.period_px > 0 && p->geometry.period_px <= 2) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_INVALID_ARGUMENT,
                 "stripe period_px = %g: stripes finer than 2 pixels cannot be resolved (0 = unknown)",
                 p->geometry.period_px);
    return FALSE;
  }

  double cond = 1.0 / (1.0 - p->black_level);
  if (cond > DS_MAX_CONDITION) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_ILL_CONDITIONED,
                 "black level b = %g: condition number 1/(1-b) = %.4g exceeds DS_MAX_CONDITION = %g",
                 p->black_level, cond, DS_MAX_CONDITION);
    return FALSE;
  }
  double m = ds_pattern_mean (p->pattern, p->duty, p->black_level);
  if (1.0 / m > DS_MAX_CONDITION) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_ILL_CONDITIONED,
                 "pattern mean m = %g: condition number 1/m = %.4g exceeds DS_MAX_CONDITION = %g",
                 m, 1.0 / m, DS_MAX_CONDITION);
    return FALSE;
  }
  if (p->estimator == DS_ESTIMATOR_SINE) {
    double h = p->harmonic_gain > 0 ? p->harmonic_gain
                                    : ds_harmonic_gain_theory (p->pattern, p->duty, p->black_level);
    if (!(h > 0) || 1.0 / h > DS_MAX_CONDITION) {
      g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_ILL_CONDITIONED,
                   "harmonic gain h = %g: condition number 1/h = %.4g exceeds DS_MAX_CONDITION = %g",
                   h, 1.0 / h, DS_MAX_CONDITION);
      return FALSE;
    }
  }
  DsSamplingCheck check;
  return ds_separation_check_sampling (p, &check, error);
}

void
ds_separation_free (DsSeparation *sep)
{
  if (!sep)
    return;
  ds_image_free (sep->transmissive);
  ds_image_free (sep->scattered);
  ds_image_free (sep->mask);
  ds_image_free (sep->max);
  ds_image_free (sep->min);
  ds_image_free (sep->mean);
  ds_image_free (sep->sigma_transmissive);
  ds_image_free (sep->sigma_scattered);
  g_free (sep);
}
