/* The acquisition thread and its command queue: requests from the main thread are queued,
 * the thread runs them one at a time (or sets back to back in continuous mode) and reports
 * through events. What a set does is in set_runner.c; the file map is in
 * sequencer_private.h. */
#include <math.h>

#include "daemon/protocol/protocol.h"
#include "daemon/acquire/sequencer_private.h"

typedef enum {
  CMD_CAPTURE,
  CMD_DARK,
  CMD_START,
  CMD_STOP,
  CMD_DEFAULTS,
  CMD_RELEASE,
  CMD_ACQUIRE,
  CMD_QUIT,
} CommandKind;

typedef struct {
  CommandKind kind;
  DsCaptureSettings settings;  /* CMD_CAPTURE, CMD_DARK, CMD_DEFAULTS; CMD_START unless
                                * follow_defaults */
  gboolean follow_defaults;    /* CMD_START without settings: each set takes the defaults as
                                * they are when it starts (a reload changes the stream) */
  guint64 tag;                 /* the request's, echoed in its events; 0 for none */
} Command;

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
 * answers captures with NOT_READY until they are acquired again. */
static void
release_devices (DsSequencer *seq, guint64 tag)
{
  if (seq->dev) {
    seq->run.mode = DS_RUN_ON_REQUEST;
    if (seq->camera_started)
      seq->dev->camera->ops->stop (seq->dev->camera->backend);
    g_autoptr (GError) off_error = NULL;
    seq->dev->illuminator->ops->off (seq->dev->illuminator->backend, seq->dev->settle_timeout_ms, &off_error);
    g_clear_pointer (&seq->dev, ds_devices_close);
    seq->camera_started = seq->camera_configured = FALSE;
    seq->need_reconnect = FALSE;
    g_mutex_lock (&seq->lock);
    g_strlcpy (seq->status.devices, "released", sizeof seq->status.devices);
    seq->status.camera_info.connected = FALSE;
    seq->status.illuminator.ready = FALSE;
    seq->status.continuous = FALSE;
    g_mutex_unlock (&seq->lock);
  }
  ds_seq_set_state (seq, DS_SEQUENCER_STATE_RELEASED);
  ds_seq_emit (seq, DS_SEQUENCER_EVENT_CONTROL, tag, NULL, NULL, "devices released: another program may open the camera");
}

/* What the next set does about the dark (status "dark"): the running stream's settings in
 * continuous mode, else the defaults. Under seq->lock. */
static void
update_dark_mode (DsSequencer *seq)
{
  const DsCaptureSettings *next = seq->run.mode == DS_RUN_STREAM ? &seq->run.settings : &seq->defaults;
  const DsDarkFrameInfo *stored = &seq->status.stored_dark;
  seq->status.per_set_dark = next->dark_frame;
  seq->status.stored_dark_applies = stored->taken && stored->exposure_us == next->exposure_us &&
                                    stored->gain_db == next->gain_db;
}

static void
acquire_devices (DsSequencer *seq, guint64 tag)
{
  if (seq->dev) {
    ds_seq_emit (seq, DS_SEQUENCER_EVENT_CONTROL, tag, NULL, NULL, "devices already open");
    return;
  }
  ds_seq_set_state (seq, DS_SEQUENCER_STATE_OPENING);
  GError *error = NULL;
  seq->dev = seq->open_devices (seq->open_data, &error);
  if (!seq->dev) {
    ds_seq_record_error (seq, error);
    ds_seq_set_state (seq, DS_SEQUENCER_STATE_RELEASED);
    g_prefix_error (&error, "acquire: ");
    ds_seq_emit (seq, DS_SEQUENCER_EVENT_CONTROL, tag, NULL, error, NULL);
    return;
  }
  g_mutex_lock (&seq->lock);
  g_strlcpy (seq->status.devices, seq->dev->description, sizeof seq->status.devices);
  g_mutex_unlock (&seq->lock);
  ds_seq_refresh_device_status (seq);
  /* Devices opened again must take the settings again, as at start and after a reconnect. */
  ds_seq_apply_defaults (seq);
  ds_seq_set_state (seq, DS_SEQUENCER_STATE_IDLE);
  ds_seq_emit (seq, DS_SEQUENCER_EVENT_CONTROL, tag, NULL, NULL, seq->dev->description);
}

