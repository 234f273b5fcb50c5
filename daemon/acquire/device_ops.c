/* Device operations as the sequencer uses them: each counts what happened (frames acquired,
 * timeouts, device errors, stale drops), and one policy says which errors end a set. */
#include <string.h>

#include "daemon/protocol/protocol.h"
#include "daemon/acquire/acquisition.h"

static gboolean
is_code (const GError *error, int code)
{
  return g_error_matches (error, DS_DEVICE_ERROR, code);
}

gboolean
ds_seq_ensure_camera (DsAcquisition *acq, const DsCaptureSettings *s, GError **error)
{
  DsCamera *cam = acq->dev->camera;
  if (acq->camera_configured && acq->camera_exposure_us == s->exposure_us &&
      acq->camera_gain_db == s->gain_db) {
    if (!acq->camera_started) {
      if (!cam->ops->start (cam->backend, error))
        return FALSE;
      acq->camera_started = TRUE;
    }
    return TRUE;
  }
  /* Configuring is a few dozen control round trips; any one of them failing ends it. */
  ds_seq_blocking (acq->shared, 2 * DS_SEQ_CONTROL_BOUND_MS);
  if (acq->camera_started) {
    cam->ops->stop (cam->backend);
    acq->camera_started = FALSE;
  }
  DsCameraSettings cs;
  ds_devices_camera_settings (acq->dev, s->exposure_us, s->gain_db, &cs);
  if (!cam->ops->configure (cam->backend, &cs, error)) {
    acq->camera_configured = FALSE;
    return FALSE;
  }
  acq->camera_configured = TRUE;
  acq->camera_exposure_us = s->exposure_us;
  acq->camera_gain_db = s->gain_db;
  if (!cam->ops->start (cam->backend, error))
    return FALSE;
  acq->camera_started = TRUE;
  return TRUE;
}

gboolean
ds_seq_apply_pattern (DsAcquisition *acq, const DsCaptureSettings *s, GError **error)
{
  DsStripePattern p = acq->dev->pattern;
  p.kind = s->pattern == DS_PATTERN_SINE ? DS_STRIPES_SINE : DS_STRIPES_SQUARE;
  p.period_px = s->period_px;
  p.duty = s->duty;
  p.black_level = s->black_level;
  p.n_phases = s->phases;
  ds_seq_blocking (acq->shared, DS_SEQ_CONTROL_BOUND_MS);
  return acq->dev->illuminator->ops->set_pattern (acq->dev->illuminator->backend, &p, error);
}

gboolean
ds_seq_set_phase (DsAcquisition *acq, guint k, GError **error)
{
  ds_seq_blocking (acq->shared, acq->dev->settle_timeout_ms + DS_SEQ_CONTROL_BOUND_MS);
  return acq->dev->illuminator->ops->set_phase (acq->dev->illuminator->backend, k,
                                                acq->dev->settle_timeout_ms, error);
}

gboolean
ds_seq_trigger (DsAcquisition *acq, DsFrameCounters *c, GError **error)
{
  gint64 t = g_get_monotonic_time ();
  ds_seq_blocking (acq->shared, DS_SEQ_CONTROL_BOUND_MS);
  if (!acq->dev->trigger->ops->fire (acq->dev->trigger->backend, error)) {
    c->device_errors++;
    return FALSE;
  }
  ds_seq_stage_add (acq->shared, DS_STAGE_TRIGGER, t);
  return TRUE;
}

DsFrame *
ds_seq_grab (DsAcquisition *acq, DsFrameCounters *c, GError **error)
{
  return ds_seq_grab_within (acq, c, acq->dev->grab_timeout_ms, error);
}

DsFrame *
ds_seq_grab_within (DsAcquisition *acq, DsFrameCounters *c, guint timeout_ms, GError **error)
{
  gint64 t = g_get_monotonic_time ();
  GError *local = NULL;
  /* The grab's own deadline, then one control round trip asking a silent camera whether it
   * is still there. */
  ds_seq_blocking (acq->shared, timeout_ms + DS_SEQ_CONTROL_BOUND_MS);
  DsFrame *frame = acq->dev->camera->ops->grab (acq->dev->camera->backend, timeout_ms, &local);
  ds_seq_stage_add (acq->shared, DS_STAGE_GRAB, t);
  if (frame) {
    c->acquired++;
    return frame;
  }
  if (is_code (local, DS_DEVICE_ERROR_TIMEOUT))
    c->timeouts++;
  else if (is_code (local, DS_DEVICE_ERROR_INCOMPLETE)) {
    c->acquired++;
    ds_frame_counters_drop (c, DS_DROP_INCOMPLETE, 1);
  } else
    c->device_errors++;
  g_propagate_error (error, local);
  return NULL;
}

