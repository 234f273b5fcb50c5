/* The acquisition thread's own state (DsAcquisition) and the functions of the files that run
 * on it. Each file has one concern:
 *   sequencer.c    the thread's loop, its command queue and the public requests (main thread)
 *   report.c       events to the main context, status, accounting (sequencer_shared.h)
 *   device_ops.c   device operations with their counting (trigger, grab, flush, camera
 *                  settings, reconnect) and the retry/fail policy
 *   set_runner.c   one phase set from settings to result
 *   pipeline.c     the N x M frames of a set, pipelined: the next phase is applied during the
 *                  transfer of the previous phase's last frame, and the next frame exposed
 *                  while the worker verifies and folds the previous frame
 *   fold_worker.c  the verify-and-fold worker thread (fold_worker.h)
 *   carry.c        continuous mode: the next set's first frame, triggered while this set's
 *                  last frame is verified and its result finalized
 *   verify.c       frame verification (stale, frame gap, stripe phase)
 *   retry.c        the retry rule of every frame acquired (phase sets, dark, pilot)
 *   dark.c         dark-frame acquisition
 *   single_frame_set.c  a set of one frame separated alone (settings.single_frame)
 *   auto_point.c   the automatic operating point (preview frames)
 *   camera_live.c  the `set` command: exposure, gain and region on the open camera
 *   stream_stop.c  continuous mode that stops by itself when its sets keep failing
 *   window_stream.c continuous mode with per-frame results: a sliding window over the newest
 *                  frame of each phase, verified and broken like a set's frames
 *   preview.c      preview mode: free-running frames with a chosen light, no sets
 * Beside the thread, each with its own header: frame_counters.c (frame accounting),
 * result.c and result_planes.c (the published result and its planes), capture_settings.c,
 * devices.c and devices_common.c (the devices from the configuration), status_dark.c.
 *
 * Ownership: a DsAcquisition belongs to the acquisition thread alone; every function declared
 * here takes it and runs on that thread (unless it says otherwise). What the main thread reads
 * or writes is in acq->shared (DsSequencerShared), under its lock or atomic. During a fold job
 * the phase set, the phase check and the raw frames are lent to the fold worker (fold_worker.h)
 * and left alone until the job is collected. Once the thread joined, its DsAcquisition passes
 * to the thread that joined it (ds_sequencer_free). */
#pragma once
#include <glib.h>

#include "daemon/acquire/fold_worker.h"
#include "daemon/acquire/result_planes.h"
#include "daemon/acquire/sequencer.h"
#include "daemon/acquire/sequencer_shared.h"
#include "daemon/operating/operating_point.h"
#include "daemon/operating/rig_timing.h"
#include "daemon/output/raw_frames.h"
#include "proc/phase_check.h"
#include "proc/phase_window.h"
#include "proc/single_frame.h"

G_BEGIN_DECLS

/* How far the next set's first frame, triggered ahead, got. */
typedef enum {
  DS_CARRY_NONE = 0,   /* no carry */
  DS_CARRY_COUNTED,    /* nothing to grab: applying phase 0 (or off), the trigger or the grab
                        * failed; only its counters (and error) are left */
  DS_CARRY_TRIGGERED,  /* triggered, not grabbed yet */
  DS_CARRY_HELD,       /* grabbed: frame (this set's last frame was dropped meanwhile) */
} DsCarryStage;

/* Continuous mode: the first frame of the next set (phase 0, or its first dark frame when it
 * takes one), triggered as soon as this set's last frame arrived, so that its exposure and
 * transfer overlap with the last frame's verification and fold and with the finalize
 * (docs/design.md, "The pipeline"). Acquisition thread only. */
typedef struct {
  DsCarryStage stage;
  gboolean dark;              /* for the next set's dark frame: the illuminator was turned off,
                               * not moved to phase 0 */
  guint64 begun_before;       /* ds_seq_frames_begun before its trigger: the next set may light
                               * phase 1 during its transfer */
  DsFrame *frame;             /* DS_CARRY_HELD: the frame grabbed */
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
  DS_RUN_PREVIEW,          /* preview: free-running frames, no sets (preview.c) */
} DsRunMode;

