/* The daemon's calibrate command: a kept phase set measured by the calibrator (calibrate_set.h). */
#include <math.h>

#include "daemon/service/calibrate_set.h"
#include "proc/calibration_json.h"
#include "proc/proc_error.h"

JsonNode *
ds_calibrate_result (DsResult *result, const DsCalibrateRequest *request, GError **error)
{
  const DsRawFrames *raw = ds_result_raw_frames (result);
  if (!raw || raw->frames->len == 0) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_EMPTY, "calibrate: the set kept no raw frames");
    return NULL;
  }
  const DsRawFrame *first = raw->frames->pdata[0];
  g_autoptr (DsCalibrator) cal = ds_calibrator_new (raw->n_phases, first->image->width, first->image->height, error);
  if (!cal)
    return NULL;
  for (guint i = 0; i < raw->frames->len; i++) {
    const DsRawFrame *f = raw->frames->pdata[i];
    if (!ds_calibrator_add (cal, f->phase, f->image, error))
      return NULL;
  }
  if (raw->black && !ds_calibrator_set_dark (cal, raw->black, error))
    return NULL;
  DsCalibrationHints hints;
  ds_calibration_hints_init (&hints);
  const DsCaptureSettings *s = ds_result_settings (result);
  hints.pattern = s->pattern;
  hints.period_px = request->period_px > 0 ? request->period_px : 0;
  if (request->pixel_aperture > 0)
    hints.pixel_aperture = request->pixel_aperture;
  /* the level the set's separation applied: the camera's pixel format, or the configuration */
  double sat = ds_result_separation (result)->meta.saturation_level;
  hints.saturation_level = isfinite (sat) && sat > 0 ? sat : 0;
  DsCalibration c;
  if (!ds_calibrator_finish (cal, &hints, &c, error))
    return NULL;
  c.period_measured = !(request->period_px > 0);
  g_autofree char *config = ds_calibration_config_lines (&c);
  g_autoptr (JsonBuilder) b = json_builder_new ();
  json_builder_begin_object (b);
  json_builder_set_member_name (b, "set_id");
  json_builder_add_int_value (b, (gint64) ds_result_set_id (result));
  ds_calibration_add_json_members (b, &c);
  json_builder_set_member_name (b, "config");
  json_builder_add_string_value (b, config);
  json_builder_end_object (b);
  return json_builder_get_root (b);
}
