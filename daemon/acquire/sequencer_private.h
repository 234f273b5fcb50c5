/* Private to daemon/acquire/sequencer*.c: the acquisition thread's state and the helpers its
 * files share. Each file has one concern:
 *   sequencer.c          the thread, its command queue and the public requests
 *   report.c   events to the main context, status, accounting
 *   device_ops.c  device operations with their counting (trigger, grab, flush,
 *                        camera settings, reconnect) and the retry/fail policy
 *   set_runner.c      the set runner: one phase set from settings to result
 *   pipeline.c the N x M frames of a set, pipelined: the next phase is applied during
 *                        the transfer of the previous phase's last frame, and the next frame
 *                        exposed while the worker verifies and folds the previous frame
 *   fold_worker.c   the verify-and-fold worker thread
 *   carry.c    continuous mode: the next set's first frame, triggered while this
 *                        set's last frame is verified and its result finalized
 *   verify.c   frame verification (stale, frame gap, stripe phase)
 *   retry.c    the retry rule of every frame acquired (phase sets, dark, pilot)
 *   dark.c     dark-frame acquisition
 *   auto_point.c     the automatic operating point (preview frames)
 * Everything here runs on the acquisition thread unless it says otherwise. */
#pragma once
#include <glib.h>

#include "daemon/operating/operating_point.h"
#include "daemon/output/raw_frames.h"
#include "daemon/operating/rig_timing.h"
#include "proc/phase_check.h"
#include "daemon/acquire/result_planes.h"
#include "daemon/acquire/sequencer.h"

G_BEGIN_DECLS

typedef struct DsFoldWorker DsFoldWorker;

/* Continuous mode: the first frame of the next set (phase 0, or its first dark frame when it
 * takes one), triggered as soon as this set's last frame arrived, so that its exposure and
 * transfer overlap with the last frame's verification and fold and with the finalize
 * (docs/design.md, "The pipeline"). Acquisition thread only. */
typedef struct {
  gboolean active;            /* there is a carry (pending, frame or only counters) */
  gboolean dark;              /* for the next set's dark frame: the illuminator was turned off,
                               * not moved to phase 0 */
  gboolean pending;           /* triggered, not grabbed yet */
  guint64 begun_before;       /* ds_seq_frames_begun before its trigger: the next set may light
                               * phase 1 during its transfer */
  DsFrame *frame;             /* grabbed already (this set's last frame was dropped meanwhile) */
  gint64 applied_at_us;       /* when phase 0 (or off) was applied for it */
  DsCaptureSettings settings; /* the settings of the set it was taken after */
  DsFrameCounters counters;   /* what applying phase 0, triggering and grabbing counted */
  GError *error;              /* a device failure that fails the set it belongs to */
} DsSeqCarry;

/* What the acquisition thread does between commands. */
typedef enum {
  DS_RUN_ON_REQUEST = 0,   /* sets only for captures (and dark frames for the dark command) */
  DS_RUN_STREAM,           /* continuous mode: sets back to back with DsRun.settings */
  DS_RUN_STREAM_DEFAULTS,  /* continuous mode: sets back to back with the defaults as they are
                            * when each set starts (a reload changes the stream) */
} DsRunMode;

typedef struct {
  DsRunMode mode;
  DsCaptureSettings settings; /* the stream's next set (the defaults copied in before each set
                               * with DS_RUN_STREAM_DEFAULTS); unused with DS_RUN_ON_REQUEST */
} DsRun;

/* Whom a set is for. A stream's set may trigger the next set's first frame ahead (carry.c)
 * and keeps its raw frames without reserving them first (set_runner.c). */
typedef enum {
  DS_SET_FOR_REQUEST = 0,  /* a capture: answered with its tag */
  DS_SET_FOR_STREAM,       /* continuous mode's (tag 0) */
} DsSetOrigin;

struct DsSequencer {
  GThread *thread;
  GAsyncQueue *queue;
  GMainContext *context;
  DsSequencerEventFunc on_event;
  gpointer user_data;
  DsDevicesOpenFunc open_devices;
  gpointer open_data;
  gint quit;     /* atomic */
  gint pending;  /* atomic: captures and darks queued */
  /* Delivery of events after free must not happen: events hold a ref on this. */
  gint alive;    /* atomic: cleared by free before joining */

