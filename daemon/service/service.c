#include "daemon/service/service.h"

#include "build_info.h"
#include "daemon/operating/data_dir.h"

#include <math.h>
#include <string.h>
#include <systemd/sd-daemon.h>

#include "daemon/output/result_files.h"
#include "daemon/output/result_meta.h"
#include "daemon/acquire/capture_settings.h"
#include "proc/phase_check.h"
#include "daemon/acquire/devices.h"
#include "daemon/service/http_server.h"
#include "daemon/service/live_view.h"
#include "daemon/service/metrics.h"
#include "daemon/service/provenance.h"
#include "daemon/service/preflight.h"
#include "daemon/operating/operating_point.h"
#include "daemon/protocol/protocol.h"
#include "daemon/service/calibrate_set.h"
#include "daemon/acquire/sequencer.h"
#include "daemon/service/server.h"
#include "daemon/service/spool.h"
#include "daemon/acquire/status_dark.h"
#include "daemon/service/wire_error.h"
#include "daemon/service/token.h"

/* A capture or dark request waiting for the acquisition thread. */
typedef struct {
  guint64 tag;
  DsConnection *conn; /* ref + hold */
  JsonNode *id;
  DsOutputFormat format;
  gboolean extrema;
  guint outputs;      /* bit i: payload i of the result's payload set */
  gboolean progress;
  gboolean save_phases; /* the raw frames go back with the reply */
  gboolean calibrate;   /* a calibrate request: the reply is the set's calibration */
  DsCalibrateRequest calibration;
  DsCaptureSettings calibrate_settings; /* the first set's, for a second period */
  gboolean calibrate_second;            /* this is the set at the second period (calibrate_set.h) */
  DsCalibration calibrate_first;        /* ... and the first set's calibration */
  guint64 calibrate_first_set;
} PendingCapture;

typedef struct {
  DsConfig *config;
} OpenData;

struct DsService {
  OpenData open_data;
  DsConfig *config;
  char *config_path;
  DsServiceOptions options;
  char *scene_override;
  GMainLoop *loop;
  DsServer *server;
  DsSequencer *sequencer;
  DsSpool *spool;
  char *socket_path;
  GHashTable *pending;   /* tag -> PendingCapture */
  guint64 next_tag;
  gboolean ready;
  gboolean devices_failed;
  guint watchdog_source;
  guint64 watchdog_usec;
  gint64 started_us;
  guint64 results_published;
  char config_sha256[65];    /* of the effective configuration: in every result */
  DsMetrics *metrics;
  DsLiveView *live;          /* with http: NULL when [http] listen is off */
  DsHttpServer *http;
  gboolean in_run;           /* continuous acquisition started and not stopped */
  DsOperatingModel *model;  /* NULL when no model file could be read (automatic captures fail) */
  char *model_error;
  char *model_path;         /* the file the model was (or failed to be) read from */
};

static void
pending_capture_free (gpointer data)
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

/* ---- devices are opened on the acquisition thread from a copy of the configuration ---- */

static DsDevices *
open_devices (gpointer data, GError **error)
{
  OpenData *od = data;
  return ds_devices_open (od->config, error);
}

/* ---- replies ---- */

static const char *const output_names[] = { "transmissive", "scattered", "mask", "max", "min", "mean" };

static void
reply_result (DsService *svc, PendingCapture *p, DsResult *result)
{
  const DsPayloadInfo *infos;
  GBytes *const *bytes;
  guint n = ds_result_payloads (result, p->format, p->extrema, &infos, &bytes);
  g_autoptr (GArray) sel_infos = g_array_new (FALSE, FALSE, sizeof (DsPayloadInfo));
  g_autoptr (GPtrArray) sel_bytes = g_ptr_array_new ();
  for (guint i = 0; i < n; i++)
    for (guint j = 0; j < G_N_ELEMENTS (output_names); j++)
      if (strcmp (infos[i].name, output_names[j]) == 0 && (p->outputs & (1u << j))) {
        g_array_append_val (sel_infos, infos[i]);
        g_ptr_array_add (sel_bytes, bytes[i]);
      }
  if (p->save_phases) {
    guint r = ds_result_raw_payloads (result, &infos, &bytes);
    g_array_append_vals (sel_infos, infos, r);
    for (guint i = 0; i < r; i++)
      g_ptr_array_add (sel_bytes, bytes[i]);
  }
  g_autoptr (JsonNode) meta = ds_result_to_json (result);
  ds_server_reply_ok (svc->server, p->conn, p->id, meta, (const DsPayloadInfo *) sel_infos->data,
                      (GBytes *const *) sel_bytes->pdata, sel_infos->len);
}

static void
reply_calibration_error (DsService *svc, PendingCapture *p, const GError *error)
{
  g_autoptr (GError) wire = ds_wire_error_new (error);
  ds_server_reply_error (svc->server, p->conn, p->id, wire);
}

/* The first set's calibration, with the second period's when it came: black level and harmonic
 * gain told apart (calibrate_set.h); second_error says why not when it was tried. */
static void
reply_calibration_pair (DsService *svc, PendingCapture *p, DsResult *second, const char *second_error)
{
  DsCalibration *c = &p->calibrate_first;
  g_autoptr (GError) error = NULL;
  DsCalibration at_second;
  if (second && (!ds_calibrate_measure (second, &p->calibration, 2 * c->period_px, &at_second, &error) ||
                 !ds_calibration_add_second_period (c, &at_second, p->calibration.pixel_aperture, &error)))
    second_error = error->message;
  if (second_error)
    g_message ("calibrate: the black level of the sine stripes is assumed, not measured: the set at twice the "
               "period: %s", second_error);
  g_autoptr (JsonNode) body = ds_calibrate_reply (p->calibrate_first_set, c, second ? ds_result_set_id (second) : 0,
                                                  second_error);
  ds_server_reply_ok (svc->server, p->conn, p->id, body, NULL, NULL, 0);
}

