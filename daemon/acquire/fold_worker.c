/* The verify-and-fold worker: a second thread that verifies one frame and, if it passes, folds
 * it into the phase set, while the acquisition thread moves the illuminator and exposes the
 * next frame (docs/design.md, "The pipeline").
 *
 * One job at a time, handed over and collected under one mutex: the acquisition thread never
 * submits a second job before it collected the first, so frames are verified and folded in the
 * order they were grabbed. The worker touches the phase set and the phase check only between
 * submit and collect; the acquisition thread touches them only outside, so the mutex orders
 * every access. The worker calls no driver and counts nothing: the acquisition thread owns the
 * frame (and returns its buffer to the camera) and does the accounting after collect. */
#include <string.h>

#include "daemon/acquire/sequencer_private.h"

struct DsFoldWorker {
  DsSequencer *seq;
  GThread *thread;
  GMutex lock;
  GCond cond;
  gboolean has_job, done, quit;
  DsFoldJob job;
};

/* overlapped: the next frame is being acquired meanwhile (the fold thread). */
static void
run_job (DsSequencer *seq, DsFoldJob *job, gboolean overlapped)
{
  gint64 t = g_get_monotonic_time ();
  job->times.verify_started_us = t;
  ds_seq_verify_frame (seq, job->settings, job->phase, job->frame, job->applied_at_us, &job->verdict);
  ds_seq_stage_add (seq, DS_STAGE_VERIFY, t);
  if (job->verdict.reason != DS_DROP_N_REASONS)
    return;
  t = g_get_monotonic_time ();
  job->times.verified_us = t;
  /* While the next frame is acquired, the transfer (and on a rig like the benchmark's, the
   * camera and the illuminator's controller) need a core: the fold takes one, and so does the
   * finalize of a set whose successor's first frame is acquired meanwhile (continuous mode):
   * on two cores a finalize on both held up that frame's transfer, the camera's cycle of phase 0
   * the longest of the set (docs/benchmarks.md, "run U"). Nothing overlaps with the last frame
   * of a set otherwise: it takes all. */
  ds_phase_set_set_fold_threads (seq->set, overlapped ? 1 : 0);
  ds_phase_set_set_finalize_threads (seq->set, overlapped ? 1 : 0);
  if (job->finalize_into) {
    /* The set's last frame: the result's planes now, in the same job (on the fold thread in
     * continuous mode, while the next set's first frame exposes, on this thread alone;
     * docs/design.md), the frame folded on the finalize's pass over the pixels. The fold
     * stage's time then includes the finalize. */
    job->finalized = ds_phase_set_accumulate_finalize_into (seq->set, job->phase, job->frame->image,
                                                            job->finalize_into, &job->folded, &job->fold_error);
  } else {
    job->folded = ds_phase_set_accumulate (seq->set, job->phase, job->frame->image, &job->fold_error);
  }
  if (!job->folded)
    return;
  job->times.folded_us = g_get_monotonic_time ();
  ds_seq_stage_add (seq, DS_STAGE_FOLD, t);
  /* Copies made here overlap with the next exposure instead of delaying it. */
  const DsFrame *f = job->frame;
  if (seq->raw && !seq->raw_incomplete &&
      !ds_raw_frames_add (seq->raw, job->phase, f->frame_id, f->timestamp_ns, f->image, NULL))
    seq->raw_incomplete = TRUE;
  g_mutex_lock (&seq->lock);
  DsSequencerFrameFunc hook = seq->frame_hook;
  gpointer hook_data = seq->frame_hook_data;
  g_mutex_unlock (&seq->lock);
  if (hook)
    hook (f, job->phase, job->settings, hook_data);
}

static gpointer
worker_main (gpointer data)
{
  DsFoldWorker *w = data;
  g_mutex_lock (&w->lock);
  for (;;) {
    while (!w->has_job && !w->quit)
      g_cond_wait (&w->cond, &w->lock);
    if (w->quit)
      break;
    g_mutex_unlock (&w->lock);
    run_job (w->seq, &w->job, TRUE);
    g_mutex_lock (&w->lock);
    w->has_job = FALSE;
    w->done = TRUE;
    g_cond_broadcast (&w->cond);
  }
  g_mutex_unlock (&w->lock);
  return NULL;
}

DsFoldWorker *
ds_fold_worker_new (DsSequencer *seq)
{
  DsFoldWorker *w = g_new0 (DsFoldWorker, 1);
  w->seq = seq;
  g_mutex_init (&w->lock);
  g_cond_init (&w->cond);
  w->thread = g_thread_new ("fold", worker_main, w);
  return w;
}

void
ds_fold_worker_free (DsFoldWorker *w)
{
  if (!w)
    return;
  g_mutex_lock (&w->lock);
  while (w->has_job)
    g_cond_wait (&w->cond, &w->lock);
  w->quit = TRUE;
  g_cond_broadcast (&w->cond);
  g_mutex_unlock (&w->lock);
  g_thread_join (w->thread);
  g_clear_error (&w->job.fold_error);
  ds_frame_verdict_clear (&w->job.verdict);
  g_mutex_clear (&w->lock);
  g_cond_clear (&w->cond);
  g_free (w);
}

void
ds_fold_worker_submit (DsFoldWorker *w, const DsCaptureSettings *s, guint phase, DsFrame *frame,
                       gint64 applied_at_us, DsSeparation *finalize_into, gboolean here)
{
  g_mutex_lock (&w->lock);
  g_assert (!w->has_job && !w->done);
  w->job = (DsFoldJob) { .settings = s, .phase = phase, .frame = frame,
                         .applied_at_us = applied_at_us, .finalize_into = finalize_into };
  if (here) {
    /* Nothing to overlap with (the last frame of a set): no hand-over, no wake-up latency.
     * The worker is idle (no job), so the phase set is this thread's. */
    g_mutex_unlock (&w->lock);
    run_job (w->seq, &w->job, FALSE);
    g_mutex_lock (&w->lock);
    w->done = TRUE;
  } else {
    w->has_job = TRUE;
    g_cond_broadcast (&w->cond);
  }
  g_mutex_unlock (&w->lock);
}

void
ds_fold_worker_collect (DsFoldWorker *w, DsFoldJob *job)
{
  g_mutex_lock (&w->lock);
  g_assert (w->has_job || w->done);
  while (!w->done)
    g_cond_wait (&w->cond, &w->lock);
  *job = w->job;
  memset (&w->job, 0, sizeof w->job);
  w->done = FALSE;
  g_mutex_unlock (&w->lock);
}