/* A capture or dark frame while the devices are released. */
static void
refuse_released (DsSequencer *seq, const Command *cmd)
{
  ds_seq_emit (seq, cmd->kind == CMD_DARK ? DS_SEQUENCER_EVENT_DARK : DS_SEQUENCER_EVENT_FAILED, cmd->tag, NULL,
               g_error_new (DS_SEQUENCER_ERROR, DS_SEQUENCER_ERROR_NOT_READY,
                            "the devices are released (another program may hold the camera): send acquire first"),
               NULL);
}

static gpointer
thread_main (gpointer data)
{
  DsSequencer *seq = data;
  g_autoptr (GError) error = NULL;
  ds_seq_set_state (seq, DS_SEQUENCER_STATE_OPENING);
  seq->dev = seq->open_devices (seq->open_data, &error);
  if (!seq->dev) {
    ds_seq_set_state (seq, DS_SEQUENCER_STATE_FAILED);
    ds_seq_record_error (seq, error);
    ds_seq_emit (seq, DS_SEQUENCER_EVENT_READY, 0, NULL, g_steal_pointer (&error), NULL);
    /* Nothing to drive: wait for the quit command so that status stays answerable. */
    for (;;) {
      Command *cmd = g_async_queue_timeout_pop (seq->queue, G_USEC_PER_SEC);
      ds_seq_heartbeat (seq);
      gboolean quit = cmd && cmd->kind == CMD_QUIT;
      if (cmd && (cmd->kind == CMD_CAPTURE || cmd->kind == CMD_DARK)) {
        g_atomic_int_dec_and_test (&seq->pending);
        ds_seq_emit (seq, cmd->kind == CMD_DARK ? DS_SEQUENCER_EVENT_DARK : DS_SEQUENCER_EVENT_FAILED,
              cmd->tag, NULL,
              g_error_new (DS_SEQUENCER_ERROR, DS_SEQUENCER_ERROR_NOT_READY, "devices are not open: %s",
                           seq->status.last_error),
              NULL);
      }
      g_free (cmd);
      if (quit)
        return NULL;
    }
  }
  g_mutex_lock (&seq->lock);
  g_strlcpy (seq->status.devices, seq->dev->description, sizeof seq->status.devices);
  g_mutex_unlock (&seq->lock);
  ds_seq_refresh_device_status (seq);
  seq->worker = ds_fold_worker_new (seq);
  /* Settings applied now, not at the first capture: a pixel format or a gain the camera
   * refuses shows in status (ready false, with the camera's reason) right after start. */
  ds_seq_apply_defaults (seq);
  ds_seq_set_state (seq, DS_SEQUENCER_STATE_IDLE);
  ds_seq_emit (seq, DS_SEQUENCER_EVENT_READY, 0, NULL, NULL, seq->dev->description);

  guint consecutive_failures = 0;
  for (;;) {
    if (seq->need_reconnect && seq->dev) {
      ds_seq_carry_discard (seq);
      ds_seq_reconnect (seq);
    }
    gboolean streaming = seq->run.mode != DS_RUN_ON_REQUEST;
    Command *cmd = streaming ? g_async_queue_try_pop (seq->queue)
                                   : g_async_queue_timeout_pop (seq->queue, G_USEC_PER_SEC / 2);
    ds_seq_heartbeat (seq);
    /* A frame triggered ahead for the next continuous set: any command comes first (it may
     * change settings, stop, capture once or release the devices), so the frame is aborted. */
    if (cmd || !streaming || g_atomic_int_get (&seq->quit))
      ds_seq_carry_discard (seq);
    if (!cmd) {
      if (g_atomic_int_get (&seq->quit))
        break;
      if (streaming) {
        if (seq->run.mode == DS_RUN_STREAM_DEFAULTS) {
          g_mutex_lock (&seq->lock);
          seq->run.settings = seq->defaults;
          g_mutex_unlock (&seq->lock);
        }
        ds_seq_set_state (seq, DS_SEQUENCER_STATE_CONTINUOUS);
        g_mutex_lock (&seq->lock);
        guint64 failed_before = seq->status.sets_failed;
        g_mutex_unlock (&seq->lock);
        ds_seq_run_set (seq, &seq->run.settings, 0, DS_SET_FOR_STREAM);
        g_mutex_lock (&seq->lock);
        gboolean failed = seq->status.sets_failed != failed_before;
        g_mutex_unlock (&seq->lock);
        /* Sets that keep failing (a setting the camera refuses fails at once) are spaced out,
         * 0.1 s doubling to 2 s, instead of spinning: commands and quit still cut the wait. */
        consecutive_failures = failed ? consecutive_failures + 1 : 0;
        guint wait_ms = consecutive_failures ? MIN (100u << MIN (consecutive_failures - 1, 5u), 2000u) : 0;
        for (guint waited = 0; waited < wait_ms && !g_atomic_int_get (&seq->quit) &&
                               g_async_queue_length (seq->queue) <= 0; waited += 20) {
          ds_seq_heartbeat (seq);
          g_usleep (20 * 1000);
        }
      }
      continue;
    }
    CommandKind kind = cmd->kind;
    if (!seq->dev && (kind == CMD_CAPTURE || kind == CMD_DARK)) {
      refuse_released (seq, cmd);
      g_atomic_int_add (&seq->pending, -1);
      g_free (cmd);
      continue;
    }
    switch (kind) {
    case CMD_CAPTURE:
      ds_seq_set_state (seq, DS_SEQUENCER_STATE_ACQUIRING);
      ds_seq_run_set (seq, &cmd->settings, cmd->tag, DS_SET_FOR_REQUEST);
      g_atomic_int_add (&seq->pending, -1);
      break;
    case CMD_DARK:
      ds_seq_set_state (seq, DS_SEQUENCER_STATE_ACQUIRING);
      ds_seq_run_dark (seq, &cmd->settings, cmd->tag);
      g_atomic_int_add (&seq->pending, -1);
      break;
    case CMD_START:
      if (!seq->dev) {
        ds_seq_emit (seq, DS_SEQUENCER_EVENT_DEVICE, 0, NULL, NULL,
                     "continuous acquisition not started: the devices are released (send acquire first)");
        break;
      }
      seq->run.mode = cmd->follow_defaults ? DS_RUN_STREAM_DEFAULTS : DS_RUN_STREAM;
      seq->run.settings = cmd->settings;
      break;
    case CMD_STOP:
      seq->run.mode = DS_RUN_ON_REQUEST;
      break;
    case CMD_DEFAULTS:
      g_mutex_lock (&seq->lock);
      seq->defaults = cmd->settings;
      g_mutex_unlock (&seq->lock);
      /* Released devices take the new defaults when they are acquired again. */
      if (seq->dev)
        ds_seq_apply_defaults (seq);
      break;
    case CMD_RELEASE:
      release_devices (seq, cmd->tag);
      g_atomic_int_add (&seq->pending, -1);
      break;
    case CMD_ACQUIRE:
      acquire_devices (seq, cmd->tag);
      g_atomic_int_add (&seq->pending, -1);
      break;
    case CMD_QUIT:
      break;
    }
    g_free (cmd);
    if (kind == CMD_QUIT)
      break;
    g_mutex_lock (&seq->lock);
    seq->status.continuous = seq->run.mode != DS_RUN_ON_REQUEST;
    update_dark_mode (seq);
    g_mutex_unlock (&seq->lock);
    ds_seq_set_state (seq, !seq->dev ? DS_SEQUENCER_STATE_RELEASED
                           : seq->need_reconnect ? DS_SEQUENCER_STATE_RECONNECTING
                           : seq->run.mode != DS_RUN_ON_REQUEST ? DS_SEQUENCER_STATE_CONTINUOUS : DS_SEQUENCER_STATE_IDLE);
  }
  ds_seq_carry_discard (seq);
  if (seq->dev && seq->camera_started)
    seq->dev->camera->ops->stop (seq->dev->camera->backend);
  g_autoptr (GError) off_error = NULL;
  if (seq->dev)
    seq->dev->illuminator->ops->off (seq->dev->illuminator->backend, seq->dev->settle_timeout_ms, &off_error);
  g_clear_pointer (&seq->worker, ds_fold_worker_free);
  return NULL;
}

