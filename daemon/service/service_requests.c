/* Clients' commands beyond the server's own (hello, subscribe, unsubscribe): each checks its
 * arguments, then answers at once (status, config, start, stop) or queues work for the
 * acquisition thread and answers when its event comes (service_events.c). */
#include "daemon/service/service_private.h"

#include <math.h>
#include <string.h>

#include "daemon/protocol/protocol.h"
#include "daemon/service/json_build.h"
#include "proc/phase_check.h"

const char *const ds_service_output_names[DS_SERVICE_N_OUTPUTS] = { "transmissive", "scattered", "mask",
                                                                     "max",          "min",       "mean" };

void
ds_service_pending_free (gpointer data)
{
  PendingCapture *p = data;
  if (p->conn) {
    ds_connection_release (p->conn);
    ds_connection_unref (p->conn);
  }
  if (p->id)
    json_node_unref (p->id);
  g_free (p);
}

#define DS_SAVE_PHASES_MAX_FRAMES 256

/* Capture settings from the defaults overlaid with the request's arguments. */
static gboolean
settings_from_request (DsService *svc, const DsRequest *req, DsCaptureSettings *s, GError **error)
{
  ds_capture_settings_from_config (s, svc->config);
  ds_service_camera_defaults (svc, s);
  /* A capture is one set; continuous mode's `results` is start's own argument. */
  s->per_frame = FALSE;
  guint64 u;
  double d;
  gboolean bval;
  const char *choice;
  static const char *const estimators[] = { "maxmin", "sine", "robust", NULL };
  if (!ds_request_get_uint (req, "phases", 2, 64, s->phases, &u, error))
    return FALSE;
  s->phases = (guint) u;
  if (!ds_request_get_uint (req, "averages", 1, 64, s->averages, &u, error))
    return FALSE;
  s->averages = (guint) u;
  if (!ds_request_get_double (req, "exposure_us", 1.0, 10e6, s->exposure_us, &d, error))
    return FALSE;
  s->exposure_us = d;
  if (!ds_request_get_double (req, "gain_db", 0.0, 48.0, s->gain_db, &d, error))
    return FALSE;
  s->gain_db = d;
  if (!ds_request_get_choice (req, "estimator", estimators, ds_estimator_name (s->estimator),
                              &choice, error))
    return FALSE;
  ds_estimator_from_name (choice, &s->estimator);
  if (!ds_request_get_bool (req, "dark_frame", s->dark_frame, &bval, error))
    return FALSE;
  s->dark_frame = bval;
  if (!ds_request_get_bool (req, "verify_phase", s->verify_phase, &bval, error))
    return FALSE;
  s->verify_phase = bval;
  if (!ds_request_get_bool (req, "save_phases", s->save_phases, &bval, error))
    return FALSE;
  s->save_phases = bval;
  if (!ds_request_get_bool (req, "single_frame", s->single_frame, &bval, error))
    return FALSE;
  s->single_frame = bval;
  /* Every raw frame is a payload and a line of metadata: keep a reply within bounds. */
  if (s->save_phases && s->phases * s->averages > DS_SAVE_PHASES_MAX_FRAMES) {
    g_set_error (error, DS_PROTOCOL_ERROR, DS_PROTOCOL_ERROR_BAD_ARGUMENT,
                 "\"save_phases\": phases x averages = %u exceeds %u frames per set", s->phases * s->averages,
                 DS_SAVE_PHASES_MAX_FRAMES);
    return FALSE;
  }
  if (!ds_request_get_double (req, "target_error", 0.0, 1.0, 0.0, &s->target_error, error) ||
      !ds_request_get_double (req, "time_budget_ms", 0.0, 3.6e6, 0.0, &s->time_budget_ms, error))
    return FALSE;
  /* A declared speed is the automatic operating point's: refused where nothing would use it. */
  double speed = NAN;
  if (!ds_request_get_double (req, "speed_px_s", 0.0, 1e6, NAN, &speed, error))
    return FALSE;
  if (!isnan (speed) && s->target_error <= 0 && s->time_budget_ms <= 0) {
    g_set_error (error, DS_PROTOCOL_ERROR, DS_PROTOCOL_ERROR_BAD_ARGUMENT,
                 "\"speed_px_s\" without target_error or time_budget_ms: only the automatic operating point "
                 "predicts with it");
    return FALSE;
  }
  if (!isnan (speed)) {
    s->speed_declared = TRUE;
    s->speed_px_s = speed;
  }
  /* One frame per result: the window of one period holds too few samples for robust, and the
   * automatic operating point chooses among phase sets. */
  if (s->single_frame && s->estimator == DS_ESTIMATOR_ROBUST) {
    g_set_error (error, DS_PROTOCOL_ERROR, DS_PROTOCOL_ERROR_BAD_ARGUMENT,
                 "\"single_frame\": the estimator is robust; one frame holds one stripe period per pixel, "
                 "too few samples for it: use maxmin or sine");
    return FALSE;
  }
  if (s->single_frame && (s->target_error > 0 || s->time_budget_ms > 0)) {
    g_set_error (error, DS_PROTOCOL_ERROR, DS_PROTOCOL_ERROR_BAD_ARGUMENT,
                 "\"single_frame\" with target_error or time_budget_ms: the automatic operating point chooses "
                 "among phase sets; ask for one or the other");
    return FALSE;
  }
  if ((s->target_error > 0 || s->time_budget_ms > 0) && !svc->model) {
    g_set_error (error, DS_PROTOCOL_ERROR, DS_PROTOCOL_ERROR_FAILED,
                 "automatic operating point unavailable: %s", svc->model_error);
    return FALSE;
  }
  /* An explicit tolerance in the configuration stays; otherwise it follows N. */
  if (isnan (svc->config->phase_tolerance_deg))
    s->phase_tolerance_deg = ds_phase_check_default_tolerance_deg (s->phases);
  /* The estimator's own constraints (sine needs N >= 3, ...), with its message. */
  DsSeparationParams p;
  ds_separation_params_init (&p, s->phases);
  p.estimator = s->estimator;
  p.pattern = s->pattern;
  p.duty = s->duty;
  p.black_level = s->black_level;
  g_autoptr (GError) local = NULL;
  if (!ds_separation_params_validate (&p, &local)) {
    g_set_error (error, DS_PROTOCOL_ERROR, DS_PROTOCOL_ERROR_BAD_ARGUMENT, "%s", local->message);
    return FALSE;
  }
  return TRUE;
}