  GMutex lock;   /* protects status and defaults */
  DsSequencerStatus status;
  DsCaptureSettings defaults;

  /* Acquisition thread only. */
  DsDevices *dev;
  DsPhaseSet *set;
  DsSeparationParams set_params;
  guint set_width, set_height;
  DsImage *dark;
  double dark_exposure_us, dark_gain_db;
  gboolean camera_configured, camera_started;
  double camera_exposure_us, camera_gain_db;
  DsRun run;
  guint64 next_set_id;
  DsPhaseCheck phase_check;
  double phase_check_period;
  gboolean need_reconnect;
  gint64 last_frame_us;     /* arrival of the last folded frame */
  DsLastFrameTimes last_frame_times; /* ... and its job's stamps */
  const DsOperatingModel *model; /* set before the thread uses it; read-only */
  DsRigTiming timing;
  DsFoldWorker *worker;     /* verifies and folds while the next frame is acquired */
  DsSeqCarry carry;
  DsPlanePool *planes;      /* result planes, back from results nobody holds any more */
  /* The raw frames of the set in progress when it keeps them (save_phases): filled by the
   * worker between submit and collect, attached to the result by the set runner. */
  DsRawFrames *raw;
  gboolean raw_incomplete;  /* a copy failed: the set's raw frames are not published */
  GArray *dark_ids;         /* guint64 ids of the frames of the last dark acquired */
  GArray *stored_dark_ids;  /* ... of seq->dark */
  DsSequencerFrameFunc frame_hook; /* under lock when set; read by the worker */
  gpointer frame_hook_data;
};

/* ---- report.c: events (any order of posting is the order of dispatch) ---- */

/* Takes ownership of result and error. */
void ds_seq_emit (DsSequencer *seq, DsSequencerEventKind kind, guint64 tag, DsResult *result,
                  GError *error, const char *message);
void ds_seq_emit_progress (DsSequencer *seq, guint64 tag, guint phase, guint n);
void ds_seq_emit_dark (DsSequencer *seq, guint64 tag, double dark_mean_dn);

/* Status (under seq->lock). */
void ds_seq_set_state (DsSequencer *seq, DsSequencerState state);
void ds_seq_heartbeat (DsSequencer *seq);
/* Before a device call that may block: a sign of life, and the call's own bound. The watchdog
 * stays fed while the thread waits that long (a camera timing out is not a wedged thread),
 * and starves beyond it. The next heartbeat ends the declaration. */
void ds_seq_blocking (DsSequencer *seq, guint bound_ms);
/* A control round trip with the libraries' own retries (GVCP, Modbus): what a device call
 * without a timeout of its own may take before it fails. */
#define DS_SEQ_CONTROL_BOUND_MS 5000
void ds_seq_stage_add (DsSequencer *seq, DsStage stage, gint64 since_us);
void ds_seq_record_error (DsSequencer *seq, const GError *error);
void ds_seq_refresh_device_status (DsSequencer *seq);
/* Adds a set's (or a dark frame's) counters to the totals; ok counts the set as done. */
void ds_seq_account (DsSequencer *seq, const DsFrameCounters *c, gboolean ok);
/* Adds frame counters to the totals without counting a set (frames of no set). */
void ds_seq_account_frames (DsSequencer *seq, const DsFrameCounters *c);

/* ---- device_ops.c ---- */

gboolean ds_seq_ensure_camera (DsSequencer *seq, const DsCaptureSettings *s, GError **error);
gboolean ds_seq_apply_pattern (DsSequencer *seq, const DsCaptureSettings *s, GError **error);
/* Lights phase k, within the illuminator's settle timeout. */
gboolean ds_seq_set_phase (DsSequencer *seq, guint k, GError **error);
/* One frame: trigger and grab. Counts what happened. Returns NULL with error set. The two
 * halves apart, for a frame triggered ahead (carry.c). */