/* A calibrate request's set came. Sine stripes whose black level one period cannot tell
 * (proc/calibration_sine.h) get a second set at twice the period, under a new tag that p moves
 * to: TRUE then, and the reply waits for it. */
static gboolean
calibration_step (DsService *svc, PendingCapture *p, DsResult *result)
{
  g_autoptr (GError) error = NULL;
  if (p->calibrate_second) {
    reply_calibration_pair (svc, p, result, NULL);
    return FALSE;
  }
  if (!ds_calibrate_measure (result, &p->calibration, 0, &p->calibrate_first, &error)) {
    reply_calibration_error (svc, p, error);
    return FALSE;
  }
  p->calibrate_first_set = ds_result_set_id (result);
  if (!ds_calibration_wants_second_period (&p->calibrate_first)) {
    reply_calibration_pair (svc, p, NULL, NULL);
    return FALSE;
  }
  DsCaptureSettings s = p->calibrate_settings;
  s.period_override_px = 2 * ds_result_settings (result)->period_px;
  guint64 tag = ++svc->next_tag;
  if (!ds_sequencer_capture (svc->sequencer, &s, tag)) {
    reply_calibration_pair (svc, p, NULL, "too many captures queued");
    return FALSE;
  }
  g_hash_table_steal (svc->pending, &p->tag);
  p->tag = tag;
  p->calibrate_second = TRUE;
  g_hash_table_insert (svc->pending, &p->tag, p);
  return TRUE;
}

static void
send_progress (DsService *svc, PendingCapture *p, guint phase, guint n)
{
  (void) svc;
  if (!p->progress || ds_connection_is_closed (p->conn))
    return;
  g_autoptr (JsonBuilder) b = json_builder_new ();
  json_builder_begin_object (b);
  json_builder_set_member_name (b, "id");
  json_builder_add_value (b, p->id ? json_node_copy (p->id) : json_node_new (JSON_NODE_NULL));
  json_builder_set_member_name (b, "phase");
  json_builder_add_int_value (b, phase);
  json_builder_set_member_name (b, "phases");
  json_builder_add_int_value (b, n);
  json_builder_end_object (b);
  g_autoptr (JsonNode) body = json_builder_get_root (b);
  gsize len;
  g_autofree char *line = ds_event_build ("progress", 0, body, NULL, 0, &len);
  g_autoptr (GBytes) bytes = g_bytes_new (line, len);
  ds_connection_send (p->conn, bytes, NULL, 0, TRUE);
}

static void
notify_status (DsService *svc, const char *text)
{
  (void) svc;
  sd_notifyf (0, "STATUS=%s", text);
}

static void
publish_result (DsService *svc, DsResult *result)
{
  const DsPayloadInfo *infos;
  GBytes *const *bytes;
  guint n = ds_result_payloads (result, DS_OUTPUT_F32, FALSE, &infos, &bytes);
  g_autoptr (JsonNode) meta = ds_result_to_json (result);
  ds_server_publish (svc->server, "result", meta, infos, bytes, n);
  svc->results_published++;
  gint64 last_frame = ds_json_path_int (meta, "monotonic_us.last_frame", 0);
  if (last_frame > 0)
    ds_metrics_observe_result (svc->metrics, (double) (g_get_monotonic_time () - last_frame) / 1e6);
  if (svc->live)
    ds_live_view_on_result (svc->live, result);
  /* Queued to the spool's writer thread: a slow disk never delays the loop. */
  if (svc->spool && !ds_spool_record (svc->spool, result, svc->in_run))
    g_warning ("spool: set %" G_GUINT64_FORMAT " not recorded: the disk is behind", ds_result_set_id (result));
}

