/* The acquisition thread and its command queue: requests from the main thread are queued,
 * the thread runs them one at a time (or sets back to back in continuous mode) and reports
 * through events. What a set does is in set_runner.c; the file map is in acquisition.h.
 *
 * Ownership: DsSequencer holds the shared part (DsSequencerShared: queue, status, defaults
 * under its lock, atomics) and the acquisition thread's own (DsAcquisition). The public
 * functions run on the main thread and touch only the shared part; thread_main and everything
 * it calls get the DsAcquisition, which the main thread touches again only after the join. */
#include <math.h>

#include "daemon/protocol/protocol.h"
#include "daemon/acquire/acquisition.h"

typedef enum {
  CMD_CAPTURE,
  CMD_DARK,
  CMD_START,
  CMD_STOP,
  CMD_DEFAULTS,
  CMD_RELEASE,
  CMD_ACQUIRE,
  CMD_OPERATING_MODEL,
  CMD_CANCEL,
  CMD_SET_CAMERA,
  CMD_QUIT,
  CMD_PREVIEW,
} CommandKind;

typedef struct {
  CommandKind kind;
  DsCaptureSettings settings;  /* CMD_CAPTURE, CMD_DARK, CMD_DEFAULTS; CMD_START unless
                                * follow_defaults */
  gboolean follow_defaults;    /* CMD_START without settings: each set takes the defaults as
                                * they are when it starts (a reload changes the stream) */
  guint64 tag;                 /* the request's, echoed in its events; 0 for none */
  gint gen;                    /* shared.cancel_gen when queued (CMD_CANCEL: the value it
                                * publishes): a later cancel cancels the command */
  const DsOperatingModel *model; /* CMD_OPERATING_MODEL, with the rig's timing */
  DsRigTiming timing;
  DsCameraChange camera;       /* CMD_SET_CAMERA */
  gboolean preview_on;         /* CMD_PREVIEW: on or off, the light and the phase lit */
  DsPreviewLight preview_light;
  guint preview_phase;
} Command;

struct DsSequencer {
  DsSequencerShared shared;    /* main thread and acquisition thread (sequencer_shared.h) */
  DsAcquisition acq;           /* the acquisition thread's; the main thread's after the join */
  GThread *thread;
};

#define MAX_PENDING 8

const char *
ds_sequencer_state_name (DsSequencerState state)
{
  static const char *const names[DS_SEQUENCER_STATE_N] = {
    [DS_SEQUENCER_STATE_OPENING] = "opening",
    [DS_SEQUENCER_STATE_IDLE] = "idle",
    [DS_SEQUENCER_STATE_ACQUIRING] = "acquiring",
    [DS_SEQUENCER_STATE_CONTINUOUS] = "continuous",
    [DS_SEQUENCER_STATE_RECONNECTING] = "reconnecting",
    [DS_SEQUENCER_STATE_RELEASED] = "released",
    [DS_SEQUENCER_STATE_FAILED] = "failed",
    [DS_SEQUENCER_STATE_CANCELLING] = "cancelling",
    [DS_SEQUENCER_STATE_PREVIEW] = "preview",
  };
  return (guint) state < DS_SEQUENCER_STATE_N ? names[state] : "unknown";
}

const char *
ds_stage_name (DsStage stage)
{
  static const char *const names[DS_STAGE_N] = { "set_phase", "trigger", "expose", "grab",
                                                 "verify", "fold", "finalize", "set" };
  return (guint) stage < DS_STAGE_N ? names[stage] : "unknown";
}

G_DEFINE_QUARK (ds-sequencer-error-quark, ds_sequencer_error)

/* Closes the devices (another program may then open the camera); the thread keeps running and
 * answers captures with NOT_READY until they are acquired again. Blocks on the devices' stop
 * and off (their own bounds); never fails. */