DsSequencer *
ds_sequencer_new (DsDevicesOpenFunc open_devices, gpointer open_data,
                  const DsCaptureSettings *defaults, GMainContext *context,
                  DsSequencerEventFunc on_event, gpointer user_data)
{
  DsSequencer *seq = g_new0 (DsSequencer, 1);
  seq->queue = g_async_queue_new_full (g_free);
  seq->dark_ids = g_array_new (FALSE, FALSE, sizeof (guint64));
  seq->stored_dark_ids = g_array_new (FALSE, FALSE, sizeof (guint64));
  seq->context = g_main_context_ref (context);
  seq->on_event = on_event;
  seq->user_data = user_data;
  seq->open_devices = open_devices;
  seq->open_data = open_data;
  seq->alive = 1;
  seq->defaults = *defaults;
  seq->phase_check_period = NAN;
  /* Two sets of planes kept: one being written while the previous result is still sent. */
  seq->planes = ds_plane_pool_new (2);
  g_mutex_init (&seq->lock);
  seq->status.state = DS_SEQUENCER_STATE_OPENING;
  seq->status.phase_offset_cycles = NAN;
  seq->status.settings_ok = TRUE;
  update_dark_mode (seq);
  seq->status.illuminator.applied_phase = -1;
  seq->status.illuminator.temperature_c = NAN;
  seq->status.heartbeat_us = g_get_monotonic_time ();
  seq->thread = g_thread_new ("acquisition", thread_main, seq);
  return seq;
}