typedef struct {
  DsRunMode mode;
  gint gen;                   /* cancel_gen stamped on the CMD_START: a cancel after it ends
                               * the stream's set in progress */
  DsCaptureSettings settings; /* the stream's next set (the defaults copied in before each set
                               * with DS_RUN_STREAM_DEFAULTS); unused with DS_RUN_ON_REQUEST */
  DsPreviewLight preview_light; /* DS_RUN_PREVIEW: the light, and the phase lit */
  guint preview_phase;
} DsRun;

/* Whom a set is for. A stream's set may trigger the next set's first frame ahead (carry.c)
 * and keeps its raw frames without reserving them first (set_runner.c). */
typedef enum {
  DS_SET_FOR_REQUEST = 0,  /* a capture: answered with its tag */
  DS_SET_FOR_STREAM,       /* continuous mode's (tag 0) */
} DsSetOrigin;


typedef struct {
  DsSequencerShared *shared;      /* what the main thread reads: status, defaults, queue */

  /* Devices. */
  DsDevicesOpenFunc open_devices; /* called on this thread, at start and on acquire */
  gpointer open_data;
  DsDevices *dev;                 /* NULL: released, or failed to open */
  gboolean need_reconnect;        /* a device is gone: reopened before the next command */
  gboolean camera_configured, camera_started;
  double camera_exposure_us, camera_gain_db;
  DsCameraChange live_camera;     /* what `set` commands changed (camera_live.c): kept over
                                   * reloads and reopenings */

  /* What the thread does between commands, and the frame triggered ahead for the next set. */
  DsRun run;
  gint work_gen;                  /* cancel_gen stamped on the work running (a capture's or dark
                                   * command's, the stream's): ds_seq_check_quit compares them */
  DsSeqCarry carry;

  /* The set in progress (lent to the fold worker during a job: fold_worker.h). */
  DsPhaseSet *set;
  DsSeparationParams set_params;
  guint set_width, set_height;
  DsPhaseCheck phase_check;
  double phase_check_period;      /* the period phase_check was set up for; NAN: none yet */
  DsFoldWorker *worker;           /* verifies and folds while the next frame is acquired */
  DsPlanePool *planes;            /* result planes, back from results nobody holds any more */
  /* The raw frames of the set in progress when it keeps them (save_phases): filled by the
   * fold jobs, attached to the result by the set runner. */
  DsRawFrames *raw;
  gboolean raw_incomplete;        /* a copy failed (a job's raw_copy_failed, or reserving):
                                   * the set's raw frames are not published */
  /* Per-frame results (window_stream.c): the sliding window, lent to the fold worker during a
   * job like the phase set, and the settings of the stream that filled it last. */
  DsPhaseWindow *window;
  DsSeparationParams window_params;
  guint window_width, window_height;
  gboolean window_ran;
  DsCaptureSettings window_settings;
  /* The single-frame plan (single_frame_set.c), kept while settings and frame size stay. */
  DsSingleFrame *single;
  DsSeparationParams single_params;
  guint single_width, single_height;
  gint64 last_frame_us;           /* arrival of the last folded frame */
  DsLastFrameTimes last_frame_times; /* ... and its job's stamps */
  guint64 next_set_id;

  /* Dark frames. */
  DsImage *dark;                  /* the dark command's, subtracted at its exposure and gain */
  double dark_exposure_us, dark_gain_db;
  GArray *dark_ids;               /* guint64 ids of the frames of the last dark acquired */
  GArray *stored_dark_ids;        /* ... of dark */

  /* The automatic operating point (ds_sequencer_set_operating_model; NULL: none). */
  const DsOperatingModel *model;
  DsRigTiming timing;
} DsAcquisition;

/* Whether the thread runs sets back to back. */
static inline gboolean
ds_acquisition_streaming (const DsAcquisition *acq)
{
  return acq->run.mode == DS_RUN_STREAM || acq->run.mode == DS_RUN_STREAM_DEFAULTS;
}

/* Whether the thread runs preview frames between commands. */
static inline gboolean
ds_acquisition_previewing (const DsAcquisition *acq)
{
  return acq->run.mode == DS_RUN_PREVIEW;
}

/* ---- report.c ---- */

/* Reads the devices' statistics, identity and illuminator status into the shared status. */
void ds_seq_refresh_device_status (DsAcquisition *acq);