static void
release_devices (DsAcquisition *acq, guint64 tag)
{
  if (acq->dev) {
    acq->run.mode = DS_RUN_ON_REQUEST;
    if (acq->camera_started)
      acq->dev->camera->ops->stop (acq->dev->camera->backend);
    g_autoptr (GError) off_error = NULL;
    acq->dev->illuminator->ops->off (acq->dev->illuminator->backend, acq->dev->settle_timeout_ms, &off_error);
    g_clear_pointer (&acq->dev, ds_devices_close);
    acq->camera_started = acq->camera_configured = FALSE;
    acq->need_reconnect = FALSE;
    g_mutex_lock (&acq->shared->lock);
    g_strlcpy (acq->shared->status.devices, "released", sizeof acq->shared->status.devices);
    acq->shared->status.camera_info.connected = FALSE;
    acq->shared->status.illuminator.ready = FALSE;
    acq->shared->status.continuous = FALSE;
    g_mutex_unlock (&acq->shared->lock);
  }
  ds_seq_set_state (acq->shared, DS_SEQUENCER_STATE_RELEASED);
  ds_seq_emit (acq->shared, DS_SEQUENCER_EVENT_CONTROL, tag, NULL, NULL,
               "devices released: another program may open the camera");
}

/* What the next set does about the dark (status "dark"): the running stream's settings in
 * continuous mode, else the defaults. Under acq->shared->lock; any thread that may read acq
 * (the acquisition thread, or the main thread before it starts). */
static void
update_dark_mode (DsAcquisition *acq)
{
  DsSequencerStatus *st = &acq->shared->status;
  const DsCaptureSettings *next = acq->run.mode == DS_RUN_STREAM ? &acq->run.settings : &acq->shared->defaults;
  const DsDarkFrameInfo *stored = &st->stored_dark;
  st->per_set_dark = next->dark_frame;
  st->stored_dark_applies = stored->taken && stored->exposure_us == next->exposure_us &&
                            stored->gain_db == next->gain_db;
}

/* Opens the devices through open_devices (blocks while they open) and reports them in status.
 * FALSE with error set when they do not open. */
static gboolean
open_and_report_devices (DsAcquisition *acq, GError **error)
{
  acq->dev = acq->open_devices (acq->open_data, error);
  if (!acq->dev)
    return FALSE;
  g_mutex_lock (&acq->shared->lock);
  g_strlcpy (acq->shared->status.devices, acq->dev->description, sizeof acq->shared->status.devices);
  g_mutex_unlock (&acq->shared->lock);
  ds_seq_refresh_device_status (acq);
  return TRUE;
}

static void
acquire_devices (DsAcquisition *acq, guint64 tag)
{
  if (acq->dev) {
    ds_seq_emit (acq->shared, DS_SEQUENCER_EVENT_CONTROL, tag, NULL, NULL, "devices already open");
    return;
  }
  ds_seq_set_state (acq->shared, DS_SEQUENCER_STATE_OPENING);
  GError *error = NULL;
  if (!open_and_report_devices (acq, &error)) {
    ds_seq_record_error (acq->shared, error);
    ds_seq_set_state (acq->shared, DS_SEQUENCER_STATE_RELEASED);
    g_prefix_error (&error, "acquire: ");
    ds_seq_emit (acq->shared, DS_SEQUENCER_EVENT_CONTROL, tag, NULL, error, NULL);
    return;
  }
  /* Devices opened again must take the settings again, as at start and after a reconnect. */
  ds_seq_apply_defaults (acq);
  ds_seq_set_state (acq->shared, DS_SEQUENCER_STATE_IDLE);
  ds_seq_emit (acq->shared, DS_SEQUENCER_EVENT_CONTROL, tag, NULL, NULL, acq->dev->description);
}

/* A capture or dark frame while the devices are released. */
static void
refuse_released (DsAcquisition *acq, const Command *cmd)
{
  ds_seq_emit (acq->shared, cmd->kind == CMD_DARK ? DS_SEQUENCER_EVENT_DARK : DS_SEQUENCER_EVENT_FAILED, cmd->tag,
               NULL,
               g_error_new (DS_SEQUENCER_ERROR, DS_SEQUENCER_ERROR_NOT_READY,
                            "the devices are released (another program may hold the camera): send acquire first"),
               NULL);
}