static gboolean
outputs_from_request (const DsRequest *req, guint *outputs, gboolean *extrema, GError **error)
{
  *outputs = 0x7; /* transmissive, scattered, mask */
  *extrema = FALSE;
  JsonNode *node = json_object_get_member (req->args, "outputs");
  if (!node)
    return TRUE;
  if (!JSON_NODE_HOLDS_ARRAY (node)) {
    g_set_error (error, DS_PROTOCOL_ERROR, DS_PROTOCOL_ERROR_BAD_ARGUMENT,
                 "\"outputs\" must be an array of names (transmissive, scattered, mask, max, min, mean)");
    return FALSE;
  }
  JsonArray *arr = json_node_get_array (node);
  *outputs = 0;
  for (guint i = 0; i < json_array_get_length (arr); i++) {
    JsonNode *el = json_array_get_element (arr, i);
    const char *name = JSON_NODE_HOLDS_VALUE (el) && json_node_get_value_type (el) == G_TYPE_STRING
                           ? json_node_get_string (el)
                           : NULL;
    guint j = 0;
    while (name && j < G_N_ELEMENTS (ds_service_output_names) && strcmp (name, ds_service_output_names[j]) != 0)
      j++;
    if (!name || j == G_N_ELEMENTS (ds_service_output_names)) {
      g_set_error (error, DS_PROTOCOL_ERROR, DS_PROTOCOL_ERROR_BAD_ARGUMENT,
                   "\"outputs\"[%u] is not one of transmissive, scattered, mask, max, min, mean", i);
      return FALSE;
    }
    *outputs |= 1u << j;
    if (j >= 3)
      *extrema = TRUE;
  }
  if (*outputs == 0) {
    g_set_error (error, DS_PROTOCOL_ERROR, DS_PROTOCOL_ERROR_BAD_ARGUMENT, "\"outputs\" is empty");
    return FALSE;
  }
  return TRUE;
}

void
ds_service_reply_ok (DsService *svc, DsConnection *conn, JsonNode *id, JsonNode *body)
{
  ds_server_reply_ok (svc->server, conn, id, body, NULL, NULL, 0);
}

