/* Reporting from the acquisition thread: events posted to the main context in order, and the
 * status snapshot the main thread reads under the lock. */
#include <math.h>

#include "daemon/acquire/sequencer_private.h"

typedef struct {
  DsSequencer *seq;
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
  if (!g_atomic_int_get (&p->seq->alive))
    return G_SOURCE_REMOVE;
  DsSequencerEvent ev = { .kind = p->kind, .tag = p->tag, .result = p->result, .error = p->error,
                          .phase = p->phase, .n_phases = p->n_phases,
                          .dark_mean_dn = p->dark_mean_dn, .message = p->message };
  p->seq->on_event (&ev, p->seq->user_data);
  return G_SOURCE_REMOVE;
}

/* Every event goes through one priority, so they are dispatched in the order they were
 * posted (a progress event never overtakes the result that follows it). */
static void
post (DsSequencer *seq, PendingEvent *p)
{
  GSource *src = g_idle_source_new ();
  g_source_set_priority (src, G_PRIORITY_DEFAULT);
  g_source_set_callback (src, pending_event_dispatch, p, pending_event_free);
  g_source_attach (src, seq->context);
  g_source_unref (src);
}

/* Takes ownership of result and error. */
void
ds_seq_emit (DsSequencer *seq, DsSequencerEventKind kind, guint64 tag, DsResult *result, GError *error,
      const char *message)
{
  PendingEvent *p = g_new0 (PendingEvent, 1);
  p->seq = seq;
  p->kind = kind;
  p->tag = tag;
  p->result = result;
  p->error = error;
  p->message = g_strdup (message);
  post (seq, p);
}

void
ds_seq_emit_progress (DsSequencer *seq, guint64 tag, guint phase, guint n)
{
  /* Progress answers a capture request; continuous sets (tag 0) have no one to answer, and
   * each event would wake the main thread, which at 1 MP takes a core the camera needs
   * (docs/benchmarks.md, "Daemon rate"). */
  if (tag == 0)
    return;
  PendingEvent *p = g_new0 (PendingEvent, 1);
  p->seq = seq;
  p->kind = DS_SEQUENCER_EVENT_PROGRESS;
  p->tag = tag;
  p->phase = phase;
  p->n_phases = n;
  post (seq, p);
}

void
ds_seq_emit_dark (DsSequencer *seq, guint64 tag, double dark_mean_dn)
{
  PendingEvent *p = g_new0 (PendingEvent, 1);
  p->seq = seq;
  p->kind = DS_SEQUENCER_EVENT_DARK;
  p->tag = tag;
  p->dark_mean_dn = dark_mean_dn;
  post (seq, p);
}

void
ds_seq_set_state (DsSequencer *seq, DsSequencerState state)
{
  g_mutex_lock (&seq->lock);
  seq->status.state = state;
  seq->status.heartbeat_us = g_get_monotonic_time ();
  seq->status.blocking_until_us = 0;
  g_mutex_unlock (&seq->lock);
}

void
ds_seq_heartbeat (DsSequencer *seq)
{
  g_mutex_lock (&seq->lock);
  seq->status.heartbeat_us = g_get_monotonic_time ();
  seq->status.blocking_until_us = 0;
  g_mutex_unlock (&seq->lock);
}

void
ds_seq_blocking (DsSequencer *seq, guint bound_ms)
{
  g_mutex_lock (&seq->lock);
  seq->status.heartbeat_us = g_get_monotonic_time ();
  seq->status.blocking_until_us = seq->status.heartbeat_us + (gint64) bound_ms * 1000;
  g_mutex_unlock (&seq->lock);
}

void
ds_seq_stage_add (DsSequencer *seq, DsStage stage, gint64 since_us)
{
  double ms = (double) (g_get_monotonic_time () - since_us) / 1000.0;
  g_mutex_lock (&seq->lock);
  seq->status.stages[stage].total_ms += ms;
  seq->status.stages[stage].count++;
  seq->status.heartbeat_us = g_get_monotonic_time ();
  seq->status.blocking_until_us = 0;
  g_mutex_unlock (&seq->lock);
}

void
ds_seq_record_error (DsSequencer *seq, const GError *error)
{
  g_mutex_lock (&seq->lock);
  g_strlcpy (seq->status.last_error, error->message, sizeof seq->status.last_error);
  g_mutex_unlock (&seq->lock);
}

void
ds_seq_refresh_device_status (DsSequencer *seq)
{
  if (!seq->dev)
    return;
  DsCameraStats cs = { 0 };
  DsCameraInfo ci = { 0 };
  DsIlluminatorStatus is = { .applied_phase = -1, .temperature_c = NAN };
  seq->dev->camera->ops->get_stats (seq->dev->camera->backend, &cs);
  seq->dev->camera->ops->get_info (seq->dev->camera->backend, &ci);
  g_autoptr (GError) error = NULL;
  gboolean have_ill = seq->dev->illuminator->ops->get_status (seq->dev->illuminator->backend, &is, &error);
  g_mutex_lock (&seq->lock);
  seq->status.camera_stats = cs;
  seq->status.camera_info = ci;
  if (have_ill)
    seq->status.illuminator = is;
  g_mutex_unlock (&seq->lock);
}

void
ds_seq_account (DsSequencer *seq, const DsFrameCounters *c, gboolean ok)
{
  g_mutex_lock (&seq->lock);
  ds_frame_counters_add (&seq->status.frames, c);
  if (ok)
    seq->status.sets_done++;
  else
    seq->status.sets_failed++;
  g_mutex_unlock (&seq->lock);
}

void
ds_seq_account_frames (DsSequencer *seq, const DsFrameCounters *c)
{
  g_mutex_lock (&seq->lock);
  ds_frame_counters_add (&seq->status.frames, c);
  g_mutex_unlock (&seq->lock);
}
