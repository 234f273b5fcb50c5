/* The frames of one phase: apply phase k, flush stale buffers, then M times trigger, grab,
 * verify and fold, with retries counted against the phase. */
#include "daemon/protocol/protocol.h"
#include "daemon/service/sequencer_private.h"

/* Consumes one retry of the current phase after `why`; fails with `why` when none are left. */
static gboolean
use_retry (guint *retries_left, DsFrameCounters *c, guint k, GError **why, GError **error)
{
  if (*retries_left == 0) {
    g_propagate_prefixed_error (error, g_steal_pointer (why), "phase %u: retries exhausted: ", k);
    return FALSE;
  }
  (*retries_left)--;
  c->retries++;
  g_clear_error (why);
  return TRUE;
}

/* Acquires the M frames of phase k and folds them; every frame is verified first, so a frame
 * that fails is never folded, and frames already folded for k stay valid (they were verified
 * as phase k). */
gboolean
ds_seq_acquire_phase (DsSequencer *seq, const DsCaptureSettings *s, guint k, DsFrameCounters *c,
                      GError **error)
{
  guint retries_left = s->phase_retries;
  guint done = 0;
  gboolean need_phase = TRUE;
  gint64 applied_at = 0;
  while (done < s->averages) {
    GError *why = NULL;
    if (!ds_seq_check_quit (seq, error))
      return FALSE;
    if (need_phase) {
      gint64 t = g_get_monotonic_time ();
      if (!seq->dev->illuminator->ops->set_phase (seq->dev->illuminator->backend, k,
                                                  seq->dev->settle_timeout_ms, &why)) {
        c->device_errors++;
        g_prefix_error (&why, "illuminator: ");
        if (ds_seq_fatal_device_error (seq, why) || !use_retry (&retries_left, c, k, &why, &why)) {
          g_propagate_prefixed_error (error, why, "phase %u: ", k);
          return FALSE;
        }
        continue;
      }
      ds_seq_stage_add (seq, DS_STAGE_SET_PHASE, t);
      ds_seq_flush_stale (seq, c);
      applied_at = g_get_monotonic_time ();
      need_phase = FALSE;
    }
    g_autoptr (DsFrame) frame = ds_seq_trigger_and_grab (seq, c, &why);
    if (!frame) {
      g_prefix_error (&why, "camera: ");
      if (ds_seq_fatal_device_error (seq, why) || !use_retry (&retries_left, c, k, &why, &why)) {
        g_propagate_prefixed_error (error, why, "phase %u: ", k);
        return FALSE;
      }
      /* After a lost frame the illuminator's state is still right, but a late buffer of the
       * lost trigger may arrive: flush before the next trigger. */
      ds_seq_flush_stale (seq, c);
      continue;
    }
    gint64 t = g_get_monotonic_time ();
    DsFrameVerdict verdict;
    ds_seq_verify_frame (seq, s, k, frame, applied_at, &verdict);
    ds_seq_stage_add (seq, DS_STAGE_VERIFY, t);
    if (verdict.reason != DS_DROP_N_REASONS) {
      ds_frame_counters_drop (c, verdict.reason, 1);
      if (verdict.reapply_phase)
        need_phase = TRUE;
      why = g_error_new (DS_PROTOCOL_ERROR, DS_PROTOCOL_ERROR_DEVICE, "frame dropped (%s): %s",
                         ds_drop_reason_name (verdict.reason), verdict.detail ? verdict.detail : "");
      ds_frame_verdict_clear (&verdict);
      if (!use_retry (&retries_left, c, k, &why, &why)) {
        g_propagate_prefixed_error (error, why, "phase %u: ", k);
        return FALSE;
      }
      continue;
    }
    t = g_get_monotonic_time ();
    if (!ds_phase_set_accumulate (seq->set, k, frame->image, error)) {
      ds_frame_counters_drop (c, DS_DROP_ABORTED, 1);
      return FALSE;
    }
    ds_seq_stage_add (seq, DS_STAGE_FOLD, t);
    seq->last_frame_us = frame->host_time_us ? (gint64) frame->host_time_us : t;
    done++;
  }
  return TRUE;
}