/* The size of the frames the camera delivers: its ROI, or the whole sensor, with the camera's
 * info in *info (device_ops.c). */
void ds_seq_frame_size (DsAcquisition *acq, DsCameraInfo *info, guint *width, guint *height);

/* ---- device_ops.c ----
 * Each call blocks on its device within a bound it first declares to the watchdog
 * (ds_seq_blocking): the control bound, the settle timeout or the grab timeout. A failure is
 * FALSE (or NULL) with error set, counted in c where one is given; whether it ends the set is
 * ds_seq_fatal_device_error's to say. */

gboolean ds_seq_ensure_camera (DsAcquisition *acq, const DsCaptureSettings *s, GError **error);
gboolean ds_seq_apply_pattern (DsAcquisition *acq, const DsCaptureSettings *s, GError **error);
/* Lights phase k, within the illuminator's settle timeout. */
gboolean ds_seq_set_phase (DsAcquisition *acq, guint k, GError **error);
/* One frame: trigger and grab. Counts what happened. Returns NULL with error set. The two
 * halves apart, for a frame triggered ahead (carry.c). */
gboolean ds_seq_trigger (DsAcquisition *acq, DsFrameCounters *c, GError **error);
DsFrame *ds_seq_grab (DsAcquisition *acq, DsFrameCounters *c, GError **error);
/* The same within timeout_ms instead of the grab timeout. */
DsFrame *ds_seq_grab_within (DsAcquisition *acq, DsFrameCounters *c, guint timeout_ms, GError **error);
DsFrame *ds_seq_trigger_and_grab (DsAcquisition *acq, DsFrameCounters *c, GError **error);
/* Frames the camera has begun sending (camera ops->frames_begun), read before a trigger; 0
 * when the camera cannot tell or [camera] sends-after-exposure is false. */
guint64 ds_seq_frames_begun (DsAcquisition *acq);
/* After a trigger, with `before` read before it: waits (up to the grab timeout) until the
 * camera began sending a frame since, so that its exposure is over. FALSE when it cannot tell
 * (as ds_seq_frames_begun) or no frame began in time (lost or late: grab finds out). */
gboolean ds_seq_wait_exposure_over (DsAcquisition *acq, guint64 before);
/* Drops (and counts as stale) every frame already delivered but not grabbed. */
void ds_seq_flush_stale (DsAcquisition *acq, DsFrameCounters *c);
/* FALSE with CANCELLED when the daemon is stopping or the work running (acq->work_gen) was
 * cancelled (sequencer_shared.h, cancel_gen). Checked between frames: a cancel takes effect
 * within one frame plus the device calls' own bounds. */
gboolean ds_seq_check_quit (DsAcquisition *acq, GError **error);
/* TRUE when retrying cannot help (invalid, unsupported) or the device is gone (disconnected:
 * marks it for reconnection). */
gboolean ds_seq_fatal_device_error (DsAcquisition *acq, const GError *e);
/* Reopens lost devices with capped backoff until they work or the daemon stops. */
void ds_seq_reconnect (DsAcquisition *acq);
/* Applies the default settings (camera configured and started, pattern loaded) so that a
 * setting the devices refuse shows in status at once, not at the first capture; records the
 * outcome (status.settings_ok / settings_error) and reports a change as a device event. */
gboolean ds_seq_apply_defaults (DsAcquisition *acq);

/* ---- camera_live.c: blocks on the camera's configure (its control bound) ---- */

/* The `set` command between two sets: checks the change against the camera's ranges, stops the
 * camera, configures it and starts it again (a new region gets new buffers). FALSE with error
 * (DS_PROTOCOL_ERROR_BAD_ARGUMENT for a value the camera refuses, the camera's own error when it
 * is lost) and nothing changed; else the new values are the defaults of the sets that follow. */
gboolean ds_seq_camera_set (DsAcquisition *acq, const DsCameraChange *change, GError **error);
/* Puts what `set` changed back over the defaults and the devices' camera settings, after new
 * defaults (a reload) or devices opened again. */
void ds_seq_camera_live_overlay (DsAcquisition *acq);
/* The camera's settings as they stand, into status (camera_live). Devices open. */
void ds_seq_camera_live_report (DsAcquisition *acq);
/* The frames' region: x, y, width, height (the whole sensor when no region is set). */
void ds_seq_camera_region (DsAcquisition *acq, const DsCameraInfo *info, guint region[4]);

