/* The pipeline: the N phases of a set (M frames each) acquired so that verifying and folding
 * frame i overlaps with acquiring frame i+1, and the illuminator moves to the next phase while
 * the last frame of a phase transfers. Why each overlap keeps the sequencer contract is argued
 * in docs/design.md ("The pipeline"); in short:
 *   - the illuminator leaves phase k only once the camera began sending the last frame of k
 *     (ops->frames_begun; a camera sends a frame after its exposure) or after it was received;
 *     a trigger goes out only after set_phase returned (phase applied) and stale buffers were
 *     flushed;
 *   - each frame carries the time its own phase was applied and is verified against that phase
 *     (stale, frame gap, stripe phase) before it is folded, exactly as without the pipeline;
 *   - frames are verified and folded in the order they were grabbed (one job at a time);
 *   - when the verdict on frame i is a drop after the illuminator already moved on, the frame
 *     grabbed meanwhile is kept back, phase k is applied again and re-acquired, and the kept
 *     frame is folded after it (it was exposed while its own phase was applied).
 * Every frame ends in exactly one counter: folded (via the set), or dropped with its reason. */
#include <string.h>

#include "daemon/protocol/protocol.h"
#include "daemon/acquire/acquisition.h"

typedef struct {
  DsAcquisition *acq;
  const DsCaptureSettings *s;
  guint64 tag;
  DsFrameCounters *c;
  guint *accepted;        /* frames of each phase verified and folded */
  guint *retries_left;    /* per phase */
  /* The frame in the worker (at most one). */
  gboolean in_flight;
  guint in_flight_phase;
  DsFrame *in_flight_frame;
  /* A frame grabbed while the verdict on the previous one was a drop of an earlier phase:
   * folded once that phase is complete again. */
  DsFrame *held;
  guint held_phase;
  gint64 held_applied_at;
  gboolean failing;       /* the set failed: collect the last job without reporting progress */
  /* A stream's set: the next set's first frame is triggered ahead once this set's last frame
   * is in the worker (carry.c). */
  DsSetOrigin origin;
  gboolean ahead;         /* origin is DS_SET_FOR_STREAM */
  /* This set's first frame was triggered ahead by the previous set: grab it without a trigger
   * (grab_begun_before: the camera's frames_begun before that trigger). */
  gboolean grab_only;
  guint64 grab_begun_before;
  DsSeparation *planes;   /* the result's, finalized by the job of the frame completing the set */
  gboolean finalized;
  /* Applying the next phase during a frame's transfer failed: handled (retry or fail) once
   * that frame was grabbed and handed to the worker, as if applying it had failed then. */
  GError *early_error;
  guint early_phase;
  /* Continuous mode: the next set's phase 0 was lit during the transfer of this set's last
   * frame, and stale buffers flushed after its grab at this time (0: not). */
  gint64 next_set_lit_at;
} Pipeline;

/* After a device failure in phase k, or a frame of it dropped: the one retry rule
 * (ds_seq_retry_or_fail), with phase k's retries. Each failure is prefixed once: "phase k: "
 * when it ends the set at once, "phase k: retries exhausted: " when the retries ran out. */
static gboolean
retry_or_fail (Pipeline *pl, guint k, GError **why, GError **error)
{
  return ds_seq_retry_or_fail (pl->acq, &pl->retries_left[k], pl->c, why, error, "phase %u", k);
}

/* Waits for the frame in the worker and accounts for it. *dropped_phase receives its phase when
 * verification dropped it, else G_MAXUINT; *reapply when the illuminator must apply that phase
 * again. FALSE with error when the set must fail (fold error, retries exhausted). */
