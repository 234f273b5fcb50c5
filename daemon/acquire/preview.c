/* Preview mode: free-running frames for aligning and focusing (sequencer.h,
 * ds_sequencer_preview). Each frame is triggered as soon as the previous one was grabbed, before
 * that one goes to the hooks, so the rate is the camera's (exposure plus transfer); nothing is
 * verified, folded or published, and a queued command is noticed between two frames.
 *
 * The light stays put for the whole preview: only the camera's settings follow the defaults
 * frame by frame, so that a live setting shows at the next frame. */
#include <string.h>

#include "daemon/protocol/protocol.h"
#include "daemon/acquire/acquisition.h"

/* After this many device failures in a row (timeouts, a lost frame) preview ends: a camera that
 * delivers nothing would otherwise spin unseen. */
#define PREVIEW_MAX_FAILURES 5

const char *
ds_preview_light_name (DsPreviewLight light)
{
  static const char *const names[DS_PREVIEW_LIGHT_N] = { "all", "off", "phase" };
  return (guint) light < DS_PREVIEW_LIGHT_N ? names[light] : "unknown";
}

/* The defaults, with the stripe geometry the illuminator projects (as a set takes it). */
static void
preview_settings (DsAcquisition *acq, DsCaptureSettings *s)
{
  g_mutex_lock (&acq->shared->lock);
  *s = acq->shared->defaults;
  g_mutex_unlock (&acq->shared->lock);
  s->pattern = acq->dev->pattern.kind == DS_STRIPES_SINE ? DS_PATTERN_SINE : DS_PATTERN_SQUARE;
  s->period_px = acq->dev->pattern.period_px;
  s->duty = acq->dev->pattern.duty;
  s->black_level = acq->dev->pattern.black_level;
  if (acq->dev->pattern_known)
    ds_capture_settings_take_knowledge (s, &acq->dev->known);
}

static void
set_preview_status (DsAcquisition *acq, gboolean on, guint n_phases)
{
  g_mutex_lock (&acq->shared->lock);
  DsPreviewStatus *p = &acq->shared->status.preview;
  if (on && !p->on) {
    p->frames = 0;
    p->fps = 0;
  }
  p->on = on;
  p->light = acq->run.preview_light;
  p->phase = acq->run.preview_phase;
  p->n_phases = n_phases;
  g_mutex_unlock (&acq->shared->lock);
}

/* Camera started with s, the pattern loaded and the light applied, stale frames flushed.
 * FALSE with error (prefixed with the device) when a device refuses. */
static gboolean
light_up (DsAcquisition *acq, const DsCaptureSettings *s, DsFrameCounters *c, GError **error)
{
  if (!ds_seq_ensure_camera (acq, s, error)) {
    g_prefix_error (error, "camera: ");
    return FALSE;
  }
  DsIlluminator *ill = acq->dev->illuminator;
  gboolean ok;
  switch (acq->run.preview_light) {
  case DS_PREVIEW_LIGHT_OFF:
    ds_seq_blocking (acq->shared, acq->dev->settle_timeout_ms + DS_SEQ_CONTROL_BOUND_MS);
    ok = ill->ops->off (ill->backend, acq->dev->settle_timeout_ms, error);
    break;
  case DS_PREVIEW_LIGHT_ALL:
    ok = ds_seq_apply_pattern (acq, s, error);
    ds_seq_blocking (acq->shared, acq->dev->settle_timeout_ms + DS_SEQ_CONTROL_BOUND_MS);
    ok = ok && ds_illuminator_all_on (ill, acq->dev->settle_timeout_ms, error);
    break;
  case DS_PREVIEW_LIGHT_PHASE:
  default:
    if (acq->run.preview_phase >= s->phases) {
      g_set_error (error, DS_ILLUMINATOR_ERROR, DS_DEVICE_ERROR_INVALID,
                   "phase %u is not one of the %u configured phases", acq->run.preview_phase, s->phases);
      ok = FALSE;
      break;
    }
    ok = ds_seq_apply_pattern (acq, s, error) && ds_seq_set_phase (acq, acq->run.preview_phase, error);
    break;
  }
  ds_seq_heartbeat (acq->shared);
  if (!ok) {
    c->device_errors++;
    g_prefix_error (error, "illuminator: ");
    ds_seq_fatal_device_error (acq, *error);
    return FALSE;
  }
  ds_seq_flush_stale (acq, c);
  return TRUE;
}