/* One frame: trigger and grab. Counts what happened. Returns NULL with error set. */
DsFrame *
ds_seq_trigger_and_grab (DsAcquisition *acq, DsFrameCounters *c, GError **error)
{
  if (!ds_seq_trigger (acq, c, error))
    return NULL;
  return ds_seq_grab (acq, c, error);
}

guint64
ds_seq_frames_begun (DsAcquisition *acq)
{
  DsCamera *cam = acq->dev->camera;
  if (!acq->dev->sends_after_exposure || !cam->ops->frames_begun)
    return 0;
  return cam->ops->frames_begun (cam->backend, 0, 0);
}

gboolean
ds_seq_wait_exposure_over (DsAcquisition *acq, guint64 before)
{
  DsCamera *cam = acq->dev->camera;
  if (!acq->dev->sends_after_exposure || !cam->ops->frames_begun)
    return FALSE;
  /* The frame's own deadline, as its grab has. */
  gint64 t = g_get_monotonic_time ();
  ds_seq_blocking (acq->shared, acq->dev->grab_timeout_ms);
  gboolean begun = cam->ops->frames_begun (cam->backend, before, acq->dev->grab_timeout_ms) > before;
  ds_seq_stage_add (acq->shared, DS_STAGE_EXPOSE, t);
  return begun;
}

void
ds_seq_flush_stale (DsAcquisition *acq, DsFrameCounters *c)
{
  guint n = acq->dev->camera->ops->flush (acq->dev->camera->backend);
  c->acquired += n;
  ds_frame_counters_drop (c, DS_DROP_STALE, n);
}

gboolean
ds_seq_check_quit (DsAcquisition *acq, GError **error)
{
  if (g_atomic_int_get (&acq->shared->quit)) {
    g_set_error (error, DS_PROTOCOL_ERROR, DS_PROTOCOL_ERROR_CANCELLED, "the daemon is stopping");
    return FALSE;
  }
  /* A cancel queued after this work was: the work's stamp is older than the count. */
  if (g_atomic_int_get (&acq->shared->cancel_gen) != acq->work_gen) {
    g_set_error (error, DS_PROTOCOL_ERROR, DS_PROTOCOL_ERROR_CANCELLED, "cancelled by a cancel request");
    return FALSE;
  }
  return TRUE;
}

gboolean
ds_seq_fatal_device_error (DsAcquisition *acq, const GError *e)
{
  /* The one policy (drivers/core/device_error.h); an error that is not a device's (a rejected
   * frame) is the caller's to retry. */
  if (!e || e->domain != DS_DEVICE_ERROR)
    return FALSE;
  switch (ds_device_error_policy (e)) {
  case DS_DEVICE_POLICY_RECONNECT:
    acq->need_reconnect = TRUE;
    /* In status at once, before the failure reaches anyone: not ready until reconnected. */
    ds_seq_set_state (acq->shared, DS_SEQUENCER_STATE_RECONNECTING);
    return TRUE;
  case DS_DEVICE_POLICY_FAIL:
    return TRUE;
  case DS_DEVICE_POLICY_RETRY:
    break;
  }
  return FALSE;
}