static gboolean
collect (Pipeline *pl, guint *dropped_phase, gboolean *reapply, GError **error)
{
  *dropped_phase = G_MAXUINT;
  *reapply = FALSE;
  if (!pl->in_flight)
    return TRUE;
  DsFoldJob job;
  ds_fold_worker_collect (pl->acq->worker, &job);
  pl->in_flight = FALSE;
  /* Once a copy failed, no later job copies (submit lends no raw frames): the set's raw
   * frames are not published. */
  if (job.raw_copy_failed)
    pl->acq->raw_incomplete = TRUE;
  guint k = pl->in_flight_phase;
  g_autoptr (DsFrame) frame = g_steal_pointer (&pl->in_flight_frame);
  if (job.verdict.reason != DS_DROP_N_REASONS) {
    ds_frame_counters_drop (pl->c, job.verdict.reason, 1);
    GError *why = g_error_new (DS_SEQUENCER_ERROR, DS_SEQUENCER_ERROR_FRAME_REJECTED, "frame dropped (%s): %s",
                               ds_drop_reason_name (job.verdict.reason),
                               job.verdict.detail ? job.verdict.detail : "");
    *dropped_phase = k;
    *reapply = job.verdict.reapply_phase;
    ds_frame_verdict_clear (&job.verdict);
    return retry_or_fail (pl, k, &why, error);
  }
  if (job.verdict.unverified) {
    /* Folded without a phase proof: counted (the set's metadata carries the count), the reason
     * at debug level. */
    pl->c->unverified++;
    g_debug ("phase %u: frame folded unverified: %s", k, job.verdict.detail ? job.verdict.detail : "");
  }
  ds_frame_verdict_clear (&job.verdict);
  if (!job.folded) {
    ds_frame_counters_drop (pl->c, DS_DROP_ABORTED, 1);
    g_propagate_error (error, job.fold_error);
    return FALSE;
  }
  gint64 arrival = frame->host_time_us ? (gint64) frame->host_time_us : g_get_monotonic_time ();
  if (arrival >= pl->acq->last_frame_us) {
    pl->acq->last_frame_us = arrival;
    pl->acq->last_frame_times = job.times;
  }
  if (++pl->accepted[k] == pl->s->averages && !pl->failing)
    ds_seq_emit_progress (pl->acq->shared, pl->tag, k, pl->s->phases);
  if (job.finalize_into && !job.finalized) {
    /* Folded (the set fails, so it goes down as aborted with the others), not finalized. */
    g_propagate_prefixed_error (error, job.fold_error, "finalize: ");
    return FALSE;
  }
  pl->finalized = pl->finalized || job.finalized;
  return TRUE;
}

/* Frames phase k has or will have once the worker answers. */
static guint frames_of (const Pipeline *pl, guint k);

static void
submit (Pipeline *pl, guint k, DsFrame *frame, gint64 applied_at)
{
  /* The frame that completes the set (every earlier one was collected and accepted): its job
   * finalizes the set too. Nothing follows it to overlap with, so it is verified, folded and
   * finalized right here, sparing two thread wake-ups between the last frame and the result;
   * unless the next set's first frame is triggered ahead (continuous mode), which then
   * overlaps with all three. */
  gboolean last = k + 1 == pl->s->phases && frames_of (pl, k) + 1 >= pl->s->averages && !pl->held;
  DsAcquisition *acq = pl->acq;
  pl->in_flight = TRUE;
  pl->in_flight_phase = k;
  pl->in_flight_frame = frame;
  /* The job's context, lent to the worker until collect. */
  DsFoldJob job = { .settings = pl->s, .phase = k, .frame = frame, .applied_at_us = applied_at,
                    .set = acq->set, .phase_check = &acq->phase_check,
                    .raw = acq->raw_incomplete ? NULL : acq->raw,
                    .finalize_into = last ? pl->planes : NULL };
  ds_fold_worker_submit (acq->worker, &job, last && !pl->ahead);
}

static guint
frames_of (const Pipeline *pl, guint k)
{
  return pl->accepted[k] + (pl->in_flight && pl->in_flight_phase == k) +
         (pl->held && pl->held_phase == k);
}

