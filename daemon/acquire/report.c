/* Reporting from the acquisition thread: events posted to the main context in order, and the
 * status the main thread reads under the shared lock (sequencer_shared.h). Each function takes
 * the lock briefly or posts to the main context; none blocks on a device, none fails. */
#include <math.h>

#include "daemon/acquire/acquisition.h"
#include "daemon/protocol/protocol.h"

typedef struct {
  DsSequencerShared *shared;
  DsSequencerEventKind kind;
  guint64 tag;
  DsResult *result;
  GError *error;
  guint phase, n_phases;
  double dark_mean_dn;
  char *message;
} PendingEvent;

static void
pending_event_free (gpointer data)
{
  PendingEvent *p = data;
  if (p->result)
    ds_result_unref (p->result);
  g_clear_error (&p->error);
  g_free (p->message);
  g_free (p);
}

static gboolean
pending_event_dispatch (gpointer data)
{
  PendingEvent *p = data;
  if (!g_atomic_int_get (&p->shared->alive))
    return G_SOURCE_REMOVE;
  DsSequencerEvent ev = { .kind = p->kind, .tag = p->tag, .result = p->result, .error = p->error,
                          .phase = p->phase, .n_phases = p->n_phases,
                          .dark_mean_dn = p->dark_mean_dn, .message = p->message };
  p->shared->on_event (&ev, p->shared->user_data);
  return G_SOURCE_REMOVE;
}

/* Every event goes through one priority, so they are dispatched in the order they were
 * posted (a progress event never overtakes the result that follows it). */
static void
post (DsSequencerShared *shared, PendingEvent *p)
{
  GSource *src = g_idle_source_new ();
  g_source_set_priority (src, G_PRIORITY_DEFAULT);
  g_source_set_callback (src, pending_event_dispatch, p, pending_event_free);
  g_source_attach (src, shared->context);
  g_source_unref (src);
}

/* Takes ownership of result and error. */
void
ds_seq_emit (DsSequencerShared *shared, DsSequencerEventKind kind, guint64 tag, DsResult *result, GError *error,
      const char *message)
{
  PendingEvent *p = g_new0 (PendingEvent, 1);
  p->shared = shared;
  p->kind = kind;
  p->tag = tag;
  p->result = result;
  p->error = error;
  p->message = g_strdup (message);
  post (shared, p);
}

void
ds_seq_emit_progress (DsSequencerShared *shared, guint64 tag, guint phase, guint n)
{
  /* Progress answers a capture request; continuous sets (tag 0) have no one to answer, and
   * each event would wake the main thread, which at a megapixel frame rate takes a core the
   * camera's transfer needs. */
  if (tag == 0)
    return;
  PendingEvent *p = g_new0 (PendingEvent, 1);
  p->shared = shared;
  p->kind = DS_SEQUENCER_EVENT_PROGRESS;
  p->tag = tag;
  p->phase = phase;
  p->n_phases = n;
  post (shared, p);
}

void
ds_seq_emit_dark (DsSequencerShared *shared, guint64 tag, double dark_mean_dn)
{
  PendingEvent *p = g_new0 (PendingEvent, 1);
  p->shared = shared;
  p->kind = DS_SEQUENCER_EVENT_DARK;
  p->tag = tag;
  p->dark_mean_dn = dark_mean_dn;
  post (shared, p);
}

void
ds_seq_set_state (DsSequencerShared *shared, DsSequencerState state)
{
  g_mutex_lock (&shared->lock);
  shared->status.state = state;
  shared->status.heartbeat_us = g_get_monotonic_time ();
  shared->status.blocking_until_us = 0;
  g_mutex_unlock (&shared->lock);
}

void
ds_seq_heartbeat (DsSequencerShared *shared)
{
  g_mutex_lock (&shared->lock);
  shared->status.heartbeat_us = g_get_monotonic_time ();
  shared->status.blocking_until_us = 0;
  g_mutex_unlock (&shared->lock);
}