gboolean
ds_seq_apply_defaults (DsAcquisition *acq)
{
  /* What `set` changed holds over new defaults and devices opened again. */
  ds_seq_camera_live_overlay (acq);
  ds_seq_camera_live_report (acq);
  DsCaptureSettings s;
  g_mutex_lock (&acq->shared->lock);
  s = acq->shared->defaults;
  g_mutex_unlock (&acq->shared->lock);
  /* The stripe geometry is the illuminator's, as a set uses it (set_runner.c). */
  s.pattern = acq->dev->pattern.kind == DS_STRIPES_SINE ? DS_PATTERN_SINE : DS_PATTERN_SQUARE;
  s.period_px = acq->dev->pattern.period_px;
  s.duty = acq->dev->pattern.duty;
  s.black_level = acq->dev->pattern.black_level;
  if (acq->dev->pattern_known)
    ds_capture_settings_take_knowledge (&s, &acq->dev->known);
  g_autoptr (GError) error = NULL;
  gboolean ok = ds_seq_ensure_camera (acq, &s, &error);
  if (!ok)
    g_prefix_error (&error, "camera: ");
  else if (!(ok = ds_seq_apply_pattern (acq, &s, &error)))
    g_prefix_error (&error, "illuminator: ");
  if (!ok)
    ds_seq_fatal_device_error (acq, error);
  g_mutex_lock (&acq->shared->lock);
  /* Reported when it changes (settings_ok starts TRUE: a normal start says nothing). */
  gboolean changed = acq->shared->status.settings_ok != ok ||
                     (!ok && strcmp (acq->shared->status.settings_error, error->message) != 0);
  acq->shared->status.settings_ok = ok;
  g_strlcpy (acq->shared->status.settings_error, ok ? "" : error->message, sizeof acq->shared->status.settings_error);
  g_mutex_unlock (&acq->shared->lock);
  if (changed) {
    g_autofree char *msg = ok ? g_strdup ("devices took the configured settings")
                              : g_strdup_printf ("devices refuse the configured settings: %s", error->message);
    ds_seq_emit (acq->shared, DS_SEQUENCER_EVENT_DEVICE, 0, NULL, NULL, msg);
  }
  return ok;
}

/* Reopens a lost camera (or illuminator) with capped exponential backoff, until it works or
 * the daemon stops. Commands wait in the queue meanwhile. */
void
ds_seq_reconnect (DsAcquisition *acq)
{
  ds_seq_set_state (acq->shared, DS_SEQUENCER_STATE_RECONNECTING);
  ds_seq_emit (acq->shared, DS_SEQUENCER_EVENT_DEVICE, 0, NULL, NULL, "device disconnected: reconnecting");
  guint delay_ms = 100;
  while (!g_atomic_int_get (&acq->shared->quit)) {
    g_autoptr (GError) e1 = NULL;
    g_autoptr (GError) e2 = NULL;
    ds_seq_blocking (acq->shared, 4 * DS_SEQ_CONTROL_BOUND_MS); /* opening both again */
    gboolean cam_ok = acq->dev->camera->ops->reconnect (acq->dev->camera->backend, &e1);
    gboolean ill_ok = cam_ok && acq->dev->illuminator->ops->reconnect (acq->dev->illuminator->backend, &e2);
    ds_seq_heartbeat (acq->shared);
    if (cam_ok && ill_ok) {
      acq->camera_started = FALSE;
      acq->camera_configured = FALSE;
      acq->need_reconnect = FALSE;
      g_mutex_lock (&acq->shared->lock);
      acq->shared->status.camera_stats.reconnects++;
      g_mutex_unlock (&acq->shared->lock);
      ds_seq_emit (acq->shared, DS_SEQUENCER_EVENT_DEVICE, 0, NULL, NULL, "devices reconnected");
      /* A camera that came back (or another one at that address) must take the settings
       * again; a refusal shows in status before the next set. */
      ds_seq_apply_defaults (acq);
      return;
    }
    ds_seq_record_error (acq->shared, e1 ? e1 : e2);
    /* Sleep in slices so that quitting stays prompt. */
    for (guint slept = 0; slept < delay_ms && !g_atomic_int_get (&acq->shared->quit); slept += 50)
      g_usleep (50 * 1000);
    delay_ms = MIN (delay_ms * 2, 2000);
  }
}

void
ds_seq_frame_size (DsAcquisition *acq, DsCameraInfo *info, guint *width, guint *height)
{
  DsCameraSettings *cs = &acq->dev->camera_settings;
  *info = (DsCameraInfo){ 0 };
  acq->dev->camera->ops->get_info (acq->dev->camera->backend, info);
  *width = cs->roi_width ? cs->roi_width : info->sensor_width;
  *height = cs->roi_width ? cs->roi_height : info->sensor_height;
}
