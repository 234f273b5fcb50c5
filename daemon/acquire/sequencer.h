/* The sequencer: the acquisition thread that owns the devices and turns commands into phase
 * sets (design.md, "Sequencer contract").
 *
 * Threads: ds_sequencer_new/free and every request function are called from the main thread;
 * requests are queued (GAsyncQueue) and never block. The thread reports back through
 * DsSequencerEventFunc, always invoked in the GMainContext given to ds_sequencer_new. The
 * thread is the only one that touches a driver. */
#pragma once
#include <glib.h>

#include "daemon/acquire/camera_live.h"
#include "daemon/acquire/capture_settings.h"
#include "daemon/acquire/devices.h"
#include "daemon/acquire/result.h"

G_BEGIN_DECLS

/* Failures that are the sequencer's own, not a device's: on the wire `failed` for a rejected
 * frame, `device_error` when the devices are not usable (daemon/service/wire_error.c). */
#define DS_SEQUENCER_ERROR (ds_sequencer_error_quark ())
GQuark ds_sequencer_error_quark (void);

typedef enum {
  DS_SEQUENCER_ERROR_FRAME_REJECTED = 1, /* frames kept failing verification (stale, frame gap,
                                          * wrong phase, stripes in a dark frame, size change) */
  DS_SEQUENCER_ERROR_NOT_READY = 2,      /* devices not open, or they refuse the configured settings */
} DsSequencerError;

typedef enum {
  DS_SEQUENCER_EVENT_READY = 0,   /* devices open (error set if opening failed: the thread ends) */
  DS_SEQUENCER_EVENT_RESULT,      /* a set finished: result set; tag of the capture or 0 */
  DS_SEQUENCER_EVENT_FAILED,      /* a set failed: error says why; tag of the capture or 0 */
  DS_SEQUENCER_EVENT_PROGRESS,    /* phase (0-based) of n_phases done for tag (a capture's:
                                   * continuous sets, tag 0, report none) */
  DS_SEQUENCER_EVENT_DARK,        /* dark frame calibrated (dark_mean_dn) or error */
  DS_SEQUENCER_EVENT_DEVICE,      /* a device state change worth logging: message */
  DS_SEQUENCER_EVENT_CONTROL,     /* devices released or acquired for `tag` (error set if not) */
  DS_SEQUENCER_EVENT_STREAM_STOPPED, /* continuous mode stopped by itself: message says when and
                                      * why (its sets kept failing) */
  DS_SEQUENCER_EVENT_WINDOW_BROKEN,  /* per-frame results: the sliding window was broken;
                                      * message is "REASON: detail" (window_stream.c) */
} DsSequencerEventKind;

typedef struct {
  DsSequencerEventKind kind;
  guint64 tag;
  DsResult *result;   /* borrowed for the callback; ref it to keep it */
  const GError *error;
  guint phase, n_phases;
  double dark_mean_dn;
  const char *message;
} DsSequencerEvent;

typedef void (*DsSequencerEventFunc) (const DsSequencerEvent *event, gpointer user_data);

/* Opens the devices itself (on the new thread) through `open_devices`, so that a slow device
 * never blocks the main loop. */
typedef DsDevices *(*DsDevicesOpenFunc) (gpointer data, GError **error);

typedef struct DsSequencer DsSequencer;

DsSequencer *ds_sequencer_new (DsDevicesOpenFunc open_devices, gpointer open_data,
                               const DsCaptureSettings *defaults, GMainContext *context,
                               DsSequencerEventFunc on_event, gpointer user_data);
/* Stops the thread (an ongoing set is abandoned between two frames, at most one grab
 * timeout later), closes the devices and joins. No event is delivered after this returns. */
void ds_sequencer_free (DsSequencer *seq);
G_DEFINE_AUTOPTR_CLEANUP_FUNC (DsSequencer, ds_sequencer_free)

/* One set with these settings; answered by a RESULT or FAILED event with `tag`. Returns FALSE
 * (busy) when max_pending captures are already queued. */
gboolean ds_sequencer_capture (DsSequencer *seq, const DsCaptureSettings *settings, guint64 tag);
/* Releases the devices so that another program can take the camera (arv-viewer, arv-tool):
 * continuous acquisition stops, the camera and illuminator are closed (the GigE Vision control
 * privilege with them); captures fail with NOT_READY until ds_sequencer_acquire reopens them.
 * Answered by a CONTROL event with `tag`. FALSE (busy) like ds_sequencer_capture. */
gboolean ds_sequencer_release (DsSequencer *seq, guint64 tag);
gboolean ds_sequencer_acquire (DsSequencer *seq, guint64 tag);
/* Cancels all the work queued before it, whoever asked for it: the set running (a capture's,
 * a calibrate's, the stream's) ends between two frames with DS_PROTOCOL_ERROR_CANCELLED (a
 * FAILED event; a dark frame's DARK event), its frames counted as aborted and the set as
 * cancelled, nothing published; captures and darks queued before it are answered the same way
 * without a frame; continuous mode stops (a start queued before it does not start). Releases,
 * acquires and defaults queued before it still run. Never blocks; answered by a CONTROL event
 * with `tag` once every command queued before it was answered, so that after it the thread is
 * idle unless something was queued since. Not counted against max_pending. Main thread. */