/* A request the sequencer answers later, by its tag: the connection is held (no further request
 * is read from it) until the reply is sent. */
static PendingCapture *
pending_add (DsService *svc, DsConnection *conn, DsRequest *req, guint64 tag)
{
  PendingCapture *p = g_new0 (PendingCapture, 1);
  p->tag = tag;
  p->conn = ds_connection_ref (conn);
  ds_connection_hold (conn);
  p->id = req->id ? json_node_copy (req->id) : NULL;
  p->cancels_before = svc->cancels;
  g_hash_table_insert (svc->pending, &p->tag, p);
  return p;
}

PendingCapture *
ds_service_pending_add (DsService *svc, DsConnection *conn, DsRequest *req, guint64 tag)
{
  return pending_add (svc, conn, req, tag);
}

/* A request the sequencer did not take: its queue is full. While the devices open (or
 * reconnect) requests wait in that queue like any other: the acquisition thread takes them
 * once the devices are open, or answers them `device_error` when they fail to open. */
static void
reply_not_queued (DsService *svc, DsConnection *conn, DsRequest *req)
{
  g_autoptr (GError) error = g_error_new (DS_PROTOCOL_ERROR, DS_PROTOCOL_ERROR_BUSY,
                                          "%s: too many requests queued; try again later", req->cmd);
  ds_server_reply_error (svc->server, conn, req->id, error);
}

/* A command without arguments: TRUE when it has none, else answered with the error. */
static gboolean
no_arguments (DsService *svc, DsConnection *conn, DsRequest *req)
{
  static const char *const keys[] = { NULL };
  g_autoptr (GError) error = NULL;
  if (ds_request_check_keys (req, keys, &error))
    return TRUE;
  ds_server_reply_error (svc->server, conn, req->id, error);
  return FALSE;
}

static void
handle_capture (DsService *svc, DsConnection *conn, DsRequest *req)
{
  static const char *const keys[] = { "phases", "averages", "exposure_us", "gain_db", "estimator",
                                      "dark_frame", "verify_phase", "format", "outputs",
                                      "progress", "target_error", "time_budget_ms", "speed_px_s", "save_phases",
                                      "single_frame", NULL };
  g_autoptr (GError) error = NULL;
  DsCaptureSettings s;
  const char *format;
  static const char *const formats[] = { "f32", "u16", NULL };
  guint outputs;
  gboolean extrema, progress;
  if (!ds_request_check_keys (req, keys, &error) || !settings_from_request (svc, req, &s, &error) ||
      !ds_request_get_choice (req, "format", formats, "f32", &format, &error) ||
      !outputs_from_request (req, &outputs, &extrema, &error) ||
      !ds_request_get_bool (req, "progress", FALSE, &progress, &error)) {
    ds_server_reply_error (svc->server, conn, req->id, error);
    return;
  }
  s.keep_extrema = extrema;
  guint64 tag = ++svc->next_tag;
  if (!ds_sequencer_capture (svc->sequencer, &s, tag)) {
    reply_not_queued (svc, conn, req);
    return;
  }
  PendingCapture *p = pending_add (svc, conn, req, tag);
  p->cancellable = TRUE;
  p->format = strcmp (format, "u16") == 0 ? DS_OUTPUT_U16 : DS_OUTPUT_F32;
  p->extrema = extrema;
  p->outputs = outputs;
  p->progress = progress;
  /* Asked for explicitly: frames kept only for the spool stay off the wire. */
  p->save_phases = s.save_phases && json_object_has_member (req->args, "save_phases");
}

static void
handle_dark (DsService *svc, DsConnection *conn, DsRequest *req)
{
  static const char *const keys[] = { "averages", "exposure_us", "gain_db", NULL };
  g_autoptr (GError) error = NULL;
  DsCaptureSettings s;
  if (!ds_request_check_keys (req, keys, &error) || !settings_from_request (svc, req, &s, &error)) {
    ds_server_reply_error (svc->server, conn, req->id, error);
    return;
  }
  guint64 tag = ++svc->next_tag;
  if (!ds_sequencer_dark (svc->sequencer, &s, tag)) {
    reply_not_queued (svc, conn, req);
    return;
  }
  pending_add (svc, conn, req, tag)->cancellable = TRUE;
}

