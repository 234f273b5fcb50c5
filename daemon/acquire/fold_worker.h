/* The verify-and-fold worker and the job it runs: one frame verified and, if it passes, folded
 * into the phase set (and, for the set's last frame, the set finalized), on a second thread
 * while the acquisition thread acquires the next frame.
 *
 * A job carries its whole context: the phase set, the phase check and the raw frames it may
 * touch are borrowed from the acquisition thread between submit and collect, and what the
 * worker finds (verdict, fold error, a raw copy that failed, timestamps) goes into the job's
 * out fields, which the acquisition thread reads after collect. The worker writes no field of
 * the acquisition thread's (DsAcquisition) and only the shared status's stage times, under its
 * lock; but a per-frame job's window_done publishes its result from the worker, which takes the
 * next result id (DsAcquisition.next_set_id, lent with the job: a per-frame run's acquisition
 * thread takes none) and counts the result and its frames in the shared status, under its
 * lock. */
#pragma once
#include <glib.h>

#include "daemon/acquire/sequencer_shared.h"
#include "daemon/output/raw_frames.h"
#include "proc/phase_check.h"
#include "proc/separation.h"

G_BEGIN_DECLS

/* ---- verify.c ---- */

typedef struct {
  DsDropReason reason;     /* DS_DROP_N_REASONS: the frame may be folded */
  char *detail;            /* why, when dropped (owned) */
  gboolean reapply_phase;  /* the illuminator may show another phase: apply k again */
  gboolean unverified;     /* may be folded, but its stripes could not prove its phase (detail: why) */
} DsFrameVerdict;

/* Verifies a frame lit (as far as the sequencer knows) with phase k, applied at applied_at_us,
 * in the order of docs/design.md: stale, frame gap, stripe phase (against check, which learns
 * from the frame). The thread that owns check at the time: the fold worker during a job, the
 * acquisition thread otherwise. CPU only; never fails (the verdict says why a frame is
 * dropped). */
void ds_seq_verify_frame (DsPhaseCheck *check, const DsCaptureSettings *s, guint k,
                          const DsFrame *frame, gint64 applied_at_us, DsFrameVerdict *verdict);
void ds_frame_verdict_clear (DsFrameVerdict *verdict);

/* ---- fold_worker.c ---- */

typedef struct DsFoldWorker DsFoldWorker;

typedef struct DsFoldJobS {
  /* In: borrowed by the worker from submit to collect; the acquisition thread leaves them
   * alone meanwhile. */
  const DsCaptureSettings *settings;
  guint phase;
  DsFrame *frame;                    /* the acquisition thread frees it after collect */
  gint64 applied_at_us;
  DsPhaseSet *set;                   /* folded into */
  DsPhaseCheck *phase_check;         /* verification's, learning from the frame */
  DsRawFrames *raw;                  /* the frame is copied in once folded; NULL: no copy */
  DsSeparation *finalize_into;       /* the set's last frame: once folded, the set is finalized
                                      * into these planes */
  /* Per-frame results (window_stream.c): once verified, the frame goes to window_step instead
   * of into `set` (NULL then); it returns whether the frame was taken (else fold_error), and
   * sets finalized when it finalized a result into finalize_into. window_data is lent too. */
  gboolean (*window_step) (struct DsFoldJobS *job, gpointer window_data);
  gpointer window_data;
  /* Run at the end of a job whose window_step took the frame, once the job's times are
   * stamped (window_stream.c publishes the result the step made): a result then does not wait
   * until the acquisition thread, which meanwhile waits for the next frame, collects the job.
   * It uses what the job lends (window_data, the frame, finalize_into) and calls no driver.
   * NULL: none. */
  void (*window_done) (struct DsFoldJobS *job, gpointer window_data);
  /* Out: the worker's findings, read by the acquisition thread after collect. */
  DsFrameVerdict verdict;
  gboolean folded;                   /* verified and folded */
  gboolean finalized;                /* ... and the set finalized into finalize_into */
  GError *fold_error;                /* verified, but the fold (or the finalize) failed */
  gboolean raw_copy_failed;          /* folded, but the copy into raw failed: the set's raw
                                      * frames are incomplete */
  DsLastFrameTimes times;            /* when it was verified and folded */
} DsFoldJob;

/* Starts the worker thread; shared gives it the stage times and the frame hook. Acquisition
 * thread. Never fails. */
DsFoldWorker *ds_fold_worker_new (DsSequencerShared *shared);
/* Waits for a job in progress, then stops and joins the thread. Acquisition thread; blocks for
 * at most one job. */
void ds_fold_worker_free (DsFoldWorker *worker);
/* Hands one job over (its in fields; never blocks); the previous job must have been collected.
 * With `here` the job runs on the calling thread before this returns (for a frame nothing will
 * overlap with); collect it all the same. Acquisition thread. */
void ds_fold_worker_submit (DsFoldWorker *worker, const DsFoldJob *job, gboolean here);
/* Waits for the submitted job and moves it, with its outcome, to *job (the caller then owns
 * verdict.detail and fold_error). Acquisition thread; blocks until the job is done. */
void ds_fold_worker_collect (DsFoldWorker *worker, DsFoldJob *job);

G_END_DECLS