void
ds_seq_blocking (DsSequencerShared *shared, guint bound_ms)
{
  g_mutex_lock (&shared->lock);
  shared->status.heartbeat_us = g_get_monotonic_time ();
  shared->status.blocking_until_us = shared->status.heartbeat_us + (gint64) bound_ms * 1000;
  g_mutex_unlock (&shared->lock);
}

void
ds_seq_stage_add (DsSequencerShared *shared, DsStage stage, gint64 since_us)
{
  double ms = (double) (g_get_monotonic_time () - since_us) / 1000.0;
  g_mutex_lock (&shared->lock);
  shared->status.stages[stage].total_ms += ms;
  shared->status.stages[stage].count++;
  shared->status.heartbeat_us = g_get_monotonic_time ();
  shared->status.blocking_until_us = 0;
  g_mutex_unlock (&shared->lock);
}

void
ds_seq_record_error (DsSequencerShared *shared, const GError *error)
{
  g_mutex_lock (&shared->lock);
  g_strlcpy (shared->status.last_error, error->message, sizeof shared->status.last_error);
  g_mutex_unlock (&shared->lock);
}

void
ds_seq_refresh_device_status (DsAcquisition *acq)
{
  if (!acq->dev)
    return;
  DsCameraStats cs = { 0 };
  DsCameraInfo ci = { 0 };
  DsIlluminatorStatus is = { .applied_phase = -1, .temperature_c = NAN };
  acq->dev->camera->ops->get_stats (acq->dev->camera->backend, &cs);
  acq->dev->camera->ops->get_info (acq->dev->camera->backend, &ci);
  g_autoptr (GError) error = NULL;
  gboolean have_ill = acq->dev->illuminator->ops->get_status (acq->dev->illuminator->backend, &is, &error);
  g_mutex_lock (&acq->shared->lock);
  acq->shared->status.camera_stats = cs;
  acq->shared->status.camera_info = ci;
  if (have_ill)
    acq->shared->status.illuminator = is;
  g_mutex_unlock (&acq->shared->lock);
}

void
ds_seq_account (DsSequencerShared *shared, const DsFrameCounters *c, gboolean ok)
{
  g_mutex_lock (&shared->lock);
  ds_frame_counters_add (&shared->status.frames, c);
  if (ok)
    shared->status.sets_done++;
  else
    shared->status.sets_failed++;
  g_mutex_unlock (&shared->lock);
}

/* Under one lock: a status that counts the set failed carries its error as last_error, which
 * is how the live view tells a failed capture's status from another failure's. */
void
ds_seq_account_failed (DsSequencerShared *shared, const DsFrameCounters *c, const GError *error)
{
  g_mutex_lock (&shared->lock);
  ds_frame_counters_add (&shared->status.frames, c);
  shared->status.sets_failed++;
  g_strlcpy (shared->status.last_error, error->message, sizeof shared->status.last_error);
  g_mutex_unlock (&shared->lock);
}

gboolean
ds_seq_error_is_cancel (const GError *error)
{
  return g_error_matches (error, DS_PROTOCOL_ERROR, DS_PROTOCOL_ERROR_CANCELLED);
}

void
ds_seq_account_unfinished (DsSequencerShared *shared, DsFrameCounters *c, const GError *error)
{
  ds_frame_counters_abort_rest (c);
  if (!ds_seq_error_is_cancel (error)) {
    ds_seq_account_failed (shared, c, error);
    return;
  }
  g_mutex_lock (&shared->lock);
  ds_frame_counters_add (&shared->status.frames, c);
  shared->status.sets_cancelled++;
  g_mutex_unlock (&shared->lock);
}

void
ds_seq_account_frames (DsSequencerShared *shared, const DsFrameCounters *c)
{
  g_mutex_lock (&shared->lock);
  ds_frame_counters_add (&shared->status.frames, c);
  g_mutex_unlock (&shared->lock);
}

DsSequencerFrameFunc
ds_seq_frame_hook (DsSequencerShared *shared, gpointer *user_data)
{
  g_mutex_lock (&shared->lock);
  DsSequencerFrameFunc hook = shared->frame_hook;
  *user_data = shared->frame_hook_data;
  g_mutex_unlock (&shared->lock);
  return hook;
}