void
ds_seq_preview_end (DsAcquisition *acq, const char *why)
{
  if (!ds_acquisition_previewing (acq))
    return;
  acq->run.mode = DS_RUN_ON_REQUEST;
  set_preview_status (acq, FALSE, acq->shared->status.preview.n_phases);
  if (why)
    ds_seq_emit (acq->shared, DS_SEQUENCER_EVENT_DEVICE, 0, NULL, NULL, why);
}

void
ds_seq_preview_command (DsAcquisition *acq, gboolean on, DsPreviewLight light, guint phase, guint64 tag)
{
  if (!on) {
    gboolean was = ds_acquisition_previewing (acq);
    ds_seq_preview_end (acq, NULL);
    /* Dark between uses, as after a capture's dark frame: nothing lit that nobody watches. */
    g_autoptr (GError) off_error = NULL;
    if (was && acq->dev) {
      ds_seq_blocking (acq->shared, acq->dev->settle_timeout_ms + DS_SEQ_CONTROL_BOUND_MS);
      acq->dev->illuminator->ops->off (acq->dev->illuminator->backend, acq->dev->settle_timeout_ms, &off_error);
      ds_seq_heartbeat (acq->shared);
    }
    /* The state before the answer, so that a status read after it shows preview over. */
    if (acq->dev && was)
      ds_seq_set_state (acq->shared, acq->need_reconnect ? DS_SEQUENCER_STATE_RECONNECTING : DS_SEQUENCER_STATE_IDLE);
    ds_seq_emit (acq->shared, DS_SEQUENCER_EVENT_CONTROL, tag, NULL, NULL,
                 was ? "preview stopped" : "preview was not running");
    return;
  }
  if (!acq->dev) {
    ds_seq_emit (acq->shared, DS_SEQUENCER_EVENT_CONTROL, tag, NULL,
                 g_error_new (DS_SEQUENCER_ERROR, DS_SEQUENCER_ERROR_NOT_READY,
                              "preview: the devices are released (another program may hold the camera): "
                              "send acquire first"),
                 NULL);
    return;
  }
  /* A stream running (its start came after the check on the main thread) gives way, as a
   * capture makes preview give way: the newest request wins. */
  acq->run.mode = DS_RUN_PREVIEW;
  acq->run.preview_light = light;
  acq->run.preview_phase = phase;
  DsCaptureSettings s;
  preview_settings (acq, &s);
  DsFrameCounters c = { 0 };
  GError *error = NULL;
  gboolean ok = light_up (acq, &s, &c, &error);
  ds_seq_account_frames (acq->shared, &c);
  if (!ok) {
    acq->run.mode = DS_RUN_ON_REQUEST;
    ds_seq_record_error (acq->shared, error);
    g_prefix_error (&error, "preview: ");
    ds_seq_emit (acq->shared, DS_SEQUENCER_EVENT_CONTROL, tag, NULL, error, NULL);
    return;
  }
  set_preview_status (acq, TRUE, s.phases);
  ds_seq_set_state (acq->shared, DS_SEQUENCER_STATE_PREVIEW);
  g_autofree char *msg = light == DS_PREVIEW_LIGHT_PHASE
                           ? g_strdup_printf ("preview: phase %u of %u lit", phase, s.phases)
                           : g_strdup_printf ("preview: illuminator %s", light == DS_PREVIEW_LIGHT_ALL ? "all on" : "off");
  ds_seq_emit (acq->shared, DS_SEQUENCER_EVENT_CONTROL, tag, NULL, NULL, msg);
}

/* Whether preview should hand the thread back: a command waits, the work was cancelled, or
 * the daemon stops. */
static gboolean
preview_interrupted (DsAcquisition *acq)
{
  return g_atomic_int_get (&acq->shared->quit) || g_async_queue_length (acq->shared->queue) > 0 ||
         g_atomic_int_get (&acq->shared->cancel_gen) != acq->work_gen;
}

/* One frame to the hooks, counted as a preview; the rate measured over about a second. */
static void
hand_on (DsAcquisition *acq, DsFrame *frame, const DsCaptureSettings *s, gint64 *window_start, guint *window_frames)
{
  gpointer data;
  DsSequencerFrameFunc hook = ds_seq_frame_hook (acq->shared, &data);
  guint phase = acq->run.preview_light == DS_PREVIEW_LIGHT_PHASE ? acq->run.preview_phase : 0;
  if (hook)
    hook (frame, phase, s, data);
  g_mutex_lock (&acq->shared->lock);
  DsSequencerPreviewFunc preview = acq->shared->preview_hook;
  gpointer preview_data = acq->shared->preview_hook_data;
  g_mutex_unlock (&acq->shared->lock);
  if (preview)
    preview (frame, acq->run.preview_light, phase, s->phases, preview_data);
  gint64 now = g_get_monotonic_time ();
  (*window_frames)++;
  g_mutex_lock (&acq->shared->lock);
  DsPreviewStatus *p = &acq->shared->status.preview;
  p->frames++;
  if (now - *window_start >= G_USEC_PER_SEC) {
    p->fps = *window_frames * (double) G_USEC_PER_SEC / (double) (now - *window_start);
    *window_start = now;
    *window_frames = 0;
  }
  g_mutex_unlock (&acq->shared->lock);
}