/* The phase the illuminator may move to while the frame just triggered for phase k transfers:
 * k + 1 when that frame completes phase k (once accepted) and k + 1 still needs frames; 0 when
 * it completes the set and the next set's first frame will be triggered ahead with phase 0 lit
 * (continuous mode, carry.c; not for a next set that starts with its dark frame, nor
 * with one phase, which stays lit); G_MAXUINT when it stays (more frames of k, a frame kept
 * back). */
static guint
phase_to_move_to (const Pipeline *pl, guint k)
{
  const DsCaptureSettings *s = pl->s;
  if (pl->held || frames_of (pl, k) + 1 < s->averages)
    return G_MAXUINT;
  if (k + 1 >= s->phases)
    return pl->ahead && s->phases > 1 && !s->dark_frame && ds_seq_carry_allowed (pl->acq, pl->origin, s) ? 0 : G_MAXUINT;
  if (frames_of (pl, k + 1) >= s->averages)
    return G_MAXUINT;
  return k + 1;
}

/* Triggers the frame of phase k (unless the previous set did: grab_only) and grabs it. When
 * the camera tells that the frame's exposure is over (it began sending it) and the illuminator
 * may move on (phase_to_move_to), the next phase is applied during the frame's transfer:
 * *applied and *applied_at then follow it. */
static DsFrame *
trigger_and_grab (Pipeline *pl, guint k, int *applied, gint64 *applied_at, GError **error)
{
  DsAcquisition *acq = pl->acq;
  guint next = phase_to_move_to (pl, k);
  guint64 before;
  pl->next_set_lit_at = 0;
  if (pl->grab_only) {
    pl->grab_only = FALSE;
    before = pl->grab_begun_before;
  } else {
    before = next != G_MAXUINT ? ds_seq_frames_begun (acq) : 0;
    if (!ds_seq_trigger (acq, pl->c, error))
      return NULL;
  }
  if (next == G_MAXUINT)
    return ds_seq_grab (acq, pl->c, error);
  gint64 t = g_get_monotonic_time ();
  if (!ds_seq_wait_exposure_over (acq, before)) {
    /* No frame began within the grab timeout (or the camera cannot tell): the illuminator
     * stays, and the grab's deadline is what is left of it. */
    guint waited_ms = (guint) ((g_get_monotonic_time () - t) / 1000);
    guint left = acq->dev->grab_timeout_ms > waited_ms ? acq->dev->grab_timeout_ms - waited_ms : 1;
    return ds_seq_grab_within (acq, pl->c, left, error);
  }
  /* Frame k is exposed: phase `next` is lit during its transfer, settling meanwhile. */
  t = g_get_monotonic_time ();
  g_autoptr (GError) next_set_error = NULL;
  /* The next set's phase 0 (next < k): failing to light it is not this set's failure; the
   * carry applies it again and handles a failure as its own (carry.c). */
  GError **set_phase_error = next < k ? &next_set_error : &pl->early_error;
  if (ds_seq_set_phase (acq, next, set_phase_error)) {
    ds_seq_stage_add (acq->shared, DS_STAGE_SET_PHASE, t);
    *applied = (int) next;
  } else {
    pl->c->device_errors++;
    if (next > k) {
      g_prefix_error (&pl->early_error, "illuminator: ");
      pl->early_phase = next;
    }
    *applied = -1;
  }
  DsFrame *frame = ds_seq_grab (acq, pl->c, error);
  /* What was delivered besides frame k is stale, as after any phase change; frames of `next`
   * can only arrive after this (verification's "arrived after the phase was applied"). */
  ds_seq_flush_stale (acq, pl->c);
  *applied_at = g_get_monotonic_time ();
  if (frame && next < k && *applied == (int) next)
    pl->next_set_lit_at = *applied_at;
  return frame;
}

