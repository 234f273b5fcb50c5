/* Continuous mode: the next set's first frame triggered ahead. As soon as a set's last frame
 * arrived (its exposure is over), the illuminator moves to phase 0 (or goes off, when the next
 * set starts with its dark frame) and the trigger goes out; phase 0 is usually lit already,
 * during the last frame's transfer (pipeline.c), and then only the trigger is left;
 * the last frame's verification and fold and the set's finalize then overlap with that
 * frame's exposure and transfer instead of preceding them. The frame belongs to the next set:
 * it is grabbed, counted and verified there like any first frame (or, when the last frame was
 * dropped and its phase must be lit again, grabbed before the illuminator moves and kept).
 * When the next set does not come as expected (a command, stop, new settings, a reconnect),
 * the frame is grabbed and counted as aborted: every frame stays accounted for
 * (docs/design.md, "The pipeline"). */
#include <string.h>

#include "daemon/acquire/acquisition.h"

gboolean
ds_seq_carry_allowed (DsAcquisition *acq, DsSetOrigin origin, const DsCaptureSettings *s)
{
  return origin == DS_SET_FOR_STREAM && ds_acquisition_streaming (acq) &&
         acq->carry.stage == DS_CARRY_NONE && !acq->need_reconnect &&
         g_async_queue_length (acq->shared->queue) <= 0 && !g_atomic_int_get (&acq->shared->quit) &&
         s->target_error <= 0 && s->time_budget_ms <= 0;
}

/* A device failure while taking the next set's first frame. When retrying cannot help (the
 * device is gone, or refuses), that set has failed on its first frame: the failure is kept and
 * reported as the set's when the carry is discarded, as it would have been without the
 * overlap (a camera lost between two continuous sets is reported as lost, not only
 * reconnected). */
static void
carry_device_error (DsAcquisition *acq, GError *e, const char *what)
{
  DsSeqCarry *cy = &acq->carry;
  if (ds_seq_fatal_device_error (acq, e) && !cy->error)
    cy->error = g_error_new (e->domain, e->code, "%s: %s", what, e->message);
}

void
ds_seq_carry_trigger (DsAcquisition *acq, const DsCaptureSettings *s, gint64 lit_since)
{
  DsSeqCarry *cy = &acq->carry;
  memset (cy, 0, sizeof *cy);
  cy->stage = DS_CARRY_COUNTED;
  cy->settings = *s;
  cy->dark = s->dark_frame;
  g_autoptr (GError) e = NULL;
  const char *first = cy->dark ? "dark frame" : "phase 0";
  if (lit_since > 0) {
    /* Phase 0 went on during the last frame's transfer, and what arrived before was flushed
     * after that frame's grab: only the trigger is left. */
    g_assert (!cy->dark);
    cy->applied_at_us = lit_since;
  } else {
    if (cy->dark) {
      if (!ds_seq_illuminator_off (acq, &cy->counters, &e)) {
        carry_device_error (acq, e, first); /* prefixed "dark frame: illuminator off" */
        return;
      }
    } else {
      gint64 t = g_get_monotonic_time ();
      if (!ds_seq_set_phase (acq, 0, &e)) {
        cy->counters.device_errors++;
        g_prefix_error (&e, "illuminator: ");
        carry_device_error (acq, e, first);
        return;
      }
      ds_seq_stage_add (acq->shared, DS_STAGE_SET_PHASE, t);
    }
    ds_seq_flush_stale (acq, &cy->counters);
    cy->applied_at_us = g_get_monotonic_time ();
  }
  cy->begun_before = ds_seq_frames_begun (acq);
  if (!ds_seq_trigger (acq, &cy->counters, &e)) {
    g_prefix_error (&e, "camera: ");
    carry_device_error (acq, e, first);
    return;
  }
  cy->stage = DS_CARRY_TRIGGERED;
}

void
ds_seq_carry_grab (DsAcquisition *acq)
{
  DsSeqCarry *cy = &acq->carry;
  if (cy->stage != DS_CARRY_TRIGGERED)
    return;
  g_autoptr (GError) e = NULL;
  cy->frame = ds_seq_grab (acq, &cy->counters, &e);
  cy->stage = cy->frame ? DS_CARRY_HELD : DS_CARRY_COUNTED;
  if (!cy->frame) {
    g_prefix_error (&e, "camera: ");
    carry_device_error (acq, e, cy->dark ? "dark frame" : "phase 0");
    /* A frame of the lost trigger that still comes is flushed after the next set_phase. */
  }
}

gboolean
ds_seq_carry_fits (DsAcquisition *acq, DsSetOrigin origin, const DsCaptureSettings *s)
{
  return acq->carry.stage != DS_CARRY_NONE && !acq->carry.error && origin == DS_SET_FOR_STREAM && !acq->need_reconnect &&
         acq->dev && memcmp (&acq->carry.settings, s, sizeof *s) == 0;
}

void
ds_seq_carry_discard (DsAcquisition *acq)
{
  DsSeqCarry *cy = &acq->carry;
  if (cy->stage == DS_CARRY_NONE)
    return;
  if (cy->stage == DS_CARRY_TRIGGERED && acq->dev && !acq->need_reconnect)
    ds_seq_carry_grab (acq);
  if (cy->frame) {
    ds_frame_counters_drop (&cy->counters, DS_DROP_ABORTED, 1);
    g_clear_pointer (&cy->frame, ds_frame_free);
  }
  if (cy->error) {
    /* The set it belonged to failed on its first frame (carry_device_error). */
    ds_seq_account_failed (acq->shared, &cy->counters, cy->error);
    ds_seq_refresh_device_status (acq);
    ds_seq_emit (acq->shared, DS_SEQUENCER_EVENT_FAILED, 0, NULL, g_steal_pointer (&cy->error), NULL);
  } else {
    ds_seq_account_frames (acq->shared, &cy->counters);
    /* The camera's statistics count the frame grabbed here as the counters now do. */
    ds_seq_refresh_device_status (acq);
  }
  memset (cy, 0, sizeof *cy);
}