/* Whether a cancel was queued after cmd: then it is answered cancelled instead of run. */
static gboolean
command_cancelled (DsAcquisition *acq, const Command *cmd)
{
  return cmd->gen != g_atomic_int_get (&acq->shared->cancel_gen);
}

/* A capture or dark frame cancelled before its first frame: answered as a set cancelled between
 * frames would be (no frame to count), so the requester cannot tell the two apart. */
static void
refuse_cancelled (DsAcquisition *acq, const Command *cmd)
{
  g_mutex_lock (&acq->shared->lock);
  acq->shared->status.sets_cancelled++;
  g_mutex_unlock (&acq->shared->lock);
  ds_seq_emit (acq->shared, cmd->kind == CMD_DARK ? DS_SEQUENCER_EVENT_DARK : DS_SEQUENCER_EVENT_FAILED, cmd->tag,
               NULL, g_error_new (DS_PROTOCOL_ERROR, DS_PROTOCOL_ERROR_CANCELLED, "cancelled by a cancel request"),
               NULL);
}

/* CMD_CANCEL taken: every command queued before it was answered (FIFO), the set it cancelled
 * ended; continuous mode stops with its frame triggered ahead. The cancel is acknowledged
 * (status leaves `cancelling`) and answered. */
static void
finish_cancel (DsAcquisition *acq, const Command *cmd)
{
  gboolean was_streaming = ds_acquisition_streaming (acq);
  ds_seq_preview_end (acq, "preview stopped: cancelled");
  acq->run.mode = DS_RUN_ON_REQUEST;
  ds_seq_carry_discard (acq);
  g_mutex_lock (&acq->shared->lock);
  acq->shared->status.continuous = FALSE;
  g_mutex_unlock (&acq->shared->lock);
  /* The state before the answer, so that a status read after it shows the thread idle. Without
   * devices (released, failed to open) the state stays. */
  if (acq->dev)
    ds_seq_set_state (acq->shared, acq->need_reconnect ? DS_SEQUENCER_STATE_RECONNECTING : DS_SEQUENCER_STATE_IDLE);
  g_atomic_int_set (&acq->shared->cancel_acked, cmd->gen);
  ds_seq_emit (acq->shared, DS_SEQUENCER_EVENT_CONTROL, cmd->tag, NULL, NULL,
               was_streaming ? "cancelled: continuous acquisition stopped" : "cancelled");
}

/* The devices failed to open: nothing to drive. Captures and darks are refused, until the
 * quit command comes, so that status stays answerable. Blocks on the queue (1 s slices). */
static void
run_without_devices (DsAcquisition *acq)
{
  for (;;) {
    Command *cmd = g_async_queue_timeout_pop (acq->shared->queue, G_USEC_PER_SEC);
    ds_seq_heartbeat (acq->shared);
    gboolean quit = cmd && cmd->kind == CMD_QUIT;
    if (cmd && cmd->kind == CMD_CANCEL)
      finish_cancel (acq, cmd);
    /* Every counted command is answered and uncounted here as in run_command: a request left
     * unanswered would hang its client, and its place in MAX_PENDING would never come back. */
    if (cmd && (cmd->kind == CMD_CAPTURE || cmd->kind == CMD_DARK || cmd->kind == CMD_RELEASE ||
                cmd->kind == CMD_ACQUIRE || cmd->kind == CMD_SET_CAMERA || cmd->kind == CMD_PREVIEW)) {
      g_atomic_int_dec_and_test (&acq->shared->pending);
      g_mutex_lock (&acq->shared->lock);
      g_autofree char *why = g_strdup (acq->shared->status.last_error);
      g_mutex_unlock (&acq->shared->lock);
      DsSequencerEventKind kind = cmd->kind == CMD_DARK      ? DS_SEQUENCER_EVENT_DARK
                                  : cmd->kind == CMD_CAPTURE ? DS_SEQUENCER_EVENT_FAILED
                                                             : DS_SEQUENCER_EVENT_CONTROL;
      ds_seq_emit (acq->shared, kind, cmd->tag, NULL,
                   g_error_new (DS_SEQUENCER_ERROR, DS_SEQUENCER_ERROR_NOT_READY, "devices are not open: %s", why),
                   NULL);
    }
    g_free (cmd);
    if (quit)
      return;
  }
}

