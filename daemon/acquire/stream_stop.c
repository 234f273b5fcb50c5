/* Continuous mode that cannot work stops by itself: sets that keep failing (a controller lighting
 * the wrong phase, a camera refusing a setting) would otherwise run, fail and be retried for
 * ever, with the daemon still saying `continuous`. After [acquisition] max-failed-sets failures
 * in a row the stream ends, and says so with the time and the last cause, so that a person
 * finds out what happened after the fact. */
#include "daemon/acquire/acquisition.h"

gboolean
ds_seq_stream_gives_up (DsAcquisition *acq, guint consecutive_failures)
{
  guint limit = acq->run.settings.max_failed_sets;
  if (limit == 0 || consecutive_failures < limit || !ds_acquisition_streaming (acq))
    return FALSE;
  acq->run.mode = DS_RUN_ON_REQUEST;
  ds_seq_carry_discard (acq);
  g_autoptr (GDateTime) now = g_date_time_new_now_utc ();
  g_autofree char *when = g_date_time_format (now, "%Y-%m-%dT%H:%M:%SZ");
  g_mutex_lock (&acq->shared->lock);
  g_autofree char *cause = g_strdup (acq->shared->status.last_error);
  g_autofree char *why = g_strdup_printf ("continuous acquisition stopped at %s: %u sets in a row failed "
                                          "([acquisition] max-failed-sets = %u); the last: %s",
                                          when, consecutive_failures, limit, cause);
  g_strlcpy (acq->shared->status.last_error, why, sizeof acq->shared->status.last_error);
  acq->shared->status.continuous = FALSE;
  g_mutex_unlock (&acq->shared->lock);
  ds_seq_set_state (acq->shared, acq->need_reconnect ? DS_SEQUENCER_STATE_RECONNECTING : DS_SEQUENCER_STATE_IDLE);
  ds_seq_emit (acq->shared, DS_SEQUENCER_EVENT_STREAM_STOPPED, 0, NULL, NULL, why);
  return TRUE;
}
