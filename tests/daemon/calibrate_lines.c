/* The calibrator's lines for tests (calibrate_lines.h). */
#include "tests/daemon/calibrate_lines.h"

#include "proc/calibration.h"
#include "proc/calibration_json.h"

static void
measure (DsImage *const *phases, guint n, const DsImage *dark, double period, DsCalibration *out)
{
  g_autoptr (GError) error = NULL;
  g_autoptr (DsCalibrator) cal = ds_calibrator_new (n, phases[0]->width, phases[0]->height, &error);
  g_assert_no_error (error);
  for (guint k = 0; k < n; k++)
    g_assert_true (ds_calibrator_add (cal, k, phases[k], &error));
  g_assert_true (ds_calibrator_set_dark (cal, dark, &error));
  DsCalibrationHints hints;
  ds_calibration_hints_init (&hints);
  if (period > 0) {
    hints.pattern = DS_PATTERN_SINE;
    hints.pattern_forced = TRUE;
    hints.period_px = period;
  }
  g_assert_true (ds_calibrator_finish (cal, &hints, out, &error));
  g_assert_no_error (error);
}

char *
calibrate_lines (DsImage *const *phases, DsImage *const *second, guint n, const DsImage *dark,
                 double second_period_px, double *contrast)
{
  DsCalibration c, c2;
  measure (phases, n, dark, 0, &c);
  measure (second, n, dark, second_period_px, &c2);
  g_autoptr (GError) error = NULL;
  if (c.pattern == DS_PATTERN_SINE)
    g_assert_true (ds_calibration_add_second_period (&c, &c2, 1.0, &error));
  *contrast = c.contrast;
  return ds_calibration_config_lines (&c);
}