/* One set of the stream, then a pause when the sets keep failing. *consecutive_failures
 * counts the stream's failed sets in a row. Blocks for the set and the pause; commands and
 * quit cut the pause short. */
static void
run_stream_set (DsAcquisition *acq, guint *consecutive_failures)
{
  if (acq->run.mode == DS_RUN_STREAM_DEFAULTS) {
    g_mutex_lock (&acq->shared->lock);
    acq->run.settings = acq->shared->defaults;
    g_mutex_unlock (&acq->shared->lock);
  }
  ds_seq_set_state (acq->shared, DS_SEQUENCER_STATE_CONTINUOUS);
  g_mutex_lock (&acq->shared->lock);
  guint64 failed_before = acq->shared->status.sets_failed;
  g_mutex_unlock (&acq->shared->lock);
  acq->work_gen = acq->run.gen;
  if (acq->run.settings.per_frame)
    ds_seq_run_window_stream (acq, &acq->run.settings);
  else
    ds_seq_run_set (acq, &acq->run.settings, 0, DS_SET_FOR_STREAM);
  g_mutex_lock (&acq->shared->lock);
  gboolean failed = acq->shared->status.sets_failed != failed_before;
  g_mutex_unlock (&acq->shared->lock);
  /* Sets that keep failing (a setting the camera refuses fails at once) are spaced out,
   * 0.1 s doubling to 2 s, instead of spinning: commands and quit still cut the wait. */
  *consecutive_failures = failed ? *consecutive_failures + 1 : 0;
  if (ds_seq_stream_gives_up (acq, *consecutive_failures)) {
    *consecutive_failures = 0;
    return;
  }
  guint n = *consecutive_failures;
  guint wait_ms = n ? MIN (100u << MIN (n - 1, 5u), 2000u) : 0;
  for (guint waited = 0; waited < wait_ms && !g_atomic_int_get (&acq->shared->quit) &&
                         g_async_queue_length (acq->shared->queue) <= 0; waited += 20) {
    ds_seq_heartbeat (acq->shared);
    g_usleep (20 * 1000);
  }
}

/* Runs one command (not CMD_QUIT) and updates the status it may change. Blocks for as long as
 * the command takes (a capture: its set). */
