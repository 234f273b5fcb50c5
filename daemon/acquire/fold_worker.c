/* The verify-and-fold worker: a second thread that verifies one frame and, if it passes, folds
 * it into the phase set, while the acquisition thread moves the illuminator and exposes the
 * next frame (docs/design.md, "The pipeline").
 *
 * One job at a time, handed over and collected under one mutex: the acquisition thread never
 * submits a second job before it collected the first, so frames are verified and folded in the
 * order they were grabbed. The worker touches what the job lends it (phase set, phase check,
 * raw frames) only between submit and collect; the acquisition thread touches them only
 * outside, so the mutex orders every access. The worker calls no driver, counts nothing and
 * writes none of the acquisition thread's fields: its findings go into the job's out fields;
 * the acquisition thread owns the frame (and returns its buffer to the camera) and does the
 * accounting after collect. The only shared state it writes is the stage times, under the
 * shared lock. The exception is a per-frame result (fold_worker.h, window_done): the worker
 * publishes it, with what the job lends for it, so that it does not wait for the next
 * frame. */
#include <string.h>

#include "daemon/acquire/fold_worker.h"

struct DsFoldWorker {
  DsSequencerShared *shared;
  GThread *thread;
  GMutex lock;
  GCond cond;
  gboolean has_job, done, quit;
  DsFoldJob job;
};

/* Verifies, folds (and for the set's last frame finalizes) one job, filling its out fields.
 * overlapped: on the worker thread, while the next frame is acquired; else on the acquisition
 * thread with nothing to overlap with. CPU only; a failure goes to job->fold_error. */
static void
run_job (DsSequencerShared *shared, DsFoldJob *job, gboolean overlapped)
{
  gint64 t = g_get_monotonic_time ();
  job->times.verify_started_us = t;
  ds_seq_verify_frame (job->phase_check, job->settings, job->phase, job->frame, job->applied_at_us,
                       &job->verdict);
  ds_seq_stage_add (shared, DS_STAGE_VERIFY, t);
  if (job->verdict.reason != DS_DROP_N_REASONS)
    return;
  t = g_get_monotonic_time ();
  job->times.verified_us = t;
  /* While the next frame is acquired, its transfer (and on a rig with a software camera or
   * illuminator controller, those too) needs a core of its own: an overlapped fold takes one
   * thread, and so does the finalize of a set whose successor's first frame is acquired
   * meanwhile (continuous mode), since a finalize spread over every core delays that frame's
   * transfer and with it the next set. Nothing overlaps with the last frame of a set
   * otherwise: it takes every core. */
  if (!job->window_step) {
    ds_phase_set_set_fold_threads (job->set, overlapped ? 1 : 0);
    ds_phase_set_set_finalize_threads (job->set, overlapped ? 1 : 0);
  }
  if (job->window_step) {
    job->folded = job->window_step (job, job->window_data);
  } else if (job->finalize_into) {
    /* The set's last frame: the result's planes now, in the same job (on the fold thread in
     * continuous mode, while the next set's first frame exposes, on this thread alone;
     * docs/design.md), the frame folded on the finalize's pass over the pixels. The fold
     * stage's time then includes the finalize. */
    job->finalized = ds_phase_set_accumulate_finalize_into (job->set, job->phase, job->frame->image,
                                                            job->finalize_into, &job->folded, &job->fold_error);
  } else {
    job->folded = ds_phase_set_accumulate (job->set, job->phase, job->frame->image, &job->fold_error);
  }
  if (!job->folded)
    return;
  job->times.folded_us = g_get_monotonic_time ();
  ds_seq_stage_add (shared, DS_STAGE_FOLD, t);
  if (job->window_done)
    job->window_done (job, job->window_data);
  /* Copies made here overlap with the next exposure instead of delaying it. */
  const DsFrame *f = job->frame;
  if (job->raw && !ds_raw_frames_add (job->raw, job->phase, f->frame_id, f->timestamp_ns, f->image, NULL))
    job->raw_copy_failed = TRUE;
  gpointer hook_data = NULL;
  DsSequencerFrameFunc hook = ds_seq_frame_hook (shared, &hook_data);
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
    run_job (w->shared, &w->job, TRUE);
    g_mutex_lock (&w->lock);
    w->has_job = FALSE;
    w->done = TRUE;
    g_cond_broadcast (&w->cond);
  }
  g_mutex_unlock (&w->lock);
  return NULL;
}

DsFoldWorker *
ds_fold_worker_new (DsSequencerShared *shared)
{
  DsFoldWorker *w = g_new0 (DsFoldWorker, 1);
  w->shared = shared;
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
ds_fold_worker_submit (DsFoldWorker *w, const DsFoldJob *job, gboolean here)
{
  g_mutex_lock (&w->lock);
  g_assert (!w->has_job && !w->done);
  /* The in fields only: the out fields start cleared. */
  w->job = (DsFoldJob) { .settings = job->settings, .phase = job->phase, .frame = job->frame,
                         .applied_at_us = job->applied_at_us, .set = job->set,
                         .phase_check = job->phase_check, .raw = job->raw,
                         .finalize_into = job->finalize_into, .window_step = job->window_step,
                         .window_data = job->window_data, .window_done = job->window_done };
  if (here) {
    /* Nothing to overlap with (the last frame of a set): no hand-over, no wake-up latency.
     * The worker is idle (no job), so the phase set is this thread's. */
    g_mutex_unlock (&w->lock);
    run_job (w->shared, &w->job, FALSE);
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