gboolean ds_seq_trigger (DsSequencer *seq, DsFrameCounters *c, GError **error);
DsFrame *ds_seq_grab (DsSequencer *seq, DsFrameCounters *c, GError **error);
/* The same within timeout_ms instead of the grab timeout. */
DsFrame *ds_seq_grab_within (DsSequencer *seq, DsFrameCounters *c, guint timeout_ms, GError **error);
DsFrame *ds_seq_trigger_and_grab (DsSequencer *seq, DsFrameCounters *c, GError **error);
/* Frames the camera has begun sending (camera ops->frames_begun), read before a trigger; 0
 * when the camera cannot tell or [camera] sends-after-exposure is false. */
guint64 ds_seq_frames_begun (DsSequencer *seq);
/* After a trigger, with `before` read before it: waits (up to the grab timeout) until the
 * camera began sending a frame since, so that its exposure is over. FALSE when it cannot tell
 * (as ds_seq_frames_begun) or no frame began in time (lost or late: grab finds out). */
gboolean ds_seq_wait_exposure_over (DsSequencer *seq, guint64 before);
/* Drops (and counts as stale) every frame already delivered but not grabbed. */
void ds_seq_flush_stale (DsSequencer *seq, DsFrameCounters *c);
/* FALSE with CANCELLED when the daemon is stopping. */
gboolean ds_seq_check_quit (DsSequencer *seq, GError **error);
/* TRUE when retrying cannot help (invalid, unsupported) or the device is gone (disconnected:
 * marks it for reconnection). */
gboolean ds_seq_fatal_device_error (DsSequencer *seq, const GError *e);
/* Reopens lost devices with capped backoff until they work or the daemon stops. */
void ds_seq_reconnect (DsSequencer *seq);
/* Applies the default settings (camera configured and started, pattern loaded) so that a
 * setting the devices refuse shows in status at once, not at the first capture; records the
 * outcome (status.settings_ok / settings_error) and reports a change as a device event. */
gboolean ds_seq_apply_defaults (DsSequencer *seq);

/* ---- set_runner.c ---- */

void ds_seq_run_set (DsSequencer *seq, const DsCaptureSettings *requested, guint64 tag,
                     DsSetOrigin origin);

/* ---- pipeline.c ---- */

/* Acquires the N x M frames of a set and folds them into seq->set (which is prepared); emits
 * progress per completed phase. The job of the frame that completes the set also finalizes it
 * into `planes` (*finalized then TRUE). FALSE with error when the set fails; every frame is
 * counted in c (the ones neither folded nor dropped are the caller's to count as aborted). */
gboolean ds_seq_acquire_phases (DsSequencer *seq, const DsCaptureSettings *s, guint64 tag, DsSetOrigin origin,
                                DsFrameCounters *c, DsSeparation *planes, gboolean *finalized,
                                GError **error);

/* ---- carry.c ---- */

/* Whether the set running may trigger the next set's first frame ahead: a continuous set
 * with nothing queued, whose next set chooses no operating point (that needs preview frames
 * first). The frame is verified in the next set, after this set's frames were confirmed as a
 * whole (ds_phase_check_confirm), like any first frame; a dark frame as any dark frame. */
gboolean ds_seq_carry_allowed (DsSequencer *seq, DsSetOrigin origin, const DsCaptureSettings *s);
/* After the set's last frame arrived (so its exposure is over): applies phase 0, or turns the
 * illuminator off when the next set takes a dark frame, and triggers. lit_since > 0: phase 0
 * was applied during that frame's transfer and stale buffers were flushed after its grab, at
 * lit_since (pipeline.c); it is not applied again. Failures are counted in the carry
 * and leave the next set to start as usual. */
void ds_seq_carry_trigger (DsSequencer *seq, const DsCaptureSettings *s, gint64 lit_since);
/* Grabs the frame triggered ahead, before the illuminator moves again for this set. */
void ds_seq_carry_grab (DsSequencer *seq);
/* Whether the set about to run with settings s can start from the carry. */
gboolean ds_seq_carry_fits (DsSequencer *seq, DsSetOrigin origin, const DsCaptureSettings *s);
/* The carry is not used: its frame (grabbed now if pending) is counted as aborted, and its
 * counters go to the totals; after a device failure that ends the set it belonged to, that
 * set is reported failed with it (tag 0: a continuous set). No-op without a carry. */
void ds_seq_carry_discard (DsSequencer *seq);