static void
run_command (DsAcquisition *acq, const Command *cmd)
{
  CommandKind kind = cmd->kind;
  if ((kind == CMD_CAPTURE || kind == CMD_DARK) && command_cancelled (acq, cmd)) {
    refuse_cancelled (acq, cmd);
    g_atomic_int_add (&acq->shared->pending, -1);
    return;
  }
  /* A start queued before a cancel: the cancel stops continuous mode, so it never starts. */
  if (kind == CMD_START && command_cancelled (acq, cmd))
    return;
  /* Nor does a preview; its requester hears why. */
  if (kind == CMD_PREVIEW && cmd->preview_on && command_cancelled (acq, cmd)) {
    ds_seq_emit (acq->shared, DS_SEQUENCER_EVENT_CONTROL, cmd->tag, NULL,
                 g_error_new (DS_PROTOCOL_ERROR, DS_PROTOCOL_ERROR_CANCELLED, "preview: cancelled by a cancel request"),
                 NULL);
    g_atomic_int_add (&acq->shared->pending, -1);
    return;
  }
  acq->work_gen = cmd->gen;
  /* Preview gives the camera up to the work asked for (docs/protocol.md, `preview`). */
  if (kind == CMD_CAPTURE || kind == CMD_DARK || kind == CMD_START || kind == CMD_STOP || kind == CMD_RELEASE)
    ds_seq_preview_end (acq, kind == CMD_STOP || kind == CMD_RELEASE ? "preview stopped"
                                                                     : "preview stopped: a set takes the camera");
  if (!acq->dev && (kind == CMD_CAPTURE || kind == CMD_DARK)) {
    refuse_released (acq, cmd);
    g_atomic_int_add (&acq->shared->pending, -1);
    return;
  }
  switch (kind) {
  case CMD_CAPTURE:
    ds_seq_set_state (acq->shared, DS_SEQUENCER_STATE_ACQUIRING);
    ds_seq_run_set (acq, &cmd->settings, cmd->tag, DS_SET_FOR_REQUEST);
    g_atomic_int_add (&acq->shared->pending, -1);
    break;
  case CMD_DARK:
    ds_seq_set_state (acq->shared, DS_SEQUENCER_STATE_ACQUIRING);
    ds_seq_run_dark (acq, &cmd->settings, cmd->tag);
    g_atomic_int_add (&acq->shared->pending, -1);
    break;
  case CMD_START:
    if (!acq->dev) {
      ds_seq_emit (acq->shared, DS_SEQUENCER_EVENT_DEVICE, 0, NULL, NULL,
                   "continuous acquisition not started: the devices are released (send acquire first)");
      break;
    }
    acq->run.mode = cmd->follow_defaults ? DS_RUN_STREAM_DEFAULTS : DS_RUN_STREAM;
    acq->run.gen = cmd->gen;
    acq->run.settings = cmd->settings;
    break;
  case CMD_STOP:
    acq->run.mode = DS_RUN_ON_REQUEST;
    break;
  case CMD_DEFAULTS:
    g_mutex_lock (&acq->shared->lock);
    acq->shared->defaults = cmd->settings;
    g_mutex_unlock (&acq->shared->lock);
    /* Released devices take the new defaults when they are acquired again. */
    if (acq->dev)
      ds_seq_apply_defaults (acq);
    break;
  case CMD_RELEASE:
    release_devices (acq, cmd->tag);
    g_atomic_int_add (&acq->shared->pending, -1);
    break;
  case CMD_ACQUIRE:
    acquire_devices (acq, cmd->tag);
    g_atomic_int_add (&acq->shared->pending, -1);
    break;
  case CMD_SET_CAMERA: {
    GError *error = NULL;
    gboolean ok = ds_seq_camera_set (acq, &cmd->camera, &error);
    g_atomic_int_add (&acq->shared->pending, -1);
    ds_seq_emit (acq->shared, DS_SEQUENCER_EVENT_CONTROL, cmd->tag, NULL, error, ok ? "camera settings applied" : NULL);
    break;
  }
  case CMD_PREVIEW:
    ds_seq_preview_command (acq, cmd->preview_on, cmd->preview_light, cmd->preview_phase, cmd->tag);
    g_atomic_int_add (&acq->shared->pending, -1);
    break;
  case CMD_OPERATING_MODEL:
  case CMD_CANCEL:
  case CMD_QUIT:
    g_assert_not_reached ();
  }
  g_mutex_lock (&acq->shared->lock);
  acq->shared->status.continuous = ds_acquisition_streaming (acq);
  update_dark_mode (acq);
  g_mutex_unlock (&acq->shared->lock);
  ds_seq_set_state (acq->shared, !acq->dev ? DS_SEQUENCER_STATE_RELEASED
                                 : acq->need_reconnect ? DS_SEQUENCER_STATE_RECONNECTING
                                 : ds_acquisition_streaming (acq) ? DS_SEQUENCER_STATE_CONTINUOUS
                                 : ds_acquisition_previewing (acq) ? DS_SEQUENCER_STATE_PREVIEW
                                 : DS_SEQUENCER_STATE_IDLE);
}

/* The thread's loop once the devices opened: commands one at a time, and in continuous mode
 * sets back to back between them. Returns on CMD_QUIT (or quit set with no command left). */
