/* The set runner: one phase set from its settings to a published result or a failure, with
 * every frame of it accounted for. */
#include <math.h>
#include <string.h>

#include "daemon/acquire/acquisition.h"
#include "proc/pixfmt.h"

static gboolean
prepare_phase_set (DsAcquisition *acq, const DsCaptureSettings *s, guint width, guint height,
                   GError **error)
{
  DsSeparationParams p;
  ds_capture_settings_separation_params (s, &p);
  if (acq->set && width == acq->set_width && height == acq->set_height &&
      memcmp (&p, &acq->set_params, sizeof p) == 0) {
    ds_phase_set_reset (acq->set);
    return TRUE;
  }
  g_clear_pointer (&acq->set, ds_phase_set_free);
  acq->set = ds_phase_set_new (&p, width, height, error);
  if (!acq->set)
    return FALSE;
  /* Logged once per change of settings: maxmin or robust on sine stripes reads Ld low. */
  DsSamplingCheck check;
  if (ds_separation_check_sampling (&p, &check, NULL) && check.warning[0])
    g_warning ("%s", check.warning);
  acq->set_params = p;
  acq->set_width = width;
  acq->set_height = height;
  return TRUE;
}

/* The frames of one set, from configuring the camera to the finalized separation. Returns NULL
 * with error set; the caller accounts for the frames in `c` either way. Early returns only: no
 * jump may cross an auto-cleanup declaration (-Wjump-misses-init). */
static DsSeparation *
acquire_set (DsAcquisition *acq, const DsCaptureSettings *s, guint64 tag, DsSetOrigin origin, DsFrameCounters *c,
             gint64 *last_frame_us, GError **error)
{
  if (acq->phase_check_period != s->period_px || !acq->phase_check.offset_known) {
    if (acq->phase_check_period != s->period_px)
      ds_phase_check_init (&acq->phase_check, s->period_px, s->phase_tolerance_deg);
    acq->phase_check_period = s->period_px;
  }
  acq->phase_check.tolerance_cycles = s->phase_tolerance_deg / 360.0;
  ds_phase_check_set_pattern (&acq->phase_check, s->pattern == DS_PATTERN_SQUARE, s->duty);
  ds_phase_check_begin_set (&acq->phase_check);

  if (!ds_seq_ensure_camera (acq, s, error)) {
    g_prefix_error (error, "camera: ");
    ds_seq_fatal_device_error (acq, *error);
    return NULL;
  }
  /* A set that starts from a frame triggered ahead has the previous set's pattern, the same
   * (ds_seq_carry_fits): loading it again could change the light while that frame exposes. */
  if (acq->carry.stage == DS_CARRY_NONE && !ds_seq_apply_pattern (acq, s, error)) {
    g_prefix_error (error, "illuminator: ");
    ds_seq_fatal_device_error (acq, *error);
    return NULL;
  }
  g_autoptr (DsImage) dark = NULL;
  const DsImage *use_dark = NULL;
  if (!ds_seq_dark_for (acq, s, c, &dark, &use_dark, error))
    return NULL;
  DsCameraInfo info;
  guint w, h;
  ds_seq_frame_size (acq, &info, &w, &h);
  if (s->single_frame)
    return ds_seq_acquire_single_frame (acq, s, use_dark, w, h, c, last_frame_us, error);
  if (!prepare_phase_set (acq, s, w, h, error))
    return NULL;
  /* The phase set is reused between sets: forget an earlier dark frame when this set has
   * none (or one for other settings). */
  if (!ds_phase_set_set_dark (acq->set, use_dark, error))
    return NULL;
  /* The result's planes now, before the first frame: reused ones, or new ones touched here,
   * so that no page fault falls between the last frame and the result. */
  DsSeparation *planes = ds_plane_pool_take (acq->planes, w, h, error);
  if (!planes)
    return NULL;
  g_clear_pointer (&acq->raw, ds_raw_frames_free);
  acq->raw_incomplete = FALSE;
  if (s->save_phases) {
    acq->raw = ds_raw_frames_new (s->phases);
    /* Every frame a single capture will fold, now, as the result's planes above (in the type
     * the camera's format unpacks to; a frame of another type or size is copied into new
     * memory). Not in continuous mode: there the next set's first frame is already on its way
     * (carry.c), and writing a set's worth of fresh memory here would hold up its
     * grab; each copy is made on the fold thread instead, overlapped with the next frame. */
    DsPixelFormat fmt = DS_PIXFMT_MONO16;
    ds_pixfmt_from_name (acq->dev->camera_settings.pixel_format, &fmt); /* none configured: the camera's, most likely 16 bits */
    DsSampleType type = ds_pixfmt_sample_type (fmt);
    if (origin == DS_SET_FOR_REQUEST && !ds_raw_frames_reserve (acq->raw, s->phases * s->averages, type, w, h, NULL))
      acq->raw_incomplete = TRUE;
    GArray *ids = dark ? acq->dark_ids : acq->stored_dark_ids;
    if (use_dark && !ds_raw_frames_set_black (acq->raw, use_dark, (const guint64 *) ids->data, ids->len, NULL))
      acq->raw_incomplete = TRUE;
  }
  gboolean finalized = FALSE;
  if (!ds_seq_acquire_phases (acq, s, tag, origin, c, planes, &finalized, error)) {
    ds_plane_pool_give (acq->planes, planes);
    if (acq->phase_check.provisional)
      ds_phase_check_abandon (&acq->phase_check);
    return NULL;
  }
  /* A set whose frames could only be checked together (the first one, or the scene changed)
   * is checked now, before it becomes a result. */
  g_autofree char *why = NULL;
  if (acq->phase_check.provisional && !ds_phase_check_confirm (&acq->phase_check, &why)) {
    ds_plane_pool_give (acq->planes, planes);
    g_set_error (error, DS_SEQUENCER_ERROR, DS_SEQUENCER_ERROR_FRAME_REJECTED, "%s", why);
    return NULL;
  }
  *last_frame_us = acq->last_frame_us;
  /* The job of the set's last frame finalized it already (pipeline.c). */
  return finalized ? planes : ds_phase_set_finalize_reusing (acq->set, planes, error);
}