void ds_sequencer_cancel (DsSequencer *seq, guint64 tag);
/* Continuous mode: sets back to back with these settings until stopped (tag 0 events); with
 * settings NULL, each set takes the defaults as they are when it starts (ds_sequencer_set_defaults
 * changes the stream). */
void ds_sequencer_start (DsSequencer *seq, const DsCaptureSettings *settings);
void ds_sequencer_stop (DsSequencer *seq);
/* Measures the dark frame (illuminator off, `averages` frames) used by later sets. */
gboolean ds_sequencer_dark (DsSequencer *seq, const DsCaptureSettings *settings, guint64 tag);
/* The model for captures with a target error or time budget (daemon/operating/operating_point.h).
 * Borrowed: must outlive the sequencer. Queued like a capture (never blocks): the captures
 * requested after it use it. Main thread. */
struct DsOperatingModel;
void ds_sequencer_set_operating_model (DsSequencer *seq, const struct DsOperatingModel *model,
                                       double settle_ms, double link_mbit);
/* Called for every frame that was verified and folded (phase of the set taken with settings), on
 * the fold worker thread while the next frame is acquired (the last frame of a set: on the
 * acquisition thread, in the time between that frame and the result), and for every preview
 * frame on the acquisition thread (phase: the phase lit, else 0), before the frame is released
 * (its pixels may be the camera's buffer): copy what is needed, quickly, and keep no pointer.
 * For the live view (daemon/service/live_view.h). Main thread; NULL removes it. */
typedef void (*DsSequencerFrameFunc) (const DsFrame *frame, guint phase, const DsCaptureSettings *settings,
                                      gpointer user_data);
void ds_sequencer_set_frame_hook (DsSequencer *seq, DsSequencerFrameFunc func, gpointer user_data);
/* The `set` command (camera_live.h): exposure, gain and region applied to the open camera
 * between two sets, then the defaults of the sets that follow (a running stream's next set
 * included). Answered by a CONTROL event with `tag`: its error (bad_argument on the wire for a
 * value out of the camera's range, naming it and the range), or status.camera_live as applied.
 * FALSE (busy) like ds_sequencer_capture. Main thread. */
gboolean ds_sequencer_set_camera (DsSequencer *seq, const DsCameraChange *change, guint64 tag);
/* Preview (docs/protocol.md, `preview`): free-running frames for aligning and focusing, one
 * after the other at the camera's rate, with the illuminator all on, off, or showing one phase;
 * no phase set, no verification, nothing folded or published; each frame goes to the frame
 * hook (phase: the phase lit, else 0) and the preview hook, and counts as dropped `preview`.
 * The camera takes the defaults as they are at each frame (a reload or a live setting shows
 * at the next frame). It runs until preview off, stop, cancel, release, or a capture, dark or
 * start, which end it first (the command then runs; preview does not resume). Answered by a
 * CONTROL event with `tag` once the thread took it: for on, once the light is applied (error
 * set when the devices are released or refuse the light; preview is then off). Counted like a
 * capture (FALSE: busy). Main thread. */
typedef enum {
  DS_PREVIEW_LIGHT_ALL = 0, /* every stripe lit (ds_illuminator_all_on) */
  DS_PREVIEW_LIGHT_OFF,     /* illuminator dark */
  DS_PREVIEW_LIGHT_PHASE,   /* phase k of the configured phases */
  DS_PREVIEW_LIGHT_N
} DsPreviewLight;
/* The wire names: "all", "off", "phase"; "unknown" out of range. Any thread. */
const char *ds_preview_light_name (DsPreviewLight light);
gboolean ds_sequencer_preview (DsSequencer *seq, gboolean on, DsPreviewLight light, guint phase, guint64 tag);
/* Called for every preview frame on the acquisition thread, after the frame hook, before the
 * frame is released: copy what is needed, quickly. For the socket's `frame` events. Main thread;
 * NULL removes it. */
typedef void (*DsSequencerPreviewFunc) (const DsFrame *frame, DsPreviewLight light, guint phase, guint n_phases,
                                        gpointer user_data);
void ds_sequencer_set_preview_hook (DsSequencer *seq, DsSequencerPreviewFunc func, gpointer user_data);
/* New defaults (SIGHUP); continuous mode picks them up at its next set. */
void ds_sequencer_set_defaults (DsSequencer *seq, const DsCaptureSettings *defaults);

typedef struct {
  double total_ms;
  guint64 count;
} DsStageTime;