/* release / acquire: the devices closed for another program (arv-viewer) and opened again. */
static void
handle_control (DsService *svc, DsConnection *conn, DsRequest *req, gboolean release)
{
  if (!no_arguments (svc, conn, req))
    return;
  guint64 tag = ++svc->next_tag;
  gboolean queued = release ? ds_sequencer_release (svc->sequencer, tag) : ds_sequencer_acquire (svc->sequencer, tag);
  if (!queued) {
    reply_not_queued (svc, conn, req);
    return;
  }
  /* The set in progress ends the run; the run file closes after it. */
  if (release) {
    svc->in_run = FALSE;
    if (svc->spool)
      ds_spool_end_run (svc->spool);
  }
  pending_add (svc, conn, req, tag);
}

static void
handle_release (DsService *svc, DsConnection *conn, DsRequest *req)
{
  handle_control (svc, conn, req, TRUE);
}

static void
handle_acquire (DsService *svc, DsConnection *conn, DsRequest *req)
{
  handle_control (svc, conn, req, FALSE);
}

/* A phase set of a reference with little scattering, measured instead of only separated: the
 * raw frames are kept and the phase check is off (the set measures the period and phase the
 * check would test against); sine needs no sampling precondition that a wrong configured
 * period or duty would fail. The set is published as any other. It takes a dark frame unless the
 * request says otherwise, whatever [acquisition] dark-frame says: the open field's lit level
 * (calibrate_set.c) is only known above the sensor's offset and the ambient light. */
static void
handle_calibrate (DsService *svc, DsConnection *conn, DsRequest *req)
{
  static const char *const keys[] = { "phases", "averages", "exposure_us", "gain_db", "dark_frame",
                                      "period_px", "pixel_aperture", "progress", NULL };
  g_autoptr (GError) error = NULL;
  DsCaptureSettings s;
  DsCalibrateRequest cr = { 0 };
  gboolean progress;
  if (!ds_request_check_keys (req, keys, &error) || !settings_from_request (svc, req, &s, &error) ||
      !ds_request_get_double (req, "period_px", 2.0, 1e5, 0.0, &cr.period_px, &error) ||
      !ds_request_get_double (req, "pixel_aperture", 0.01, 1.0, 0.0, &cr.pixel_aperture, &error) ||
      !ds_request_get_bool (req, "progress", FALSE, &progress, &error) ||
      !ds_request_get_bool (req, "dark_frame", TRUE, &s.dark_frame, &error)) {
    ds_server_reply_error (svc->server, conn, req->id, error);
    return;
  }
  if (s.phases < 3 || s.phases * s.averages > DS_SAVE_PHASES_MAX_FRAMES) {
    g_set_error (&error, DS_PROTOCOL_ERROR, DS_PROTOCOL_ERROR_BAD_ARGUMENT,
                 "calibrate: \"phases\" must be at least 3 (the harmonic gain needs three), and phases x "
                 "averages at most %u (got %u x %u)",
                 DS_SAVE_PHASES_MAX_FRAMES, s.phases, s.averages);
    ds_server_reply_error (svc->server, conn, req->id, error);
    return;
  }
  s.save_phases = TRUE;
  s.verify_phase = FALSE;
  s.estimator = DS_ESTIMATOR_SINE;
  s.target_error = 0;
  s.time_budget_ms = 0;
  s.single_frame = FALSE; /* calibration reads the pattern from a phase set's raw frames */
  guint64 tag = ++svc->next_tag;
  if (!ds_sequencer_capture (svc->sequencer, &s, tag)) {
    reply_not_queued (svc, conn, req);
    return;
  }
  PendingCapture *p = pending_add (svc, conn, req, tag);
  p->cancellable = TRUE;
  p->progress = progress;
  p->calibrate = TRUE;
  p->calibration = cr;
  p->calibrate_settings = s;
}

/* Per-frame results keep one frame per phase in their sliding window: averaging M frames per
 * phase would need M frames of every phase in it, which is a set again. */
