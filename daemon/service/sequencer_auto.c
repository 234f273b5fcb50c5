/* The automatic operating point of a capture with a target error or time budget. */
#include <math.h>

#include "daemon/protocol/protocol.h"
#include "daemon/service/sequencer_private.h"
#include "proc/image_stats.h"

/* Automatic operating point: one dark and one phase-0 preview frame at the requested base
 * exposure give the scene's signal and direct fraction; the model then picks estimator, N, M
 * and exposure (docs/accuracy.md). The two frames are counted as `preview` drops. */
gboolean
ds_seq_choose_operating_point (DsSequencer *seq, DsCaptureSettings *s, DsFrameCounters *c, GError **error)
{
  if (!seq->model) {
    g_set_error (error, DS_PROTOCOL_ERROR, DS_PROTOCOL_ERROR_FAILED,
                 "automatic operating point: no operating model loaded");
    return FALSE;
  }
  DsCaptureSettings one = *s;
  one.averages = 1;
  guint64 before = c->acquired, dropped_before = c->dropped;
  g_autoptr (DsImage) dark = ds_seq_acquire_dark (seq, &one, c, error);
  if (!dark)
    return FALSE;
  if (!ds_seq_apply_pattern (seq, s, error) || !ds_seq_set_phase (seq, 0, error)) {
    c->device_errors++;
    g_prefix_error (error, "preview: illuminator: ");
    ds_seq_fatal_device_error (seq, *error);
    return FALSE;
  }
  ds_seq_flush_stale (seq, c);
  g_autoptr (DsFrame) preview = ds_seq_trigger_and_grab (seq, c, error);
  if (!preview) {
    g_prefix_error (error, "preview: ");
    ds_seq_fatal_device_error (seq, *error);
    return FALSE;
  }
  ds_frame_counters_drop (c, DS_DROP_PREVIEW, (c->acquired - before) - (c->dropped - dropped_before));
  double a = s->duty, b = s->black_level;
  gboolean sine = s->pattern == DS_PATTERN_SINE;
  double m = sine ? b + (1 - b) / 2 : a + b * (1 - a);
  double h = sine ? (1 - b) / 2 : (1 - b) * (2 / G_PI) * sin (G_PI * a);
  double dark_dn = ds_image_mean (dark);
  DsSceneStats st;
  if (!ds_scene_stats_from_frame (preview->image, dark_dn, s->period_px, m, h, s->exposure_us, &st, error)) {
    g_prefix_error (error, "preview: ");
    return FALSE;
  }
  /* The largest exposure that keeps the brightest pixels below 90 % of full scale. */
  double full = preview->image->type == DS_SAMPLE_F32 ? INFINITY : (double) ((1u << preview->image->bit_depth) - 1);
  double high = ds_image_percentile (preview->image, 99.9) - dark_dn;
  double max_exposure = high > 0 && isfinite (full) ? s->exposure_us * (0.9 * full - dark_dn) / high : 4 * s->exposure_us;
  max_exposure = CLAMP (max_exposure, s->exposure_us * 0.5, s->exposure_us * 4);
  DsCameraInfo info = { 0 };
  seq->dev->camera->ops->get_info (seq->dev->camera->backend, &info);
  guint w = seq->dev->camera_settings.roi_width ? seq->dev->camera_settings.roi_width : info.sensor_width;
  guint hh = seq->dev->camera_settings.roi_width ? seq->dev->camera_settings.roi_height : info.sensor_height;
  DsOperatingPoint op;
  if (!ds_operating_point_choose (seq->model, &st, &seq->timing, w, hh, max_exposure, s->target_error,
                                  s->time_budget_ms, &op, error))
    return FALSE;
  s->estimator = op.estimator;
  s->phases = op.phases;
  s->averages = op.averages;
  s->exposure_us = op.exposure_us;
  s->automatic = TRUE;
  s->predicted_error = op.predicted_error;
  s->predicted_time_ms = op.predicted_time_ms;
  s->preview_signal_dn = st.signal_dn;
  s->preview_direct_fraction = st.direct_fraction;
  s->phase_tolerance_deg = MIN (s->phase_tolerance_deg, 90.0 / op.phases);
  return TRUE;
}