/* ---- stream_stop.c: CPU only ---- */

/* After a continuous set: when consecutive_failures reached the stream's max_failed_sets (0:
 * never), continuous mode stops, status says when and why (last_error, from the last set's
 * error) and a STREAM_STOPPED event tells the main thread. TRUE when it stopped. */
gboolean ds_seq_stream_gives_up (DsAcquisition *acq, guint consecutive_failures);

/* ---- set_runner.c ---- */

/* One phase set with `requested` (the stripe geometry taken from the illuminator), from the
 * camera settings to a RESULT event, or a FAILED event saying why; every frame is accounted
 * in the totals either way. Blocks for the whole set; fails only through the event. */
void ds_seq_run_set (DsAcquisition *acq, const DsCaptureSettings *requested, guint64 tag,
                     DsSetOrigin origin);

/* ---- window_stream.c: blocks for the stream's frames (device calls, waits for fold jobs) ---- */

/* Continuous mode with `requested->per_frame`: frames of phases 0, 1, ..., N-1, 0, ... back to
 * back, each verified like a set's (stale, frame gap, stripe phase) and pushed into the
 * sliding window, which publishes a RESULT (tag 0) for every good frame once it holds a
 * confirmed frame of every phase. A lost or refused frame, or settings other than the last
 * run's, break the window (a WINDOW_BROKEN event). Runs until a command is queued, the work is
 * cancelled or the daemon stops (the window's frames not yet in a result are aborted), or the
 * frames keep failing: a FAILED event then, counted as a failed set. */
void ds_seq_run_window_stream (DsAcquisition *acq, const DsCaptureSettings *requested);
/* ---- single_frame_set.c: blocks on the devices for the frame ---- */

/* A single-frame set (s->single_frame) once the camera, the pattern and the dark frame are
 * ready: phase 0 lit, one frame, separated from its own stripes into planes from acq->planes
 * (given back on failure). NULL with error when the set fails; the frame and its retries are
 * counted in c. *last_frame_us: the frame's arrival. No raw frames are kept (acq->raw cleared). */
DsSeparation *ds_seq_acquire_single_frame (DsAcquisition *acq, const DsCaptureSettings *s, const DsImage *dark,
                                           guint width, guint height, DsFrameCounters *c, gint64 *last_frame_us,
                                           GError **error);

/* ---- pipeline.c: blocks for the set's frames (device calls, and waits for fold jobs) ---- */

/* Acquires the N x M frames of a set and folds them into acq->set (which is prepared); emits
 * progress per completed phase. The job of the frame that completes the set also finalizes it
 * into `planes` (*finalized then TRUE). FALSE with error when the set fails; every frame is
 * counted in c (the ones neither folded nor dropped are the caller's to count as aborted). */
gboolean ds_seq_acquire_phases (DsAcquisition *acq, const DsCaptureSettings *s, guint64 tag, DsSetOrigin origin,
                                DsFrameCounters *c, DsSeparation *planes, gboolean *finalized,
                                GError **error);

/* ---- carry.c: blocks on the devices like device_ops.c; a failure stays in the carry ---- */

/* Whether the set running may trigger the next set's first frame ahead: a continuous set
 * with nothing queued, whose next set chooses no operating point (that needs preview frames
 * first). The frame is verified in the next set, after this set's frames were confirmed as a
 * whole (ds_phase_check_confirm), like any first frame; a dark frame as any dark frame. */
gboolean ds_seq_carry_allowed (DsAcquisition *acq, DsSetOrigin origin, const DsCaptureSettings *s);
/* After the set's last frame arrived (so its exposure is over): applies phase 0, or turns the
 * illuminator off when the next set takes a dark frame, and triggers. lit_since > 0: phase 0
 * was applied during that frame's transfer and stale buffers were flushed after its grab, at
 * lit_since (pipeline.c); it is not applied again. Failures are counted in the carry
 * and leave the next set to start as usual. */