static gboolean
results_mode_fits (const DsCaptureSettings *s, gboolean per_frame, GError **error)
{
  if (per_frame && s->averages > 1) {
    g_set_error (error, DS_PROTOCOL_ERROR, DS_PROTOCOL_ERROR_BAD_ARGUMENT,
                 "\"results\": per-frame needs averages = 1 (got %u): the sliding window holds one frame per "
                 "phase and does not average", s->averages);
    return FALSE;
  }
  if (per_frame && s->single_frame) {
    /* A single-frame result already comes from every frame; a window of phases has nothing to
     * add to it and the two would disagree on which frames a result holds. */
    g_set_error (error, DS_PROTOCOL_ERROR, DS_PROTOCOL_ERROR_BAD_ARGUMENT,
                 "\"results\": per-frame and \"single_frame\" exclude each other: a single-frame "
                 "result is already one per frame");
    return FALSE;
  }
  return TRUE;
}

static void
handle_start (DsService *svc, DsConnection *conn, DsRequest *req)
{
  static const char *const keys[] = { "phases", "averages", "exposure_us", "gain_db", "estimator",
                                      "dark_frame", "verify_phase", "target_error", "time_budget_ms", "speed_px_s",
                                      "save_phases", "results", "single_frame", NULL };
  static const char *const modes[] = { "per-set", "per-frame", NULL };
  g_autoptr (GError) error = NULL;
  DsCaptureSettings s;
  const char *results = NULL;
  if (!ds_request_check_keys (req, keys, &error) || !settings_from_request (svc, req, &s, &error) ||
      !ds_request_get_choice (req, "results", modes, svc->config->results, &results, &error) ||
      !results_mode_fits (&s, strcmp (results, "per-frame") == 0, &error)) {
    ds_server_reply_error (svc->server, conn, req->id, error);
    return;
  }
  s.per_frame = strcmp (results, "per-frame") == 0;
  /* Without arguments continuous mode follows the configuration (and its reloads). */
  ds_sequencer_start (svc->sequencer, json_object_get_size (req->args) ? &s : NULL);
  svc->in_run = TRUE;
  g_autoptr (JsonNode) body = ds_capture_settings_to_json (&s);
  /* Said in words: a stream whose devices are not ready fails every set, and a reply that only
   * echoed the settings read as success. */
  g_autofree char *not_ready = ds_service_not_ready_reason (svc);
  json_object_set_string_member (
    json_node_get_object (body), "message",
    !not_ready ? "continuous acquisition started"
    : !svc->ready ? "continuous acquisition starts once the devices are open"
                  : "continuous acquisition started, but the devices are not ready: its sets fail until they are");
  if (not_ready)
    json_object_set_string_member (json_node_get_object (body), "not_ready_reason", not_ready);
  ds_service_reply_ok (svc, conn, req->id, body);
}

static void
handle_stop (DsService *svc, DsConnection *conn, DsRequest *req)
{
  if (!no_arguments (svc, conn, req))
    return;
  ds_sequencer_stop (svc->sequencer);
  /* The set in progress still completes: it goes into the run file, which closes after it. */
  gboolean was_running = svc->in_run;
  svc->in_run = FALSE;
  if (svc->spool)
    ds_spool_end_run (svc->spool);
  /* Said in words as well as a flag: whether acquisition was running, and what stops it. */
  g_autoptr (JsonBuilder) b = ds_json_object_begin ();
  ds_json_add_bool (b, "was_running", was_running);
  ds_json_add_string (b, "message", was_running ? "continuous acquisition stops after the set in progress"
                                                : "continuous acquisition was not running");
  g_autoptr (JsonNode) body = ds_json_object_end (b);
  ds_service_reply_ok (svc, conn, req->id, body);
}

/* The cancel's reply: how many requests it answered `cancelled`, whether continuous
 * acquisition stopped, and the state it left. */
void
ds_service_reply_cancel (DsService *svc, DsConnection *conn, JsonNode *id, guint cancelled, gboolean stream_stopped)
{
  DsSequencerStatus st;
  ds_sequencer_get_status (svc->sequencer, &st);
  g_autoptr (JsonBuilder) b = ds_json_object_begin ();
  ds_json_add_uint (b, "cancelled", cancelled);
  ds_json_add_bool (b, "stream_stopped", stream_stopped);
  ds_json_add_string (b, "state", ds_sequencer_state_name (st.state));
  g_autoptr (JsonNode) body = ds_json_object_end (b);
  ds_service_reply_ok (svc, conn, id, body);
}