/* ---- verify.c ---- */

typedef struct {
  DsDropReason reason;     /* DS_DROP_N_REASONS: the frame may be folded */
  char *detail;            /* why, when dropped (owned) */
  gboolean reapply_phase;  /* the illuminator may show another phase: apply k again */
} DsFrameVerdict;

/* Verifies a frame lit (as far as the sequencer knows) with phase k, applied at applied_at_us,
 * in the order of docs/design.md: stale, frame gap, stripe phase. */
void ds_seq_verify_frame (DsSequencer *seq, const DsCaptureSettings *s, guint k,
                          const DsFrame *frame, gint64 applied_at_us, DsFrameVerdict *verdict);
void ds_frame_verdict_clear (DsFrameVerdict *verdict);

/* ---- retry.c ---- */

/* After `why` (a device failure, or a frame rejected by verification): FALSE with *error set to
 * why, prefixed "WHAT: " when the policy ends the acquisition at once (ds_seq_fatal_device_error)
 * and "WHAT: retries exhausted: " when *retries_left is 0; otherwise one retry is used
 * (*retries_left decremented, c->retries counted) and why cleared. WHAT is what_format. */
gboolean ds_seq_retry_or_fail (DsSequencer *seq, guint *retries_left, DsFrameCounters *c, GError **why,
                               GError **error, const char *what_format, ...) G_GNUC_PRINTF (6, 7);

/* ---- fold_worker.c ---- */

typedef struct {
  const DsCaptureSettings *settings; /* borrowed for the job */
  guint phase;
  DsFrame *frame;                    /* borrowed: the acquisition thread frees it after collect */
  gint64 applied_at_us;
  DsSeparation *finalize_into;       /* the set's last frame: once folded, the set is finalized
                                      * into these planes (borrowed) */
  DsFrameVerdict verdict;            /* out */
  gboolean folded;                   /* out: verified and folded */
  gboolean finalized;                /* out: ... and the set finalized into finalize_into */
  GError *fold_error;                /* out: verified, but the fold (or the finalize) failed */
  DsLastFrameTimes times;            /* out: when it was verified and folded */
} DsFoldJob;

DsFoldWorker *ds_fold_worker_new (DsSequencer *seq);
/* Waits for a job in progress, then stops and joins the thread. */
void ds_fold_worker_free (DsFoldWorker *worker);
/* Hands one frame over (never blocks); the previous job must have been collected. With `here`
 * the job runs on the calling thread before this returns (for a frame nothing will overlap
 * with); collect it all the same. */
void ds_fold_worker_submit (DsFoldWorker *worker, const DsCaptureSettings *s, guint phase,
                            DsFrame *frame, gint64 applied_at_us, DsSeparation *finalize_into,
                            gboolean here);
/* Waits for the submitted job and moves its outcome (verdict, fold error) to *job. */
void ds_fold_worker_collect (DsFoldWorker *worker, DsFoldJob *job);

/* ---- dark.c ---- */

/* Turns the illuminator off, within its settle timeout; counts a failure in c. */
gboolean ds_seq_illuminator_off (DsSequencer *seq, DsFrameCounters *c, GError **error);
/* Averages s->averages frames with the illuminator off into an image of the frames' type. The
 * first may be a frame triggered ahead by the previous set (seq->carry, dark), taken over. */
DsImage *ds_seq_acquire_dark (DsSequencer *seq, const DsCaptureSettings *s, DsFrameCounters *c,
                              double *mean_dn, GError **error);
/* Records a dark frame taken with settings s (mean of what is subtracted) for status: a set's
 * own (by_set), or the dark command's, which is also the stored one. Acquisition thread. */
void ds_seq_note_dark (DsSequencer *seq, const DsCaptureSettings *s, double mean_dn, gboolean by_set);
void ds_seq_run_dark (DsSequencer *seq, const DsCaptureSettings *s, guint64 tag);

/* ---- auto_point.c ---- */

/* Picks estimator, N, M and exposure for a target error or time budget from a dark and a
 * preview frame; rewrites *s. */
gboolean ds_seq_choose_operating_point (DsSequencer *seq, DsCaptureSettings *s, DsFrameCounters *c,
                                        GError **error);

G_END_DECLS