static gboolean
run (Pipeline *pl, int applied, gint64 applied_at, GError **error)
{
  /* applied: the phase the illuminator shows, -1 unknown; applied_at: since when. */
  DsAcquisition *acq = pl->acq;
  const DsCaptureSettings *s = pl->s;
  guint k = 0;
  for (;;) {
    if (!ds_seq_check_quit (acq, error))
      return FALSE;
    if (pl->early_error) {
      /* Applying phase early_phase during the previous frame's transfer failed. */
      GError *why = g_steal_pointer (&pl->early_error);
      if (!retry_or_fail (pl, pl->early_phase, &why, error))
        return FALSE;
      continue;
    }
    guint dropped;
    if (k >= s->phases) {
      /* Every phase has its frames, the last one perhaps still in the worker. */
      if (!pl->in_flight)
        return TRUE;
      if (pl->ahead && acq->carry.stage == DS_CARRY_NONE && ds_seq_carry_allowed (acq, pl->origin, s)) {
        /* The last frame arrived, so its exposure is over: the next set's first frame is
         * exposed while it is verified and folded and while the result is finalized. */
        ds_seq_carry_trigger (acq, s, 0);
        applied = acq->carry.stage == DS_CARRY_TRIGGERED && !acq->carry.dark ? 0 : -1;
      }
      gboolean re;
      if (!collect (pl, &dropped, &re, error))
        return FALSE;
      if (dropped != G_MAXUINT) {
        k = dropped;
        if (re && applied == (int) dropped)
          applied = -1;
      }
      continue;
    }
    if (pl->held && pl->held_phase == k) {
      /* Phase k-1 is complete again: the frame kept back goes to the worker. */
      gboolean re;
      if (!collect (pl, &dropped, &re, error))
        return FALSE;
      if (dropped != G_MAXUINT) {
        k = dropped;
        if (re && applied == (int) dropped)
          applied = -1;
        continue;
      }
      DsFrame *f = g_steal_pointer (&pl->held);
      submit (pl, k, f, pl->held_applied_at);
      continue;
    }
    if (frames_of (pl, k) >= s->averages) {
      k++;
      continue;
    }
    /* A frame triggered ahead for the next set is fetched before this set moves the
     * illuminator or triggers again (the last frame was dropped: its phase is acquired again). */
    if (acq->carry.stage == DS_CARRY_TRIGGERED)
      ds_seq_carry_grab (acq);
    GError *why = NULL;
    if (applied != (int) k) {
      /* Overlaps with the worker verifying and folding the previous phase's last frame. */
      gint64 t = g_get_monotonic_time ();
      if (!ds_seq_set_phase (acq, k, &why)) {
        pl->c->device_errors++;
        applied = -1;
        g_prefix_error (&why, "illuminator: ");
        if (!retry_or_fail (pl, k, &why, error))
          return FALSE;
        continue;
      }
      ds_seq_stage_add (acq->shared, DS_STAGE_SET_PHASE, t);
      ds_seq_flush_stale (acq, pl->c);
      applied = (int) k;
      applied_at = g_get_monotonic_time ();
    }
    /* Exposed while phase k was applied, since frame_applied_at (applied_at may move on to the
     * next phase during the transfer). */
    gint64 frame_applied_at = applied_at;
    DsFrame *frame = trigger_and_grab (pl, k, &applied, &applied_at, &why);
    if (!frame) {
      g_prefix_error (&why, "camera: ");
      if (!retry_or_fail (pl, k, &why, error))
        return FALSE;
      /* After a lost frame the illuminator's state is still right, but a late buffer of the
       * lost trigger may arrive: flush before the next trigger. */
      ds_seq_flush_stale (acq, pl->c);
      continue;
    }
    if (pl->next_set_lit_at > 0) {
      /* The set's last frame is here and the next set's phase 0 is lit: that set's first
       * frame goes out now, before the verdict on the frame before this one and before this
       * one's job (whose finalize takes a core), so that the trigger waits for neither.
       * When that verdict is a drop, this frame is kept back and the frame triggered ahead is
       * grabbed before the dropped phase is lit again (below), as after a drop of the last
       * frame. */
      if (acq->carry.stage == DS_CARRY_NONE && ds_seq_carry_allowed (acq, pl->origin, s))
        ds_seq_carry_trigger (acq, s, pl->next_set_lit_at);
      pl->next_set_lit_at = 0;
    }
    gboolean re;
    if (!collect (pl, &dropped, &re, error)) {
      ds_frame_free (frame); /* acquired, not dropped: the caller counts it as aborted */
      return FALSE;
    }
    if (dropped != G_MAXUINT && re && applied == (int) dropped)
      applied = -1;
    if (dropped != G_MAXUINT && dropped < k) {
      /* The illuminator moved on before the verdict came: keep this frame (exposed while k
       * was applied), go back to the dropped phase. */
      g_assert (!pl->held);
      pl->held = frame;
      pl->held_phase = k;
      pl->held_applied_at = frame_applied_at;
      k = dropped;
      continue;
    }
    submit (pl, k, frame, frame_applied_at);
  }
}