void ds_seq_carry_trigger (DsAcquisition *acq, const DsCaptureSettings *s, gint64 lit_since);
/* Grabs the frame triggered ahead, before the illuminator moves again for this set. */
void ds_seq_carry_grab (DsAcquisition *acq);
/* Whether the set about to run with settings s can start from the carry. */
gboolean ds_seq_carry_fits (DsAcquisition *acq, DsSetOrigin origin, const DsCaptureSettings *s);
/* The carry is not used: its frame (grabbed now if only triggered) is counted as aborted, and its
 * counters go to the totals; after a device failure that ends the set it belonged to, that
 * set is reported failed with it (tag 0: a continuous set). No-op without a carry. */
void ds_seq_carry_discard (DsAcquisition *acq);

/* ---- retry.c: CPU only ---- */

/* After `why` (a device failure, or a frame rejected by verification): FALSE with *error set to
 * why, prefixed "WHAT: " when the policy ends the acquisition at once (ds_seq_fatal_device_error)
 * and "WHAT: retries exhausted: " when *retries_left is 0; otherwise one retry is used
 * (*retries_left decremented, c->retries counted) and why cleared. WHAT is what_format. */
gboolean ds_seq_retry_or_fail (DsAcquisition *acq, guint *retries_left, DsFrameCounters *c, GError **why,
                               GError **error, const char *what_format, ...) G_GNUC_PRINTF (6, 7);

/* ---- dark.c: blocks on the devices for the dark frame's frames ---- */

/* Turns the illuminator off, within its settle timeout; counts a failure in c. */
gboolean ds_seq_illuminator_off (DsAcquisition *acq, DsFrameCounters *c, GError **error);
/* Averages s->averages frames with the illuminator off into an image of the frames' type. The
 * first may be a frame triggered ahead by the previous set (acq->carry, dark), taken over. */
DsImage *ds_seq_acquire_dark (DsAcquisition *acq, const DsCaptureSettings *s, DsFrameCounters *c,
                              double *mean_dn, GError **error);
/* Records a dark frame taken with settings s (mean of what is subtracted) for status: a set's
 * own (by_set), or the dark command's, which is also the stored one. Acquisition thread. */
void ds_seq_note_dark (DsAcquisition *acq, const DsCaptureSettings *s, double mean_dn, gboolean by_set);
/* The dark frame a set or a per-frame run with settings s subtracts: with s->dark_frame its own,
 * taken now (*own, the caller's to free); otherwise the stored one when it was taken at s's
 * exposure and gain; otherwise none (*use NULL). FALSE with error when taking it failed. */
gboolean ds_seq_dark_for (DsAcquisition *acq, const DsCaptureSettings *s, DsFrameCounters *c, DsImage **own,
                          const DsImage **use, GError **error);
/* The dark command: a dark frame with settings s, stored for later sets; answered by a DARK
 * event (with the error when it failed). */
void ds_seq_run_dark (DsAcquisition *acq, const DsCaptureSettings *s, guint64 tag);

/* ---- preview.c: blocks on the devices, one frame at a time ---- */

/* The preview command: on lights (light, phase) and enters DS_RUN_PREVIEW, or fails with the
 * devices' reason (preview off then); off leaves it with the illuminator dark. Answered by a
 * CONTROL event with tag. */
void ds_seq_preview_command (DsAcquisition *acq, gboolean on, DsPreviewLight light, guint phase, guint64 tag);
/* Preview frames until a command is queued, the work is cancelled or the daemon stops: reacts
 * within one frame (plus the device calls' own bounds). Lights again on entry (a command
 * between two calls may have moved the illuminator). A device failure that retrying cannot
 * mend ends preview (a device event says why). */
void ds_seq_run_preview (DsAcquisition *acq);
/* Leaves preview (no device call) and says why in a device event; no-op when not in it. */
void ds_seq_preview_end (DsAcquisition *acq, const char *why);

/* ---- auto_point.c ---- */

/* Picks estimator, N, M and exposure for a target error or time budget from a dark and a
 * preview frame; rewrites *s. Blocks on the devices for the pilot frames (counted in c as
 * previews); FALSE with error when there is no operating model, the pilot fails or no point
 * meets the target. */
gboolean ds_seq_choose_operating_point (DsAcquisition *acq, DsCaptureSettings *s, DsFrameCounters *c,
                                        GError **error);

G_END_DECLS