static Command *
command_new (CommandKind kind, const DsCaptureSettings *s, guint64 tag)
{
  Command *cmd = g_new0 (Command, 1);
  cmd->kind = kind;
  if (s)
    cmd->settings = *s;
  cmd->tag = tag;
  return cmd;
}

static void
push (DsSequencer *seq, CommandKind kind, const DsCaptureSettings *s, guint64 tag)
{
  g_async_queue_push (seq->queue, command_new (kind, s, tag));
}

void
ds_sequencer_free (DsSequencer *seq)
{
  if (!seq)
    return;
  g_atomic_int_set (&seq->quit, 1);
  push (seq, CMD_QUIT, NULL, 0);
  g_thread_join (seq->thread);
  g_atomic_int_set (&seq->alive, 0);
  /* Events still queued in the context are dropped by their dispatch (alive == 0), but they
   * point at seq: flush them now, before seq is freed. */
  while (g_main_context_iteration (seq->context, FALSE))
    ;
  if (seq->dev)
    ds_devices_close (seq->dev);
  g_clear_pointer (&seq->set, ds_phase_set_free);
  g_clear_pointer (&seq->dark, ds_image_free);
  g_clear_pointer (&seq->planes, ds_plane_pool_unref);
  g_clear_pointer (&seq->raw, ds_raw_frames_free);
  g_array_unref (seq->dark_ids);
  g_array_unref (seq->stored_dark_ids);
  g_async_queue_unref (seq->queue);
  g_main_context_unref (seq->context);
  g_mutex_clear (&seq->lock);
  g_free (seq);
}

gboolean
ds_sequencer_capture (DsSequencer *seq, const DsCaptureSettings *settings, guint64 tag)
{
  if (g_atomic_int_add (&seq->pending, 1) >= MAX_PENDING) {
    g_atomic_int_add (&seq->pending, -1);
    return FALSE;
  }
  push (seq, CMD_CAPTURE, settings, tag);
  return TRUE;
}

gboolean
ds_sequencer_dark (DsSequencer *seq, const DsCaptureSettings *settings, guint64 tag)
{
  if (g_atomic_int_add (&seq->pending, 1) >= MAX_PENDING) {
    g_atomic_int_add (&seq->pending, -1);
    return FALSE;
  }
  push (seq, CMD_DARK, settings, tag);
  return TRUE;
}

static gboolean
push_counted (DsSequencer *seq, CommandKind kind, guint64 tag)
{
  if (g_atomic_int_add (&seq->pending, 1) >= MAX_PENDING) {
    g_atomic_int_add (&seq->pending, -1);
    return FALSE;
  }
  push (seq, kind, NULL, tag);
  return TRUE;
}

gboolean
ds_sequencer_release (DsSequencer *seq, guint64 tag)
{
  return push_counted (seq, CMD_RELEASE, tag);
}

gboolean
ds_sequencer_acquire (DsSequencer *seq, guint64 tag)
{
  return push_counted (seq, CMD_ACQUIRE, tag);
}

void
ds_sequencer_start (DsSequencer *seq, const DsCaptureSettings *settings)
{
  Command *cmd = command_new (CMD_START, settings, 0);
  cmd->follow_defaults = settings == NULL;
  g_async_queue_push (seq->queue, cmd);
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
  g_mutex_lock (&seq->lock);
  seq->frame_hook = func;
  seq->frame_hook_data = user_data;
  g_mutex_unlock (&seq->lock);
}

void
ds_sequencer_get_status (DsSequencer *seq, DsSequencerStatus *status)
{
  g_mutex_lock (&seq->lock);
  *status = seq->status;
  status->pending = (guint) g_atomic_int_get (&seq->pending);
  g_mutex_unlock (&seq->lock);
}

void
ds_sequencer_set_operating_model (DsSequencer *seq, const DsOperatingModel *model, double settle_ms,
                                  double link_mbit)
{
  seq->model = model;
  ds_rig_timing_init (&seq->timing);
  seq->timing.settle_ms = settle_ms;
  seq->timing.link_mbit_s = link_mbit;
}