static void
run_commands (DsAcquisition *acq)
{
  guint consecutive_failures = 0;
  for (;;) {
    if (acq->need_reconnect && acq->dev) {
      ds_seq_carry_discard (acq);
      ds_seq_reconnect (acq);
    }
    gboolean streaming = ds_acquisition_streaming (acq);
    gboolean previewing = ds_acquisition_previewing (acq);
    Command *cmd = streaming || previewing ? g_async_queue_try_pop (acq->shared->queue)
                                           : g_async_queue_timeout_pop (acq->shared->queue, G_USEC_PER_SEC / 2);
    ds_seq_heartbeat (acq->shared);
    if (cmd && cmd->kind == CMD_OPERATING_MODEL) {
      /* Configuration read only by the next automatic capture: the stream (and a frame it
       * triggered ahead) goes on undisturbed. */
      acq->model = cmd->model;
      acq->timing = cmd->timing;
      g_free (cmd);
      continue;
    }
    /* A frame triggered ahead for the next continuous set: any command comes first (it may
     * change settings, stop, capture once or release the devices), so the frame is aborted. */
    if (cmd || !streaming || g_atomic_int_get (&acq->shared->quit))
      ds_seq_carry_discard (acq);
    if (!cmd) {
      if (g_atomic_int_get (&acq->shared->quit))
        return;
      if (streaming)
        run_stream_set (acq, &consecutive_failures);
      else if (previewing)
        ds_seq_run_preview (acq);
      continue;
    }
    if (cmd->kind == CMD_CANCEL) {
      finish_cancel (acq, cmd);
      g_free (cmd);
      continue;
    }
    gboolean quit = cmd->kind == CMD_QUIT;
    if (!quit)
      run_command (acq, cmd);
    g_free (cmd);
    if (quit)
      return;
  }
}

/* The acquisition thread: opens the devices, runs commands until quit, then leaves the devices
 * idle (camera stopped, illuminator off) for ds_sequencer_free to close. */
static gpointer
thread_main (gpointer data)
{
  DsAcquisition *acq = data;
  g_autoptr (GError) error = NULL;
  ds_seq_set_state (acq->shared, DS_SEQUENCER_STATE_OPENING);
  if (!open_and_report_devices (acq, &error)) {
    ds_seq_set_state (acq->shared, DS_SEQUENCER_STATE_FAILED);
    ds_seq_record_error (acq->shared, error);
    ds_seq_emit (acq->shared, DS_SEQUENCER_EVENT_READY, 0, NULL, g_steal_pointer (&error), NULL);
    run_without_devices (acq);
    return NULL;
  }
  acq->worker = ds_fold_worker_new (acq->shared);
  /* Settings applied now, not at the first capture: a pixel format or a gain the camera
   * refuses shows in status (ready false, with the camera's reason) right after start. */
  ds_seq_apply_defaults (acq);
  ds_seq_set_state (acq->shared, DS_SEQUENCER_STATE_IDLE);
  ds_seq_emit (acq->shared, DS_SEQUENCER_EVENT_READY, 0, NULL, NULL, acq->dev->description);

  run_commands (acq);

  ds_seq_carry_discard (acq);
  if (acq->dev && acq->camera_started)
    acq->dev->camera->ops->stop (acq->dev->camera->backend);
  g_autoptr (GError) off_error = NULL;
  if (acq->dev)
    acq->dev->illuminator->ops->off (acq->dev->illuminator->backend, acq->dev->settle_timeout_ms, &off_error);
  g_clear_pointer (&acq->worker, ds_fold_worker_free);
  return NULL;
}

DsSequencer *
ds_sequencer_new (DsDevicesOpenFunc open_devices, gpointer open_data,
                  const DsCaptureSettings *defaults, GMainContext *context,
                  DsSequencerEventFunc on_event, gpointer user_data)
{
  DsSequencer *seq = g_new0 (DsSequencer, 1);
  DsSequencerShared *shared = &seq->shared;
  shared->queue = g_async_queue_new_full (g_free);
  shared->context = g_main_context_ref (context);
  shared->on_event = on_event;
  shared->user_data = user_data;
  shared->alive = 1;
  shared->defaults = *defaults;
  g_mutex_init (&shared->lock);
  shared->status.state = DS_SEQUENCER_STATE_OPENING;
  shared->status.phase_offset_cycles = NAN;
  shared->status.settings_ok = TRUE;
  shared->status.illuminator.applied_phase = -1;
  shared->status.illuminator.temperature_c = NAN;
  shared->status.heartbeat_us = g_get_monotonic_time ();

  DsAcquisition *acq = &seq->acq;
  acq->shared = shared;
  acq->open_devices = open_devices;
  acq->open_data = open_data;
  acq->dark_ids = g_array_new (FALSE, FALSE, sizeof (guint64));
  acq->stored_dark_ids = g_array_new (FALSE, FALSE, sizeof (guint64));
  acq->phase_check_period = NAN;
  /* Two sets of planes kept: one being written while the previous result is still sent. */
  acq->planes = ds_plane_pool_new (2);
  update_dark_mode (acq);
  seq->thread = g_thread_new ("acquisition", thread_main, acq);
  return seq;
}