static void
on_sequencer_event (const DsSequencerEvent *ev, gpointer user_data)
{
  DsService *svc = user_data;
  PendingCapture *p = ev->tag ? g_hash_table_lookup (svc->pending, &ev->tag) : NULL;
  switch (ev->kind) {
  case DS_SEQUENCER_EVENT_READY:
    if (ev->error) {
      g_critical ("devices: %s", ev->error->message);
      sd_notifyf (0, "STATUS=devices failed: %s", ev->error->message);
      svc->devices_failed = TRUE;
      /* Without devices the service is of no use; systemd restarts it (Restart=on-failure). */
      g_main_loop_quit (svc->loop);
      return;
    }
    svc->ready = TRUE;
    g_message ("devices open: %s", ev->message);
    sd_notifyf (0, "READY=1\nSTATUS=ready: %s", ev->message);
    return;
  case DS_SEQUENCER_EVENT_PROGRESS:
    if (p)
      send_progress (svc, p, ev->phase, ev->n_phases);
    return;
  case DS_SEQUENCER_EVENT_RESULT: {
    DsSequencerStatus status;
    ds_sequencer_get_status (svc->sequencer, &status);
    DsResultProvenance prov;
    ds_provenance_fill (&prov, svc->config, svc->config_sha256, &status);
    ds_result_set_provenance (ev->result, &prov);
    g_autofree char *st = g_strdup_printf ("set %" G_GUINT64_FORMAT " done",
                                           ds_result_set_id (ev->result));
    notify_status (svc, st);
    gboolean awaits_second = FALSE;
    if (p && p->calibrate)
      awaits_second = calibration_step (svc, p, ev->result);
    else if (p)
      reply_result (svc, p, ev->result);
    publish_result (svc, ev->result);
    if (awaits_second)
      return;
    break;
  }
  case DS_SEQUENCER_EVENT_FAILED: {
    g_warning ("phase set failed: %s", ev->error->message);
    notify_status (svc, "last set failed");
    g_autoptr (GError) wire = ds_wire_error_new (ev->error);
    /* an illuminator that cannot draw twice its period: the first set's calibration stands */
    if (p && p->calibrate_second)
      reply_calibration_pair (svc, p, NULL, ev->error->message);
    else if (p)
      ds_server_reply_error (svc->server, p->conn, p->id, wire);
    {
      g_autoptr (JsonBuilder) b = json_builder_new ();
      json_builder_begin_object (b);
      json_builder_set_member_name (b, "reason");
      json_builder_add_string_value (b, ev->error->message);
      json_builder_set_member_name (b, "code");
      json_builder_add_string_value (b, ds_protocol_error_name ((DsProtocolError) wire->code));
      json_builder_end_object (b);
      g_autoptr (JsonNode) body = json_builder_get_root (b);
      ds_server_publish (svc->server, "failed", body, NULL, NULL, 0);
    }
    break;
  }
  case DS_SEQUENCER_EVENT_DARK:
    if (p) {
      if (ev->error) {
        g_autoptr (GError) wire = ds_wire_error_new (ev->error);
        ds_server_reply_error (svc->server, p->conn, p->id, wire);
      } else {
        g_autoptr (JsonBuilder) b = json_builder_new ();
        json_builder_begin_object (b);
        json_builder_set_member_name (b, "dark_mean_dn");
        json_builder_add_double_value (b, ev->dark_mean_dn);
        json_builder_end_object (b);
        g_autoptr (JsonNode) body = json_builder_get_root (b);
        ds_server_reply_ok (svc->server, p->conn, p->id, body, NULL, NULL, 0);
      }
    }
    break;
  case DS_SEQUENCER_EVENT_CONTROL:
    if (ev->error)
      g_warning ("%s", ev->error->message);
    else
      g_message ("%s", ev->message);
    if (p && ev->error) {
      g_autoptr (GError) wire = ds_wire_error_new (ev->error);
      ds_server_reply_error (svc->server, p->conn, p->id, wire);
    } else if (p) {
      DsSequencerStatus st;
      ds_sequencer_get_status (svc->sequencer, &st);
      g_autoptr (JsonBuilder) b = json_builder_new ();
      json_builder_begin_object (b);
      json_builder_set_member_name (b, "state");
      json_builder_add_string_value (b, ds_sequencer_state_name (st.state));
      json_builder_set_member_name (b, "message");
      json_builder_add_string_value (b, ev->message);
      json_builder_end_object (b);
      g_autoptr (JsonNode) body = json_builder_get_root (b);
      ds_server_reply_ok (svc->server, p->conn, p->id, body, NULL, NULL, 0);
    }
    break;
  case DS_SEQUENCER_EVENT_DEVICE:
    g_message ("%s", ev->message);
    notify_status (svc, ev->message);
    {
      g_autoptr (JsonBuilder) b = json_builder_new ();
      json_builder_begin_object (b);
      json_builder_set_member_name (b, "message");
      json_builder_add_string_value (b, ev->message);
      json_builder_end_object (b);
      g_autoptr (JsonNode) body = json_builder_get_root (b);
      ds_server_publish (svc->server, "device", body, NULL, NULL, 0);
    }
    return;
  }
  if (p)
    g_hash_table_remove (svc->pending, &ev->tag);
}

/* ---- requests ---- */

#define DS_SAVE_PHASES_MAX_FRAMES 256

