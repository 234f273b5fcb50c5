/* The daemon's calibrate command: a kept phase set measured by the calibrator (calibrate_set.h). */
#include <math.h>

#include "daemon/service/calibrate_set.h"
#include "daemon/service/json_build.h"
#include "proc/calibration_json.h"
#include "proc/proc_error.h"

gboolean
ds_calibrate_measure (DsResult *result, const DsCalibrateRequest *request, double second_period_px,
                      DsCalibration *out, GError **error)
{
  const DsRawFrames *raw = ds_result_raw_frames (result);
  if (!raw || raw->frames->len == 0) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_EMPTY, "calibrate: the set kept no raw frames");
    return FALSE;
  }
  const DsRawFrame *first = raw->frames->pdata[0];
  g_autoptr (DsCalibrator) cal = ds_calibrator_new (raw->n_phases, first->image->width, first->image->height, error);
  if (!cal)
    return FALSE;
  for (guint i = 0; i < raw->frames->len; i++) {
    const DsRawFrame *f = raw->frames->pdata[i];
    if (!ds_calibrator_add (cal, f->phase, f->image, error))
      return FALSE;
  }
  if (raw->black && !ds_calibrator_set_dark (cal, raw->black, error))
    return FALSE;
  DsCalibrationHints hints;
  ds_calibration_hints_init (&hints);
  const DsCaptureSettings *s = ds_result_settings (result);
  hints.pattern = s->pattern;
  /* a sine's black level at one period is the configured one (proc/calibration_sine.h) */
  hints.black_level = s->black_level;
  hints.period_px = request->period_px > 0 ? request->period_px : 0;
  if (second_period_px > 0)
    ds_calibration_hints_second_period (&hints, second_period_px);
  if (request->pixel_aperture > 0)
    hints.pixel_aperture = request->pixel_aperture;
  /* the level the set's separation applied: the camera's pixel format, or the configuration */
  double sat = ds_result_separation (result)->meta.saturation_level;
  hints.saturation_level = isfinite (sat) && sat > 0 ? sat : 0;
  if (!ds_calibrator_finish (cal, &hints, out, error))
    return FALSE;
  out->period_measured = !(request->period_px > 0);
  /* The open field's lit level (daemon/operating/scene_probe_loss.h), per ms at 0 dB gain: only
   * above a dark frame, which removes the sensor's offset and any ambient light. */
  if (raw->black && s->exposure_us > 0 && out->lit_level_dn > 0)
    out->open_field_dn_per_ms = out->lit_level_dn / (s->exposure_us / 1000 * pow (10, s->gain_db / 20));
  return TRUE;
}

JsonNode *
ds_calibrate_reply (guint64 set_id, const DsCalibration *c, guint64 second_set_id, const char *second_period_error)
{
  g_autofree char *config = ds_calibration_config_lines (c);
  g_autoptr (JsonBuilder) b = ds_json_object_begin ();
  ds_json_add_uint (b, "set_id", set_id);
  if (second_set_id)
    ds_json_add_uint (b, "second_set_id", second_set_id);
  if (second_period_error)
    ds_json_add_string (b, "second_period_error", second_period_error);
  ds_calibration_add_json_members (b, c);
  ds_json_add_string (b, "config", config);
  return ds_json_object_end (b);
}