/* The frame triggered ahead when preview stops or the camera is reconfigured: grabbed (within
 * the grab timeout) and counted as a preview frame, so that no buffer of it is left to pass for
 * the next work's frame. */
static void
drop_ahead (DsAcquisition *acq)
{
  DsFrameCounters c = { 0 };
  g_autoptr (GError) error = NULL;
  DsFrame *frame = ds_seq_grab (acq, &c, &error);
  if (frame) {
    ds_frame_counters_drop (&c, DS_DROP_PREVIEW, 1);
    ds_frame_free (frame);
  }
  ds_seq_account_frames (acq->shared, &c);
}

void
ds_seq_run_preview (DsAcquisition *acq)
{
  ds_seq_set_state (acq->shared, DS_SEQUENCER_STATE_PREVIEW);
  DsCaptureSettings s;
  preview_settings (acq, &s);
  DsFrameCounters c = { 0 };
  g_autoptr (GError) error = NULL;
  if (!light_up (acq, &s, &c, &error)) {
    ds_seq_account_frames (acq->shared, &c);
    ds_seq_record_error (acq->shared, error);
    g_autofree char *why = g_strdup_printf ("preview stopped: %s", error->message);
    ds_seq_preview_end (acq, why);
    return;
  }
  ds_seq_account_frames (acq->shared, &c);
  gint64 window_start = g_get_monotonic_time ();
  guint window_frames = 0, failures = 0;
  gboolean stop = FALSE, ahead = FALSE;
  while (!stop && !preview_interrupted (acq)) {
    memset (&c, 0, sizeof c);
    g_clear_error (&error);
    /* Exposure and gain as they are now; the camera is reconfigured only when they changed,
     * after the frame triggered with the old ones. */
    DsCaptureSettings now;
    preview_settings (acq, &now);
    if (now.exposure_us != s.exposure_us || now.gain_db != s.gain_db) {
      if (ahead)
        drop_ahead (acq);
      ahead = FALSE;
      if (!ds_seq_ensure_camera (acq, &now, &error)) {
        g_prefix_error (&error, "camera: ");
        stop = !ds_seq_fatal_device_error (acq, error) || !acq->need_reconnect;
        break;
      }
    }
    s = now;
    gboolean triggered = ahead || ds_seq_trigger (acq, &c, &error);
    ahead = FALSE;
    DsFrame *frame = triggered ? ds_seq_grab (acq, &c, &error) : NULL;
    if (frame) {
      failures = 0;
      /* The next frame is exposed while this one goes to the hooks (a copy for the live view,
       * one for the socket), so the rate is the camera's, not the camera's plus the hooks'. Not
       * when a command waits: this frame is the last. A trigger that fails is tried again,
       * and handled, at the next frame. */
      if (!preview_interrupted (acq)) {
        g_autoptr (GError) trigger_error = NULL;
        ahead = ds_seq_trigger (acq, &c, &trigger_error);
      }
      hand_on (acq, frame, &s, &window_start, &window_frames);
      ds_frame_counters_drop (&c, DS_DROP_PREVIEW, 1);
      ds_frame_free (frame);
    } else if (ds_seq_fatal_device_error (acq, error) || ++failures >= PREVIEW_MAX_FAILURES) {
      /* A lost device is reopened by the thread's loop, and preview goes on after it. */
      stop = !acq->need_reconnect;
      ds_seq_account_frames (acq->shared, &c);
      break;
    } else {
      /* A frame lost in transit: a late buffer of its trigger would pass for the next one. */
      ds_seq_flush_stale (acq, &c);
    }
    ds_seq_account_frames (acq->shared, &c);
    ds_seq_heartbeat (acq->shared);
  }
  if (ahead)
    drop_ahead (acq);
  if (stop) {
    ds_seq_record_error (acq->shared, error);
    g_autofree char *why = g_strdup_printf ("preview stopped: %s", error->message);
    ds_seq_preview_end (acq, why);
  }
}