static Command *
command_new (DsSequencer *seq, CommandKind kind, const DsCaptureSettings *s, guint64 tag)
{
  Command *cmd = g_new0 (Command, 1);
  cmd->kind = kind;
  cmd->gen = g_atomic_int_get (&seq->shared.cancel_gen);
  if (s)
    cmd->settings = *s;
  cmd->tag = tag;
  return cmd;
}

static void
push (DsSequencer *seq, CommandKind kind, const DsCaptureSettings *s, guint64 tag)
{
  g_async_queue_push (seq->shared.queue, command_new (seq, kind, s, tag));
}

/* What the thread owned, once it joined. */
static void
acquisition_clear (DsAcquisition *acq)
{
  if (acq->dev)
    ds_devices_close (acq->dev);
  g_clear_pointer (&acq->set, ds_phase_set_free);
  g_clear_pointer (&acq->window, ds_phase_window_free);
  g_clear_pointer (&acq->single, ds_single_frame_free);
  g_clear_pointer (&acq->dark, ds_image_free);
  g_clear_pointer (&acq->planes, ds_plane_pool_unref);
  g_clear_pointer (&acq->raw, ds_raw_frames_free);
  g_array_unref (acq->dark_ids);
  g_array_unref (acq->stored_dark_ids);
}

void
ds_sequencer_free (DsSequencer *seq)
{
  if (!seq)
    return;
  g_atomic_int_set (&seq->shared.quit, 1);
  push (seq, CMD_QUIT, NULL, 0);
  g_thread_join (seq->thread);
  g_atomic_int_set (&seq->shared.alive, 0);
  /* Events still queued in the context are dropped by their dispatch (alive == 0), but they
   * point at seq->shared: flush them now, before seq is freed. */
  while (g_main_context_iteration (seq->shared.context, FALSE))
    ;
  acquisition_clear (&seq->acq);
  g_async_queue_unref (seq->shared.queue);
  g_main_context_unref (seq->shared.context);
  g_mutex_clear (&seq->shared.lock);
  g_free (seq);
}

/* Queues a command that counts against MAX_PENDING; FALSE (nothing queued) when full. */
static gboolean
push_counted (DsSequencer *seq, CommandKind kind, const DsCaptureSettings *s, guint64 tag)
{
  if (g_atomic_int_add (&seq->shared.pending, 1) >= MAX_PENDING) {
    g_atomic_int_add (&seq->shared.pending, -1);
    return FALSE;
  }
  push (seq, kind, s, tag);
  return TRUE;
}

gboolean
ds_sequencer_capture (DsSequencer *seq, const DsCaptureSettings *settings, guint64 tag)
{
  return push_counted (seq, CMD_CAPTURE, settings, tag);
}

gboolean
ds_sequencer_dark (DsSequencer *seq, const DsCaptureSettings *settings, guint64 tag)
{
  return push_counted (seq, CMD_DARK, settings, tag);
}

gboolean
ds_sequencer_release (DsSequencer *seq, guint64 tag)
{
  return push_counted (seq, CMD_RELEASE, NULL, tag);
}

gboolean
ds_sequencer_acquire (DsSequencer *seq, guint64 tag)
{
  return push_counted (seq, CMD_ACQUIRE, NULL, tag);
}

gboolean
ds_sequencer_set_camera (DsSequencer *seq, const DsCameraChange *change, guint64 tag)
{
  if (g_atomic_int_add (&seq->shared.pending, 1) >= MAX_PENDING) {
    g_atomic_int_add (&seq->shared.pending, -1);
    return FALSE;
  }
  Command *cmd = command_new (seq, CMD_SET_CAMERA, NULL, tag);
  cmd->camera = *change;
  g_async_queue_push (seq->shared.queue, cmd);
  return TRUE;
}