void
ds_seq_run_set (DsAcquisition *acq, const DsCaptureSettings *requested, guint64 tag, DsSetOrigin origin)
{
  /* The stripe geometry is the illuminator's (configured for real devices, the scene's for
   * the simulated lab), never a per-capture choice: the set records what was projected. */
  DsCaptureSettings settings = *requested;
  const DsCaptureSettings *s = &settings;
  settings.pattern = acq->dev->pattern.kind == DS_STRIPES_SINE ? DS_PATTERN_SINE : DS_PATTERN_SQUARE;
  settings.period_px = requested->period_override_px > 0 ? requested->period_override_px
                                                        : acq->dev->pattern.period_px;
  settings.duty = acq->dev->pattern.duty;
  settings.black_level = acq->dev->pattern.black_level;
  if (acq->dev->pattern_known)
    ds_capture_settings_take_knowledge (&settings, &acq->dev->known);
  DsFrameCounters c = { 0 };
  g_autoptr (GError) error = NULL;
  if (!ds_seq_carry_fits (acq, origin, s))
    ds_seq_carry_discard (acq);
  if (settings.target_error > 0 || settings.time_budget_ms > 0) {
    if (!ds_seq_ensure_camera (acq, s, &error) || !ds_seq_choose_operating_point (acq, &settings, &c, &error)) {
      /* Pilot frames not yet counted as `preview` (the pilot stopped part way) go down with
       * the capture, as a failing set's frames do. */
      ds_seq_account_unfinished (acq->shared, &c, error);
      ds_seq_emit (acq->shared, DS_SEQUENCER_EVENT_FAILED, tag, NULL, g_steal_pointer (&error), NULL);
      return;
    }
  }
  gint64 started = g_get_monotonic_time ();
  gint64 acquired = 0;
  g_autoptr (DsSeparation) sep = acquire_set (acq, s, tag, origin, &c, &acquired, &error);
  if (!sep) {
    /* Whatever was not dropped already (folded frames, dark frames) goes down with the set; a
     * cancelled set (ds_seq_check_quit) ends here too: no result, so nothing is published or
     * spooled, and its planes went back to the pool in acquire_set. */
    ds_seq_account_unfinished (acq->shared, &c, error);
    ds_seq_refresh_device_status (acq);
    ds_seq_emit (acq->shared, DS_SEQUENCER_EVENT_FAILED, tag, NULL, g_steal_pointer (&error), NULL);
    return;
  }
  ds_seq_stage_add (acq->shared, DS_STAGE_FINALIZE, acquired);
  if (acq->phase_check.offset_known) {
    g_mutex_lock (&acq->shared->lock);
    acq->shared->status.phase_offset_cycles = acq->phase_check.offset_cycles;
    g_mutex_unlock (&acq->shared->lock);
  }
  gint64 finished = g_get_monotonic_time ();
  ds_seq_stage_add (acq->shared, DS_STAGE_SET, started);
  /* Every frame not dropped went into the result: folded into a phase, or averaged into its
   * dark frame. */
  ds_frame_counters_fold_rest (&c);
  ds_seq_account (acq->shared, &c, TRUE);
  /* The result says where on the sensor its frames came from (a `set` may have moved it). */
  DsCameraInfo info = { 0 };
  acq->dev->camera->ops->get_info (acq->dev->camera->backend, &info);
  guint region[4];
  ds_seq_camera_region (acq, &info, region);
  settings.roi_x = region[0];
  settings.roi_y = region[1];
  settings.roi_width = region[2];
  settings.roi_height = region[3];
  DsResult *result = ds_result_new (++acq->next_set_id, g_steal_pointer (&sep), acq->planes, s, &c, started,
                                    acquired, finished);
  ds_result_set_last_frame_times (result, &acq->last_frame_times);
  if (acq->raw && !acq->raw_incomplete) {
    ds_raw_frames_trim (acq->raw);
    ds_result_set_raw_frames (result, g_steal_pointer (&acq->raw));
  }
  g_clear_pointer (&acq->raw, ds_raw_frames_free);
  ds_seq_refresh_device_status (acq);
  ds_seq_emit (acq->shared, DS_SEQUENCER_EVENT_RESULT, tag, result, NULL, NULL);
}