gboolean
ds_seq_acquire_phases (DsAcquisition *acq, const DsCaptureSettings *s, guint64 tag, DsSetOrigin origin,
                       DsFrameCounters *c, DsSeparation *planes, gboolean *finalized, GError **error)
{
  g_autofree guint *accepted = g_new0 (guint, s->phases);
  g_autofree guint *retries_left = g_new (guint, s->phases);
  for (guint k = 0; k < s->phases; k++)
    retries_left[k] = s->phase_retries;
  acq->last_frame_us = 0;
  memset (&acq->last_frame_times, 0, sizeof acq->last_frame_times);
  Pipeline pl = { .acq = acq, .s = s, .tag = tag, .c = c, .accepted = accepted,
                  .retries_left = retries_left, .origin = origin,
                  .ahead = origin == DS_SET_FOR_STREAM, .planes = planes };
  int applied = -1;
  gint64 applied_at = 0;
  if (acq->carry.stage != DS_CARRY_NONE) {
    /* The set runner checked that it fits this set (ds_seq_carry_fits): phase 0 was applied
     * for this set's first frame, triggered or grabbed already. (A carry for a dark frame was
     * taken over by the dark frame's acquisition before.) */
    DsSeqCarry *cy = &acq->carry;
    g_assert (!cy->dark);
    ds_frame_counters_add (c, &cy->counters);
    if (cy->stage == DS_CARRY_TRIGGERED) {
      /* A frame kept (cy->frame) was grabbed before the previous set lit its dropped phase
       * again: the illuminator no longer shows phase 0 then. */
      applied = 0;
      applied_at = cy->applied_at_us;
    }
    pl.grab_only = cy->stage == DS_CARRY_TRIGGERED;
    pl.grab_begun_before = cy->begun_before;
    if (cy->stage == DS_CARRY_HELD) {
      pl.held = g_steal_pointer (&cy->frame);
      pl.held_phase = 0;
      pl.held_applied_at = cy->applied_at_us;
    }
    memset (cy, 0, sizeof *cy);
  }
  gboolean ok = run (&pl, applied, applied_at, error);
  pl.failing = !ok;
  if (pl.in_flight) {
    /* A failing set still waits for its last job: the worker must be idle before the phase
     * set is touched again, and the frame is counted like any other. */
    guint dropped;
    gboolean re;
    g_autoptr (GError) ignored = NULL;
    collect (&pl, &dropped, &re, &ignored);
  }
  /* A frame kept back and never folded is acquired but not dropped: the caller counts it as
   * aborted with the rest of the failed set. */
  g_clear_pointer (&pl.held, ds_frame_free);
  /* Counted as a device error when it happened; the set failed for another reason first. */
  g_clear_error (&pl.early_error);
  *finalized = ok && pl.finalized;
  return ok;
}