void
ds_sequencer_start (DsSequencer *seq, const DsCaptureSettings *settings)
{
  Command *cmd = command_new (seq, CMD_START, settings, 0);
  cmd->follow_defaults = settings == NULL;
  g_async_queue_push (seq->shared.queue, cmd);
}

void
ds_sequencer_cancel (DsSequencer *seq, guint64 tag)
{
  /* Queued first, published second: the thread, once it sees the new count (and ends its set),
   * finds the CMD_CANCEL in the queue and stops the stream there, so no stream set starts in
   * between. Main thread only: one writer, so the read and the set cannot interleave. */
  Command *cmd = command_new (seq, CMD_CANCEL, NULL, tag);
  gint gen = ++cmd->gen;
  g_async_queue_push (seq->shared.queue, cmd); /* the thread's from here: not read again */
  g_atomic_int_set (&seq->shared.cancel_gen, gen);
}

void
ds_sequencer_stop (DsSequencer *seq)
{
  push (seq, CMD_STOP, NULL, 0);
}

void
ds_sequencer_set_defaults (DsSequencer *seq, const DsCaptureSettings *defaults)
{
  push (seq, CMD_DEFAULTS, defaults, 0);
}

void
ds_sequencer_set_frame_hook (DsSequencer *seq, DsSequencerFrameFunc func, gpointer user_data)
{
  g_mutex_lock (&seq->shared.lock);
  seq->shared.frame_hook = func;
  seq->shared.frame_hook_data = user_data;
  g_mutex_unlock (&seq->shared.lock);
}

gboolean
ds_sequencer_preview (DsSequencer *seq, gboolean on, DsPreviewLight light, guint phase, guint64 tag)
{
  if (g_atomic_int_add (&seq->shared.pending, 1) >= MAX_PENDING) {
    g_atomic_int_add (&seq->shared.pending, -1);
    return FALSE;
  }
  Command *cmd = command_new (seq, CMD_PREVIEW, NULL, tag);
  cmd->preview_on = on;
  cmd->preview_light = light;
  cmd->preview_phase = phase;
  g_async_queue_push (seq->shared.queue, cmd);
  return TRUE;
}

void
ds_sequencer_set_preview_hook (DsSequencer *seq, DsSequencerPreviewFunc func, gpointer user_data)
{
  g_mutex_lock (&seq->shared.lock);
  seq->shared.preview_hook = func;
  seq->shared.preview_hook_data = user_data;
  g_mutex_unlock (&seq->shared.lock);
}

void
ds_sequencer_get_status (DsSequencer *seq, DsSequencerStatus *status)
{
  g_mutex_lock (&seq->shared.lock);
  *status = seq->shared.status;
  status->pending = (guint) g_atomic_int_get (&seq->shared.pending);
  /* At once, before the thread notices: a cancel not yet taken, over the states of work (opening,
   * reconnecting, released and failed say more about the devices, and cancel nothing). */
  gboolean working = status->state == DS_SEQUENCER_STATE_IDLE || status->state == DS_SEQUENCER_STATE_ACQUIRING ||
                     status->state == DS_SEQUENCER_STATE_CONTINUOUS || status->state == DS_SEQUENCER_STATE_PREVIEW;
  if (working && g_atomic_int_get (&seq->shared.cancel_gen) != g_atomic_int_get (&seq->shared.cancel_acked))
    status->state = DS_SEQUENCER_STATE_CANCELLING;
  g_mutex_unlock (&seq->shared.lock);
}

void
ds_sequencer_set_operating_model (DsSequencer *seq, const DsOperatingModel *model, double settle_ms,
                                  double link_mbit)
{
  /* Queued like the captures that use it, so that it reaches the thread before them. */
  Command *cmd = command_new (seq, CMD_OPERATING_MODEL, NULL, 0);
  cmd->model = model;
  ds_rig_timing_init (&cmd->timing);
  cmd->timing.settle_ms = settle_ms;
  cmd->timing.link_mbit_s = link_mbit;
  g_async_queue_push (seq->shared.queue, cmd);
}
