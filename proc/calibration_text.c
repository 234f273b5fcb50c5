/* The calibration's notices and warnings, as text (calibration.h). */
#include "proc/calibration.h"

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
char *
ds_calibration_black_level_note (const DsCalibration *cal)
{
  if (cal->pattern != DS_PATTERN_SINE || cal->black_level_measured)
    return NULL;
  return g_strdup_printf ("one stripe period cannot tell a sine's black level from the contrast blur and the "
                          "pixel take away (both only scale its harmonic): black-level=%.4f is the configured "
                          "value, assumed, not measured, and harmonic-gain=%.4f goes with it. To measure it, "
                          "calibrate on the rig with an illuminator that can change its period (the daemon then "
                          "takes a second set at twice the period), or offline give `--second DIR2`, the same "
                          "reference at another period",
                          cal->black_level, cal->harmonic_gain);
}