/* Capture settings from the defaults overlaid with the request's arguments. */
static gboolean
settings_from_request (DsService *svc, const DsRequest *req, DsCaptureSettings *s, GError **error)
{
  ds_capture_settings_from_config (s, svc->config);
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
    while (name && j < G_N_ELEMENTS (output_names) && strcmp (name, output_names[j]) != 0)
      j++;
    if (!name || j == G_N_ELEMENTS (output_names)) {
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
  g_hash_table_insert (svc->pending, &p->tag, p);
  return p;
}

/* A request the sequencer did not take: its queue is full, or the devices are not open yet. */
static void
reply_not_queued (DsService *svc, DsConnection *conn, DsRequest *req)
{
  g_autoptr (GError) error = g_error_new (DS_PROTOCOL_ERROR, DS_PROTOCOL_ERROR_BUSY, "%s: %s", req->cmd,
                                          svc->ready ? "too many requests queued" : "the devices are not open yet");
  ds_server_reply_error (svc->server, conn, req->id, error);
}

static void
handle_capture (DsService *svc, DsConnection *conn, DsRequest *req)
{
  static const char *const keys[] = { "phases", "averages", "exposure_us", "gain_db", "estimator",
                                      "dark_frame", "verify_phase", "format", "outputs",
                                      "progress", "target_error", "time_budget_ms", "save_phases", NULL };
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
  if (!svc->ready) {
    g_set_error (&error, DS_PROTOCOL_ERROR, DS_PROTOCOL_ERROR_BUSY, "capture: the devices are not open yet");
    ds_server_reply_error (svc->server, conn, req->id, error);
    return;
  }
  guint64 tag = ++svc->next_tag;
  if (!ds_sequencer_capture (svc->sequencer, &s, tag)) {
    g_set_error (&error, DS_PROTOCOL_ERROR, DS_PROTOCOL_ERROR_BUSY,
                 "capture: too many captures queued; try again later");
    ds_server_reply_error (svc->server, conn, req->id, error);
    return;
  }
  PendingCapture *p = pending_add (svc, conn, req, tag);
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
  if (!svc->ready || !ds_sequencer_dark (svc->sequencer, &s, tag)) {
    reply_not_queued (svc, conn, req);
    return;
  }
  pending_add (svc, conn, req, tag);
}

/* release / acquire: the devices closed for another program (arv-viewer) and opened again. */
static void
handle_control (DsService *svc, DsConnection *conn, DsRequest *req, gboolean release)
{
  static const char *const keys[] = { NULL };
  g_autoptr (GError) error = NULL;
  if (!ds_request_check_keys (req, keys, &error)) {
    ds_server_reply_error (svc->server, conn, req->id, error);
    return;
  }
  guint64 tag = ++svc->next_tag;
  gboolean queued = svc->ready && (release ? ds_sequencer_release (svc->sequencer, tag)
                                           : ds_sequencer_acquire (svc->sequencer, tag));
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
 * period or duty would fail. The set is published as any other. */
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
      !ds_request_get_bool (req, "progress", FALSE, &progress, &error)) {
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
  if (!svc->ready) {
    g_set_error (&error, DS_PROTOCOL_ERROR, DS_PROTOCOL_ERROR_BUSY, "calibrate: the devices are not open yet");
    ds_server_reply_error (svc->server, conn, req->id, error);
    return;
  }
  guint64 tag = ++svc->next_tag;
  if (!ds_sequencer_capture (svc->sequencer, &s, tag)) {
    g_set_error (&error, DS_PROTOCOL_ERROR, DS_PROTOCOL_ERROR_BUSY,
                 "calibrate: too many captures queued; try again later");
    ds_server_reply_error (svc->server, conn, req->id, error);
    return;
  }
  PendingCapture *p = g_new0 (PendingCapture, 1);
  p->tag = tag;
  p->conn = ds_connection_ref (conn);
  ds_connection_hold (conn);
  p->id = req->id ? json_node_copy (req->id) : NULL;
  p->progress = progress;
  p->calibrate = TRUE;
  p->calibration = cr;
  p->calibrate_settings = s;
  g_hash_table_insert (svc->pending, &p->tag, p);
}

static void
handle_start (DsService *svc, DsConnection *conn, DsRequest *req)
{
  static const char *const keys[] = { "phases", "averages", "exposure_us", "gain_db", "estimator",
                                      "dark_frame", "verify_phase", "target_error", "time_budget_ms",
                                      "save_phases", NULL };
  g_autoptr (GError) error = NULL;
  DsCaptureSettings s;
  if (!ds_request_check_keys (req, keys, &error) || !settings_from_request (svc, req, &s, &error)) {
    ds_server_reply_error (svc->server, conn, req->id, error);
    return;
  }
  /* Without arguments continuous mode follows the configuration (and its reloads). */
  ds_sequencer_start (svc->sequencer, json_object_get_size (req->args) ? &s : NULL);
  svc->in_run = TRUE;
  g_autoptr (JsonNode) body = ds_capture_settings_to_json (&s);
  ds_server_reply_ok (svc->server, conn, req->id, body, NULL, NULL, 0);
}

static void
handle_stop (DsService *svc, DsConnection *conn, DsRequest *req)
{
  static const char *const keys[] = { NULL };
  g_autoptr (GError) error = NULL;
  if (!ds_request_check_keys (req, keys, &error)) {
    ds_server_reply_error (svc->server, conn, req->id, error);
    return;
  }
  ds_sequencer_stop (svc->sequencer);
  /* The set in progress still completes: it goes into the run file, which closes after it. */
  gboolean was_running = svc->in_run;
  svc->in_run = FALSE;
  if (svc->spool)
    ds_spool_end_run (svc->spool);
  /* Said in words: a bare {} left a user wondering whether anything was running or stopped. */
  g_autoptr (JsonBuilder) b = json_builder_new ();
  json_builder_begin_object (b);
  json_builder_set_member_name (b, "was_running");
  json_builder_add_boolean_value (b, was_running);
  json_builder_set_member_name (b, "message");
  json_builder_add_string_value (b, was_running ? "continuous acquisition stops after the set in progress"
                                                : "continuous acquisition was not running");
  json_builder_end_object (b);
  g_autoptr (JsonNode) body = json_builder_get_root (b);
  ds_server_reply_ok (svc->server, conn, req->id, body, NULL, NULL, 0);
}

/* The configuration in effect: the file with the command line's overrides (--socket, --tcp;
 * --scene is already in svc->config), so that what is printed (and hashed into every result) is
 * what the daemon uses. */
static char *
effective_config_text (DsService *svc)
{
  g_autoptr (DsConfig) effective = ds_config_copy (svc->config);
  const char *socket_in_use = svc->socket_path ? svc->socket_path : svc->options.socket_path;
  if (socket_in_use) {
    g_free (effective->socket_path);
    effective->socket_path = g_strdup (socket_in_use);
  }
  if (svc->options.tcp_listen) {
    g_free (effective->tcp_listen);
    effective->tcp_listen = g_strdup (svc->options.tcp_listen);
  }
  return ds_config_to_data (effective);
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
  g_autofree char *text = effective_config_text (svc);
  g_autoptr (JsonBuilder) b = json_builder_new ();
  json_builder_begin_object (b);
  json_builder_set_member_name (b, "path");
  if (svc->config_path)
    json_builder_add_string_value (b, svc->config_path);
  else
    json_builder_add_null_value (b);
  json_builder_set_member_name (b, "text");
  json_builder_add_string_value (b, text);
  json_builder_end_object (b);
  g_autoptr (JsonNode) body = json_builder_get_root (b);
  ds_server_reply_ok (svc->server, conn, req->id, body, NULL, NULL, 0);
}

static void
add_uint (JsonBuilder *b, const char *k, guint64 v)
{
  json_builder_set_member_name (b, k);
  json_builder_add_int_value (b, (gint64) v);
}

static void
add_string (JsonBuilder *b, const char *k, const char *v)
{
  json_builder_set_member_name (b, k);
  json_builder_add_string_value (b, v);
}

static JsonNode *
status_to_json (DsService *svc)
{
  DsSequencerStatus st;
  ds_sequencer_get_status (svc->sequencer, &st);
  DsServerStats ss;
  ds_server_get_stats (svc->server, &ss);
  g_autoptr (JsonBuilder) b = json_builder_new ();
  json_builder_begin_object (b);
  add_string (b, "version", DS_VERSION);
  add_string (b, "git", DS_GIT_DESCRIBE);
  ds_json_add_double_or_null (b, "uptime_s", (double) (g_get_monotonic_time () - svc->started_us) / 1e6);
  add_string (b, "state", ds_sequencer_state_name (st.state));
  /* Ready: devices open, the configured settings taken, no device being reconnected; else
   * the reason, naming the setting and what the device allows. */
  g_autofree char *not_ready = NULL;
  if (!svc->ready)
    not_ready = st.state == DS_SEQUENCER_STATE_FAILED ? g_strdup_printf ("devices failed to open: %s", st.last_error)
                                                  : g_strdup ("devices are opening");
  else if (st.state == DS_SEQUENCER_STATE_RECONNECTING)
    not_ready = g_strdup_printf ("reconnecting: %s", st.last_error);
  else if (!st.settings_ok)
    not_ready = g_strdup_printf ("devices refuse the configured settings: %s", st.settings_error);
  json_builder_set_member_name (b, "ready");
  json_builder_add_boolean_value (b, not_ready == NULL);
  json_builder_set_member_name (b, "not_ready_reason");
  if (not_ready)
    json_builder_add_string_value (b, not_ready);
  else
    json_builder_add_null_value (b);
  json_builder_set_member_name (b, "continuous");
  json_builder_add_boolean_value (b, st.continuous);
  add_uint (b, "pending", st.pending);
  add_uint (b, "sets_done", st.sets_done);
  add_uint (b, "sets_failed", st.sets_failed);
  add_string (b, "last_error", st.last_error);
  json_builder_set_member_name (b, "has_dark");
  json_builder_add_boolean_value (b, st.has_dark);
  json_builder_set_member_name (b, "dark");
  json_builder_add_value (b, ds_status_dark_to_json (&st, g_get_real_time ()));
  ds_json_add_double_or_null (b, "phase_offset_cycles", st.phase_offset_cycles);
  json_builder_set_member_name (b, "frames");
  json_builder_add_value (b, ds_frame_counters_to_json (&st.frames));
  /* Without a model, captures with target_error/time_budget_ms are refused: say so up front. */
  json_builder_set_member_name (b, "operating_model");
  json_builder_begin_object (b);
  json_builder_set_member_name (b, "loaded");
  json_builder_add_boolean_value (b, svc->model != NULL);
  add_string (b, "path", svc->model_path ? svc->model_path : "");
  if (!svc->model)
    add_string (b, "error", svc->model_error ? svc->model_error : "not loaded");
  json_builder_end_object (b);
  json_builder_set_member_name (b, "stage_mean_ms");
  json_builder_begin_object (b);
  for (guint i = 0; i < DS_STAGE_N; i++)
    ds_json_add_double_or_null (b, ds_stage_name (i),
                                st.stages[i].count ? st.stages[i].total_ms / st.stages[i].count : NAN);
  json_builder_end_object (b);
  json_builder_set_member_name (b, "devices");
  json_builder_begin_object (b);
  add_string (b, "backends", st.devices);
  json_builder_set_member_name (b, "camera");
  json_builder_begin_object (b);
  add_string (b, "vendor", st.camera_info.vendor);
  add_string (b, "model", st.camera_info.model);
  add_string (b, "serial", st.camera_info.serial);
  add_string (b, "address", st.camera_info.address);
  add_uint (b, "width", st.camera_info.sensor_width);
  add_uint (b, "height", st.camera_info.sensor_height);
  json_builder_set_member_name (b, "connected");
  json_builder_add_boolean_value (b, st.camera_info.connected);
  add_uint (b, "completed", st.camera_stats.completed);
  add_uint (b, "failures", st.camera_stats.failures);
  add_uint (b, "missing_packets", st.camera_stats.missing_packets);
  add_uint (b, "resend_requests", st.camera_stats.resend_requests);
  add_uint (b, "timeouts", st.camera_stats.timeouts);
  add_uint (b, "ids_skipped", st.camera_stats.ids_skipped);
  add_uint (b, "reconnects", st.camera_stats.reconnects);
  add_uint (b, "unfilled_buffers", st.camera_stats.unfilled_buffers);
  json_builder_end_object (b);
  json_builder_set_member_name (b, "illuminator");
  json_builder_begin_object (b);
  json_builder_set_member_name (b, "ready");
  json_builder_add_boolean_value (b, st.illuminator.ready);
  json_builder_set_member_name (b, "fault");
  json_builder_add_boolean_value (b, st.illuminator.fault);
  json_builder_set_member_name (b, "over_temperature");
  json_builder_add_boolean_value (b, st.illuminator.over_temperature);
  json_builder_set_member_name (b, "applied_phase");
  json_builder_add_int_value (b, st.illuminator.applied_phase);
  add_uint (b, "apply_count", st.illuminator.apply_count);
  ds_json_add_double_or_null (b, "temperature_c", st.illuminator.temperature_c);
  /* Whether a second stripe period can be asked for (docs/registers.md, CAPABILITIES). */
  json_builder_set_member_name (b, "period_adjustable");
  json_builder_add_boolean_value (b, st.illuminator.period_adjustable);
  ds_json_add_double_or_null (b, "period_min_px", st.illuminator.period_min_px);
  ds_json_add_double_or_null (b, "period_max_px", st.illuminator.period_max_px);
  /* Retried requests slow the sets without failing them: where they went is said here. */
  add_uint (b, "failed_attempts", st.illuminator.failed_attempts);
  add_uint (b, "failed_accesses", st.illuminator.failed_accesses);
  add_string (b, "last_link_problem", st.illuminator.last_link_problem);
  json_builder_end_object (b);
  json_builder_end_object (b);
  json_builder_set_member_name (b, "clients");
  json_builder_begin_object (b);
  add_uint (b, "connected", ss.clients);
  add_uint (b, "tcp", ss.tcp_clients);
  add_uint (b, "subscribers", ss.subscribers);
  add_uint (b, "accepted", ss.accepted);
  add_uint (b, "refused", ss.refused);
  add_uint (b, "evicted", ss.evicted);
  add_uint (b, "timed_out", ss.timed_out);
  add_uint (b, "requests", ss.requests);
  add_uint (b, "bad_requests", ss.bad_requests);
  add_uint (b, "results_published", svc->results_published);
  add_uint (b, "results_dropped", ss.dropped);
  add_uint (b, "queued_bytes", ss.queued_bytes);
  json_builder_end_object (b);
  if (svc->http) {
    DsLiveStats ls;
    ds_live_view_get_stats (svc->live, &ls);
    json_builder_set_member_name (b, "http");
    json_builder_begin_object (b);
    add_string (b, "url", ds_http_server_url (svc->http));
    add_uint (b, "live_clients", ls.clients);
    add_uint (b, "live_updates_sent", ls.sent);
    add_uint (b, "live_updates_superseded", ls.superseded);
    json_builder_end_object (b);
  }
  if (svc->spool) {
    DsSpoolStats sp;
    ds_spool_get_stats (svc->spool, &sp);
    json_builder_set_member_name (b, "spool");
    json_builder_begin_object (b);
    add_uint (b, "bytes", sp.bytes);
    add_uint (b, "sets_written", sp.sets_written);
    add_uint (b, "sets_removed", sp.sets_removed);
    add_uint (b, "errors", sp.errors);
    add_uint (b, "dropped", sp.dropped);
    add_uint (b, "pending", sp.pending);
    json_builder_set_member_name (b, "run_open");
    json_builder_add_boolean_value (b, sp.run_open);
    add_string (b, "last_error", sp.last_error);
    json_builder_end_object (b);
  }
  json_builder_end_object (b);
  return json_builder_get_root (b);
}

static JsonNode *
live_status (gpointer data)
{
  return status_to_json (data);
}

static char *
render_metrics (gpointer data)
{
  DsService *svc = data;
  DsSequencerStatus st;
  ds_sequencer_get_status (svc->sequencer, &st);
  DsServerStats ss;
  ds_server_get_stats (svc->server, &ss);
  DsSpoolStats sp;
  if (svc->spool)
    ds_spool_get_stats (svc->spool, &sp);
  DsLiveStats ls;
  ds_live_view_get_stats (svc->live, &ls);
  ds_http_server_get_stats (svc->http, &ls.http_requests, &ls.http_unauthorized);
  DsMetricsSources src = { .sequencer = &st, .server = &ss, .spool = svc->spool ? &sp : NULL, .live = &ls,
                           .results_published = svc->results_published,
                           .uptime_s = (double) (g_get_monotonic_time () - svc->started_us) / 1e6 };
  return ds_metrics_render (svc->metrics, &src);
}

/* The live view and /metrics, when [http] listen (or --http) asks for them (checked by preflight). */
static gboolean
start_http (DsService *svc, const DsPreflight *pf, GError **error)
{
  if (!pf->http_host)
    return TRUE;
  svc->live = ds_live_view_new (g_main_loop_get_context (svc->loop), svc->server, svc->config->http_live_fps,
                                live_status, svc);
  svc->http = ds_http_server_new (pf->http_host, pf->http_port, pf->http_token, svc->live, render_metrics, svc, error);
  if (!svc->http)
    return FALSE;
  ds_sequencer_set_frame_hook (svc->sequencer, ds_live_view_on_frame, svc->live);
  g_message ("live view and /metrics at %s", ds_http_server_url (svc->http));
  return TRUE;
}

static void
handle_status (DsService *svc, DsConnection *conn, DsRequest *req)
{
  static const char *const keys[] = { NULL };
  g_autoptr (GError) error = NULL;
  if (!ds_request_check_keys (req, keys, &error)) {
    ds_server_reply_error (svc->server, conn, req->id, error);
    return;
  }
  g_autoptr (JsonNode) body = status_to_json (svc);
  ds_server_reply_ok (svc->server, conn, req->id, body, NULL, NULL, 0);
}

static void
on_request (DsServer *server, DsConnection *conn, DsRequest *req, gpointer user_data)
{
  DsService *svc = user_data;
  static const struct {
    const char *cmd;
    void (*handle) (DsService *, DsConnection *, DsRequest *);
  } commands[] = {
    { "status", handle_status }, { "capture", handle_capture }, { "dark", handle_dark },
    { "start", handle_start },   { "stop", handle_stop },       { "config", handle_config },
    { "release", handle_release }, { "acquire", handle_acquire }, { "calibrate", handle_calibrate },
  };
  for (guint i = 0; i < G_N_ELEMENTS (commands); i++)
    if (strcmp (req->cmd, commands[i].cmd) == 0) {
      commands[i].handle (svc, conn, req);
      return;
    }
  g_autoptr (GError) error = g_error_new (DS_PROTOCOL_ERROR, DS_PROTOCOL_ERROR_UNKNOWN_COMMAND,
                                          "unknown command \"%s\" (commands: hello, status, capture, "
                                          "subscribe, unsubscribe, start, stop, dark, calibrate, config, release, acquire)",
                                          req->cmd);
  ds_server_reply_error (server, conn, req->id, error);
}

/* ---- watchdog: pinged only while the acquisition thread shows signs of life ---- */

static gboolean
watchdog_tick (gpointer data)
{
  DsService *svc = data;
  DsSequencerStatus st;
  ds_sequencer_get_status (svc->sequencer, &st);
  gint64 now = g_get_monotonic_time ();
  gint64 age = now - st.heartbeat_us;
  /* Alive: a recent sign of life, or inside a device call within that call's own bound (a
   * camera timing out, a reconnect). A call past its bound is a wedged driver: no ping, and
   * systemd restarts the service. */
  if ((guint64) age < svc->watchdog_usec / 2 || now < st.blocking_until_us)
    sd_notify (0, "WATCHDOG=1");
  else
    g_warning ("acquisition thread silent for %.1f s%s: not pinging the watchdog", (double) age / 1e6,
               st.blocking_until_us ? ", past the bound of the device call it is in" : "");
  return G_SOURCE_CONTINUE;
}

/* ---- lifecycle ---- */

static gboolean
start_listening (DsService *svc, const DsPreflight *pf, GError **error)
{
  guint adopted = 0;
  if (!svc->options.no_systemd_sockets) {
    adopted = ds_server_adopt_systemd_sockets (svc->server, error);
    if (*error)
      return FALSE;
  }
  if (adopted == 0) {
    const char *path = svc->config->socket_path; /* --socket already applied */
    g_autofree char *dir = g_path_get_dirname (path);
    g_mkdir_with_parents (dir, 0755);
    if (!ds_server_listen_unix (svc->server, path, svc->config->socket_mode, error))
      return FALSE;
    svc->socket_path = g_strdup (path);
  }
  if (pf->tcp_host && !ds_server_listen_tcp (svc->server, pf->tcp_host, pf->tcp_port, error))
    return FALSE;
  return TRUE;
}

static void
update_config_hash (DsService *svc)
{
  g_autofree char *text = effective_config_text (svc);
  g_autofree char *hash = ds_output_sha256_hex (text);
  g_strlcpy (svc->config_sha256, hash, sizeof svc->config_sha256);
}

static DsPreflightOverrides
overrides_of (const DsServiceOptions *options)
{
  return (DsPreflightOverrides) { .config_name = options->config_path,
                                  .socket_path = options->socket_path,
                                  .tcp_listen = options->tcp_listen,
                                  .scene_path = options->scene_path,
                                  .http_listen = options->http_listen };
}

DsService *
ds_service_new (DsConfig *config, const DsServiceOptions *options, GMainLoop *loop, GError **error)
{
  g_autoptr (DsConfig) owned = config;
  /* Exactly what `descatterd --check` runs: nothing is bound or opened before it passed. */
  DsPreflightOverrides ov = overrides_of (options);
  g_autoptr (DsPreflight) pf = ds_preflight_run (owned, &ov, error);
  if (!pf)
    return NULL;
  /* Freed by ds_service_free on any early return: it copes with a service half built. */
  g_autoptr (DsService) svc = g_new0 (DsService, 1);
  svc->options = *options;
  svc->config_path = g_strdup (options->config_path);
  svc->scene_override = g_strdup (options->scene_path);
  svc->options.config_path = svc->config_path;
  svc->options.scene_path = svc->scene_override;
  svc->socket_path = NULL;
  svc->loop = g_main_loop_ref (loop);
  svc->started_us = g_get_monotonic_time ();
  svc->metrics = ds_metrics_new ();
  svc->pending = g_hash_table_new_full (g_int64_hash, g_int64_equal, NULL, pending_capture_free);
  svc->config = g_steal_pointer (&pf->config);
  DsServerLimits limits = { .max_clients = svc->config->max_clients,
                            .max_tcp_clients = svc->config->max_tcp_clients,
                            .max_line = DS_PROTOCOL_MAX_LINE,
                            .max_queued_bytes = svc->config->max_queued_bytes,
                            .token = pf->token, /* copied by the server */
                            .idle_timeout_ms = svc->config->idle_timeout_ms,
                            .auth_timeout_ms = svc->config->auth_timeout_ms };
  svc->server = ds_server_new (&limits, on_request, svc);
  if (!start_listening (svc, pf, error))
    return NULL;
  if (svc->config->spool_dir && *svc->config->spool_dir) {
    guint kinds = 0;
    if (!ds_file_kinds_parse (svc->config->spool_formats, &kinds, error)) {
      g_prefix_error (error, "[daemon] spool-formats: ");
      return NULL;
    }
    if (svc->config->spool_save_phases)
      kinds |= DS_FILES_PHASES;
    svc->spool = ds_spool_new (svc->config->spool_dir, svc->config->spool_max_bytes, kinds,
                               svc->config->spool_max_pending, error);
    if (!svc->spool)
      return NULL;
  }
  update_config_hash (svc);
  DsCaptureSettings defaults;
  ds_capture_settings_from_config (&defaults, svc->config);
  /* The thread opens the devices from its own copy: a reload never races with it. It lives
   * as long as the sequencer (freed after the thread joined). */
  svc->open_data.config = ds_config_copy (svc->config);
  svc->model_path = g_strdup (pf->model_path);
  svc->model = g_steal_pointer (&pf->model);
  if (!svc->model) {
    svc->model_error = g_strdup (pf->model_note);
    g_message ("automatic operating point off: %s", pf->model_note);
  }
  svc->sequencer = ds_sequencer_new (open_devices, &svc->open_data, &defaults,
                                     g_main_loop_get_context (loop), on_sequencer_event, svc);
  if (svc->model)
    ds_sequencer_set_operating_model (svc->sequencer, svc->model, svc->config->timing_settle_ms,
                                      svc->config->timing_link_mbit);
  if (!start_http (svc, pf, error))
    return NULL;
  if (sd_watchdog_enabled (0, &svc->watchdog_usec) > 0)
    svc->watchdog_source = g_timeout_add ((guint) (svc->watchdog_usec / 4000), watchdog_tick, svc);
  return g_steal_pointer (&svc);
}

/* Device settings cannot change under a running acquisition thread: a reload that touches
 * them is refused (restart the service instead), the rest applies from the next set. */
static gboolean
device_settings_equal (const DsConfig *a, const DsConfig *b)
{
  g_autofree char *ta = NULL, *tb = NULL;
  g_autoptr (DsConfig) ca = ds_config_copy (a);
  g_autoptr (DsConfig) cb = ds_config_copy (b);
  /* Compare everything but [acquisition] (which applies per set): blank those fields. */
  DsConfig *cs[] = { ca, cb };
  for (guint i = 0; i < 2; i++) {
    cs[i]->phases = 0;
    cs[i]->averages = 0;
    g_free (cs[i]->estimator);
    cs[i]->estimator = g_strdup ("maxmin");
    cs[i]->dark_frame = FALSE;
    cs[i]->phase_retries = 0;
    cs[i]->verify_phase = FALSE;
    cs[i]->phase_tolerance_deg = 0;
    cs[i]->exposure_us = 0;
    cs[i]->gain_db = 0;
  }
  ta = ds_config_to_data (ca);
  tb = ds_config_to_data (cb);
  return strcmp (ta, tb) == 0;
}

gboolean
ds_service_reload (DsService *svc, GError **error)
{
  if (!svc->config_path) {
    g_set_error (error, DS_CONFIG_ERROR, DS_CONFIG_ERROR_IO,
                 "reload: running on the built-in configuration (no --config file)");
    return FALSE;
  }
  g_autoptr (DsConfig) fresh = ds_config_load_file (svc->config_path, error);
  if (!fresh) {
    g_prefix_error (error, "reload refused, keeping the running configuration: ");
    return FALSE;
  }
  DsPreflightOverrides ov = overrides_of (&svc->options);
  g_autoptr (DsPreflight) pf = ds_preflight_run (fresh, &ov, error);
  if (!pf) {
    g_prefix_error (error, "reload refused, keeping the running configuration: ");
    return FALSE;
  }
  g_clear_pointer (&fresh, ds_config_free);
  fresh = g_steal_pointer (&pf->config);
  if (!device_settings_equal (svc->config, fresh)) {
    g_set_error (error, DS_CONFIG_ERROR, DS_CONFIG_ERROR_INCONSISTENT,
                 "reload refused, keeping the running configuration: %s changes device, socket or "
                 "spool settings, which need a restart (only [acquisition], exposure-us and "
                 "gain-db apply on reload)",
                 svc->config_path);
    return FALSE;
  }
  ds_config_free (svc->config);
  svc->config = g_steal_pointer (&fresh);
  update_config_hash (svc);
  DsCaptureSettings defaults;
  ds_capture_settings_from_config (&defaults, svc->config);
  ds_sequencer_set_defaults (svc->sequencer, &defaults);
  return TRUE;
}

void
ds_service_free (DsService *svc)
{
  if (!svc)
    return;
  if (svc->watchdog_source)
    g_source_remove (svc->watchdog_source);
  /* Freeing the sequencer runs the main context once more: requests arriving meanwhile are
   * answered `cancelled` by the server, never handed to a half-freed service. */
  if (svc->server)
    ds_server_begin_stop (svc->server);
  /* Joins the acquisition thread: no event (and no frame hook call) arrives after this. */
  g_clear_pointer (&svc->sequencer, ds_sequencer_free);
  g_clear_pointer (&svc->http, ds_http_server_free);
  g_clear_pointer (&svc->live, ds_live_view_free);
  g_clear_pointer (&svc->metrics, ds_metrics_free);
  g_clear_pointer (&svc->model, ds_operating_model_free);
  g_free (svc->model_error);
  g_free (svc->model_path);
  if (svc->pending) {
    GHashTableIter it;
    gpointer value;
    g_hash_table_iter_init (&it, svc->pending);
    g_autoptr (GError) cancelled = g_error_new (DS_PROTOCOL_ERROR, DS_PROTOCOL_ERROR_CANCELLED,
                                                "the daemon is stopping");
    while (g_hash_table_iter_next (&it, NULL, &value)) {
      PendingCapture *p = value;
      ds_server_reply_error (svc->server, p->conn, p->id, cancelled);
    }
    g_hash_table_destroy (svc->pending);
  }
  /* The replies just queued (and results still being written) reach their clients before the
   * connections close: a waiting client gets `cancelled`, never a bare EOF. Bounded, so that a
   * client that does not read cannot hold the stop beyond TimeoutStopSec. */
  if (svc->server)
    ds_server_drain (svc->server, 3000);
  if (svc->server)
    ds_server_shutdown (svc->server);
  g_clear_pointer (&svc->server, ds_server_free);
  g_clear_pointer (&svc->spool, ds_spool_free);
  g_clear_pointer (&svc->open_data.config, ds_config_free);
  g_clear_pointer (&svc->config, ds_config_free);
  g_main_loop_unref (svc->loop);
  g_free (svc->config_path);
  g_free (svc->scene_override);
  g_free (svc->socket_path);
  g_free (svc);
}

const char *
ds_service_socket_path (const DsService *svc)
{
  return svc->socket_path;
}

const char *
ds_service_http_url (const DsService *svc)
{
  return svc->http ? ds_http_server_url (svc->http) : NULL;
}

guint16
ds_service_tcp_port (const DsService *svc)
{
  return ds_server_tcp_port (svc->server);
}

gboolean
ds_service_devices_failed (const DsService *svc)
{
  return svc->devices_failed;
}