/* Stops all acquisition work, whoever asked for it (docs/protocol.md, `cancel`): the set running
 * and every capture, dark and calibrate waiting are answered `cancelled`, continuous mode stops.
 * One rig, one acquisition thread: there is no one else's work to spare, and the reply counts
 * what it cancelled so that no cancel goes unnoticed. Answered once the acquisition thread took
 * it (after the `cancelled` replies), so a client that gets the reply finds the daemon idle. */
static void
handle_cancel (DsService *svc, DsConnection *conn, DsRequest *req)
{
  if (!no_arguments (svc, conn, req))
    return;
  guint cancelled = 0;
  GHashTableIter it;
  gpointer value;
  g_hash_table_iter_init (&it, svc->pending);
  while (g_hash_table_iter_next (&it, NULL, &value))
    cancelled += ((PendingCapture *) value)->cancellable;
  gboolean stream_stopped = svc->in_run;
  svc->in_run = FALSE;
  if (svc->spool)
    ds_spool_end_run (svc->spool);
  svc->cancels++;
  /* Also while the devices open: the requests waiting for them are answered `cancelled`. */
  guint64 tag = ++svc->next_tag;
  PendingCapture *p = pending_add (svc, conn, req, tag);
  p->cancel = TRUE;
  p->cancelled = cancelled;
  p->stream_stopped = stream_stopped;
  ds_sequencer_cancel (svc->sequencer, tag);
}

static void
handle_config (DsService *svc, DsConnection *conn, DsRequest *req)
{
  static const char *const keys[] = { "action", NULL };
  static const char *const actions[] = { "get", NULL };
  g_autoptr (GError) error = NULL;
  const char *action;
  if (!ds_request_check_keys (req, keys, &error) ||
      !ds_request_get_choice (req, "action", actions, "get", &action, &error)) {
    ds_server_reply_error (svc->server, conn, req->id, error);
    return;
  }
  g_autofree char *text = ds_service_effective_config_text (svc);
  g_autoptr (JsonBuilder) b = ds_json_object_begin ();
  ds_json_add_string (b, "path", svc->config_path);
  ds_json_add_string (b, "text", text);
  g_autoptr (JsonNode) body = ds_json_object_end (b);
  ds_service_reply_ok (svc, conn, req->id, body);
}

static void
handle_status (DsService *svc, DsConnection *conn, DsRequest *req)
{
  if (!no_arguments (svc, conn, req))
    return;
  g_autoptr (JsonNode) body = ds_service_status_to_json (svc);
  ds_service_reply_ok (svc, conn, req->id, body);
}

/* Every command the service answers; the server answers hello, subscribe and unsubscribe
 * itself (ds_server_add_own_commands). An unknown command's error lists both. */
static const struct {
  const char *cmd;
  void (*handle) (DsService *svc, DsConnection *conn, DsRequest *req);
} commands[] = {
  { "status", handle_status },   { "capture", handle_capture }, { "dark", handle_dark },
  { "start", handle_start },     { "stop", handle_stop },       { "config", handle_config },
  { "release", handle_release }, { "acquire", handle_acquire }, { "calibrate", handle_calibrate },
  { "cancel", handle_cancel },    { "set", ds_service_handle_set }, { "preview", ds_service_handle_preview },
};

/* "hello, subscribe, unsubscribe, status, capture, ...": what the daemon answers. */
static char *
command_list (void)
{
  g_autoptr (GPtrArray) names = g_ptr_array_new ();
  ds_server_add_own_commands (names);
  for (guint i = 0; i < G_N_ELEMENTS (commands); i++)
    g_ptr_array_add (names, (gpointer) commands[i].cmd);
  g_ptr_array_add (names, NULL);
  return g_strjoinv (", ", (char **) names->pdata);
}

void
ds_service_on_request (DsServer *server, DsConnection *conn, DsRequest *req, gpointer user_data)
{
  DsService *svc = user_data;
  for (guint i = 0; i < G_N_ELEMENTS (commands); i++)
    if (strcmp (req->cmd, commands[i].cmd) == 0) {
      commands[i].handle (svc, conn, req);
      return;
    }
  g_autofree char *known = command_list ();
  g_autoptr (GError) error = g_error_new (DS_PROTOCOL_ERROR, DS_PROTOCOL_ERROR_UNKNOWN_COMMAND,
                                          "unknown command \"%s\" (commands: %s)", req->cmd, known);
  ds_server_reply_error (server, conn, req->id, error);
}