typedef enum {
  DS_STAGE_SET_PHASE = 0,
  DS_STAGE_TRIGGER,
  /* After a trigger, until the camera began sending the frame (its exposure over), when the
   * next phase is applied during the transfer: the camera's time, as much as the grab's. */
  DS_STAGE_EXPOSE,
  DS_STAGE_GRAB,
  DS_STAGE_VERIFY,
  DS_STAGE_FOLD,
  DS_STAGE_FINALIZE,
  DS_STAGE_SET,
  DS_STAGE_N
} DsStage;

const char *ds_stage_name (DsStage stage);

/* What the acquisition thread is doing, as status reports it. The names are the wire's
 * (docs/protocol.md, status `state`): ds_sequencer_state_name gives them. */
typedef enum {
  DS_SEQUENCER_STATE_OPENING = 0, /* opening the devices */
  DS_SEQUENCER_STATE_IDLE,        /* devices open, nothing to do */
  DS_SEQUENCER_STATE_ACQUIRING,   /* a capture or a dark frame */
  DS_SEQUENCER_STATE_CONTINUOUS,  /* continuous mode: sets back to back */
  DS_SEQUENCER_STATE_RECONNECTING,/* a device was lost: reopening it */
  DS_SEQUENCER_STATE_RELEASED,    /* devices released for another program */
  DS_SEQUENCER_STATE_FAILED,      /* the devices failed to open: the thread waits for quit */
  DS_SEQUENCER_STATE_CANCELLING,  /* a cancel is queued: the thread has not taken it yet (the
                                   * set running stops at its next frame) */
  DS_SEQUENCER_STATE_PREVIEW,     /* preview: free-running frames, no sets (ds_sequencer_preview) */
  DS_SEQUENCER_STATE_N
} DsSequencerState;

/* The state's wire name ("opening", "idle", ...); "unknown" out of range. Any thread. */
const char *ds_sequencer_state_name (DsSequencerState state);

/* A dark frame as status reports it: what was measured, when, and by whom. */
typedef struct {
  gboolean taken;               /* FALSE: none yet */
  gboolean by_set;              /* a set's own dark frame (dark_frame); else the dark command's */
  gint64 taken_unix_us;         /* g_get_real_time () when its last frame was averaged in */
  double mean_dn;               /* the mean of the dark frame subtracted, in DN */
  guint frames;                 /* frames averaged into it */
  double exposure_us, gain_db;
} DsDarkFrameInfo;

/* Preview as status reports it (meaningful while `on`; the last values stay after). */
typedef struct {
  gboolean on;
  DsPreviewLight light;
  guint phase, n_phases;        /* the phase lit (light phase) of n_phases */
  guint64 frames;               /* frames since preview began */
  double fps;                   /* frames per second, over the last second or so */
} DsPreviewStatus;

typedef struct {
  DsSequencerState state;
  gboolean continuous;
  DsPreviewStatus preview;
  gboolean has_dark;            /* a stored dark frame (the dark command's): stored_dark.taken */
  /* Whether the next set takes its own dark frame: the running stream's settings in continuous
   * mode, else the configured default (a capture may ask otherwise). */
  gboolean per_set_dark;
  DsDarkFrameInfo last_dark;    /* the last dark frame taken, by a set or the dark command */
  DsDarkFrameInfo stored_dark;  /* the dark command's, subtracted from sets without their own at
                                 * its exposure and gain */
  gboolean stored_dark_applies; /* ... and it is taken at the next set's exposure and gain */
  guint pending;
  guint64 sets_done, sets_failed;
  guint64 sets_cancelled;       /* sets and dark frames ended by a cancel or the daemon stopping */
  guint64 frame_results;        /* per-frame results published (continuous `results = per-frame`) */
  guint64 window_breaks;        /* ... sliding windows broken (lost, refused frame, new settings) */
  char last_window_break[48];   /* the last break's reason ("" none) */
  DsFrameCounters frames;
  DsStageTime stages[DS_STAGE_N];
  DsCameraStats camera_stats;
  DsCameraInfo camera_info;
  DsIlluminatorStatus illuminator;
  char devices[128];
  char last_error[512];
  double phase_offset_cycles;   /* learned stripe-phase offset of phase 0; NAN until learned */
  gint64 heartbeat_us;          /* the thread's last sign of life (g_get_monotonic_time) */
  gint64 blocking_until_us;     /* inside a device call that may block until then (its own
                                 * bound: grab timeout, settle timeout...); 0 between calls */
  /* The configured settings as the devices took them when they opened, reconnected or the
   * configuration was reloaded: FALSE with the devices' reason (naming the setting and what
   * the device allows) when they refused one. */
  gboolean settings_ok;
  char settings_error[256];
  /* The camera's exposure, gain and region as the next set without its own takes them (the
   * configuration's, or a `set`'s): FALSE until the devices first opened. */
  gboolean camera_live_known;
  DsCameraLive camera_live;
} DsSequencerStatus;

void ds_sequencer_get_status (DsSequencer *seq, DsSequencerStatus *status);

G_END_DECLS
