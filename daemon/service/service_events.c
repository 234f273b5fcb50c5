/* What the acquisition thread reports, on the main loop: a set's result goes back to the client
 * that asked for it and out to subscribers, the live view and the spool; a failure, a dark
 * frame, a release/acquire and a device change are answered and published the same way. */
#include "daemon/service/service_private.h"

#include <string.h>
#include <systemd/sd-daemon.h>

#include "daemon/output/result_meta.h"
#include "daemon/protocol/protocol.h"
#include "daemon/service/json_build.h"
#include "daemon/service/provenance.h"
#include "daemon/service/wire_error.h"

static void
reply_result (DsService *svc, PendingCapture *p, DsResult *result)
{
  const DsPayloadInfo *infos;
  GBytes *const *bytes;
  guint n = ds_result_payloads (result, p->format, p->extrema, &infos, &bytes);
  g_autoptr (GArray) sel_infos = g_array_new (FALSE, FALSE, sizeof (DsPayloadInfo));
  g_autoptr (GPtrArray) sel_bytes = g_ptr_array_new ();
  for (guint i = 0; i < n; i++)
    for (guint j = 0; j < G_N_ELEMENTS (ds_service_output_names); j++)
      if (strcmp (infos[i].name, ds_service_output_names[j]) == 0 && (p->outputs & (1u << j))) {
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

/* The pending request's error reply: the acquisition's error in the wire's terms. */
static void
reply_wire_error (DsService *svc, PendingCapture *p, const GError *error)
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
  ds_service_reply_ok (svc, p->conn, p->id, body);
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
    reply_wire_error (svc, p, error);
    return FALSE;
  }
  p->calibrate_first_set = ds_result_set_id (result);
  /* The open field's DN are the pixel format's the camera delivered the set in (proc/calibration.h). */
  g_strlcpy (p->calibrate_first.open_field_pixel_format, ds_config_camera_pixel_format (svc->config),
             sizeof p->calibrate_first.open_field_pixel_format);
  /* A cancel since the request: no second set (the first one completed before the cancel). */
  if (p->cancels_before != svc->cancels) {
    error = g_error_new (DS_PROTOCOL_ERROR, DS_PROTOCOL_ERROR_CANCELLED, "cancelled by a cancel request");
    reply_wire_error (svc, p, error);
    return FALSE;
  }
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
  g_autoptr (JsonBuilder) b = ds_json_object_begin ();
  ds_json_add_node (b, "id", p->id ? json_node_copy (p->id) : NULL);
  ds_json_add_int (b, "phase", phase);
  ds_json_add_int (b, "phases", n);
  g_autoptr (JsonNode) body = ds_json_object_end (b);
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
  const DsPayloadInfo *raw_infos;
  GBytes *const *raw_bytes;
  guint r = ds_result_per_frame (result) ? ds_result_raw_payloads (result, &raw_infos, &raw_bytes) : 0;
  /* Per-frame results come at the camera's rate: a client reading slower gets the newest,
   * never a backlog (docs/protocol.md, "Events"). */
  gboolean newest_only = ds_result_per_frame (result);
  if (r == 0) {
    ds_server_publish_result (svc->server, meta, infos, bytes, n, newest_only);
  } else {
    /* A per-frame result with save_phases carries its window's frames: no capture reply
     * brings them, and they are what a client checks the result against. */
    g_autoptr (GArray) all_infos = g_array_new (FALSE, FALSE, sizeof (DsPayloadInfo));
    g_autoptr (GPtrArray) all_bytes = g_ptr_array_new ();
    g_array_append_vals (all_infos, infos, n);
    g_array_append_vals (all_infos, raw_infos, r);
    for (guint i = 0; i < n; i++)
      g_ptr_array_add (all_bytes, bytes[i]);
    for (guint i = 0; i < r; i++)
      g_ptr_array_add (all_bytes, raw_bytes[i]);
    ds_server_publish_result (svc->server, meta, (const DsPayloadInfo *) all_infos->data,
                              (GBytes *const *) all_bytes->pdata, all_infos->len, newest_only);
  }
  svc->results_published++;
  svc->last_result_unix_us = g_get_real_time ();
  gint64 last_frame = ds_json_path_int (meta, "monotonic_us.last_frame", 0);
  if (last_frame > 0)
    ds_metrics_observe_result (svc->metrics, (double) (g_get_monotonic_time () - last_frame) / 1e6);
  if (svc->live)
    ds_live_view_on_result (svc->live, result);
  /* Queued to the spool's writer thread: a slow disk never delays the loop. */
  if (svc->spool && !ds_spool_record (svc->spool, result, svc->in_run))
    g_warning ("spool: set %" G_GUINT64_FORMAT " not recorded: the disk is behind", ds_result_set_id (result));
}

/* The devices failed to open: the requests that waited for them (docs/protocol.md, "Error
 * codes") are answered `device_error` with the reason now, before the service stops, since no
 * device will ever take them; a waiting `cancel` had nothing left to stop. */
static void
answer_pending_devices_failed (DsService *svc, const GError *why)
{
  GHashTableIter it;
  gpointer value;
  g_hash_table_iter_init (&it, svc->pending);
  while (g_hash_table_iter_next (&it, NULL, &value)) {
    PendingCapture *p = value;
    if (p->cancel)
      ds_service_reply_cancel (svc, p->conn, p->id, p->cancelled, p->stream_stopped);
    else {
      g_autoptr (GError) error = g_error_new (DS_PROTOCOL_ERROR, DS_PROTOCOL_ERROR_DEVICE,
                                              "the devices failed to open: %s", why->message);
      ds_server_reply_error (svc->server, p->conn, p->id, error);
    }
    g_hash_table_iter_remove (&it);
  }
}

static void
on_ready (DsService *svc, const DsSequencerEvent *ev)
{
  if (ev->error) {
    g_critical ("devices: %s", ev->error->message);
    sd_notifyf (0, "STATUS=devices failed: %s", ev->error->message);
    svc->devices_failed = TRUE;
    answer_pending_devices_failed (svc, ev->error);
    /* Without devices the service is of no use; systemd restarts it (Restart=on-failure). */
    g_main_loop_quit (svc->loop);
    return;
  }
  svc->ready = TRUE;
  g_message ("devices open: %s", ev->message);
  sd_notifyf (0, "READY=1\nSTATUS=ready: %s", ev->message);
}

/* A set's result: stamped with its provenance, answered to its request (a calibrate request may
 * go on to a second set) and published. FALSE while the request awaits that second set. */
static gboolean
on_result (DsService *svc, PendingCapture *p, const DsSequencerEvent *ev)
{
  DsSequencerStatus status;
  ds_sequencer_get_status (svc->sequencer, &status);
  DsResultProvenance prov;
  ds_provenance_fill (&prov, svc->config, svc->config_sha256, &status);
  ds_result_set_provenance (ev->result, &prov);
  g_autofree char *st = g_strdup_printf ("set %" G_GUINT64_FORMAT " done", ds_result_set_id (ev->result));
  notify_status (svc, st);
  gboolean awaits_second = FALSE;
  if (p && p->calibrate)
    awaits_second = calibration_step (svc, p, ev->result);
  else if (p)
    reply_result (svc, p, ev->result);
  publish_result (svc, ev->result);
  return !awaits_second;
}

static void
on_failed (DsService *svc, PendingCapture *p, const DsSequencerEvent *ev)
{
  g_autoptr (GError) wire = ds_wire_error_new (ev->error);
  gboolean cancelled = wire->code == DS_PROTOCOL_ERROR_CANCELLED;
  /* A cancel is asked for, not a fault: no warning. */
  if (cancelled)
    g_message ("phase set cancelled: %s", ev->error->message);
  else
    g_warning ("phase set failed: %s", ev->error->message);
  notify_status (svc, cancelled ? "last set cancelled" : "last set failed");
  /* an illuminator that cannot draw twice its period: the first set's calibration stands (not
   * when the set was cancelled: the whole request is) */
  if (p && p->calibrate_second && !cancelled)
    reply_calibration_pair (svc, p, NULL, ev->error->message);
  else if (p)
    ds_server_reply_error (svc->server, p->conn, p->id, wire);
  g_autoptr (JsonBuilder) b = ds_json_object_begin ();
  ds_json_add_string (b, "reason", ev->error->message);
  ds_json_add_string (b, "code", ds_protocol_error_name ((DsProtocolError) wire->code));
  g_autoptr (JsonNode) body = ds_json_object_end (b);
  ds_server_publish (svc->server, "failed", body, NULL, NULL, 0);
}

static void
on_dark (DsService *svc, PendingCapture *p, const DsSequencerEvent *ev)
{
  if (ev->error) {
    reply_wire_error (svc, p, ev->error);
    return;
  }
  g_autoptr (JsonBuilder) b = ds_json_object_begin ();
  ds_json_add_double (b, "dark_mean_dn", ev->dark_mean_dn);
  g_autoptr (JsonNode) body = ds_json_object_end (b);
  ds_service_reply_ok (svc, p->conn, p->id, body);
}

/* release or acquire done (or refused): logged, and answered with the state it left. */
static void
on_control (DsService *svc, PendingCapture *p, const DsSequencerEvent *ev)
{
  if (ev->error)
    g_warning ("%s", ev->error->message);
  else
    g_message ("%s", ev->message);
  if (!p)
    return;
  if (ev->error) {
    reply_wire_error (svc, p, ev->error);
    return;
  }
  if (p->cancel) {
    ds_service_reply_cancel (svc, p->conn, p->id, p->cancelled, p->stream_stopped);
    return;
  }
  if (p->camera_set) {
    ds_service_reply_camera_set (svc, p->conn, p->id);
    return;
  }
  if (p->preview) {
    ds_service_reply_preview (svc, p->conn, p->id, ev->message);
    return;
  }
  DsSequencerStatus st;
  ds_sequencer_get_status (svc->sequencer, &st);
  g_autoptr (JsonBuilder) b = ds_json_object_begin ();
  ds_json_add_string (b, "state", ds_sequencer_state_name (st.state));
  ds_json_add_string (b, "message", ev->message);
  g_autoptr (JsonNode) body = ds_json_object_end (b);
  ds_service_reply_ok (svc, p->conn, p->id, body);
}

static void
on_device (DsService *svc, const DsSequencerEvent *ev)
{
  g_message ("%s", ev->message);
  notify_status (svc, ev->message);
  g_autoptr (JsonBuilder) b = ds_json_object_begin ();
  ds_json_add_string (b, "message", ev->message);
  g_autoptr (JsonNode) body = ds_json_object_end (b);
  ds_server_publish (svc->server, "device", body, NULL, NULL, 0);
}

/* Continuous mode stopped by itself (its sets kept failing): the run ends as with `stop`, and
 * subscribers are told when and why. */
static void
on_stream_stopped (DsService *svc, const DsSequencerEvent *ev)
{
  g_warning ("%s", ev->message);
  notify_status (svc, "continuous acquisition stopped: its sets kept failing");
  svc->in_run = FALSE;
  if (svc->spool)
    ds_spool_end_run (svc->spool);
  g_autoptr (JsonBuilder) b = ds_json_object_begin ();
  ds_json_add_string (b, "reason", ev->message);
  g_autoptr (JsonNode) body = ds_json_object_end (b);
  ds_server_publish (svc->server, "stream_stopped", body, NULL, NULL, 0);
}

/* Per-frame results: the sliding window was broken; no result until N good frames follow.
 * Told to subscribers, so that a gap in the results' frame ids has its reason. */
static void
on_window_broken (DsService *svc, const DsSequencerEvent *ev)
{
  const char *colon = strstr (ev->message, ": ");
  g_autofree char *reason = colon ? g_strndup (ev->message, (gsize) (colon - ev->message)) : g_strdup (ev->message);
  g_debug ("sliding window broken: %s", ev->message);
  g_autoptr (JsonBuilder) b = ds_json_object_begin ();
  ds_json_add_string (b, "reason", reason);
  ds_json_add_string (b, "message", ev->message);
  g_autoptr (JsonNode) body = ds_json_object_end (b);
  ds_server_publish (svc->server, "window_broken", body, NULL, NULL, 0);
}

void
ds_service_on_sequencer_event (const DsSequencerEvent *ev, gpointer user_data)
{
  DsService *svc = user_data;
  PendingCapture *p = ev->tag ? g_hash_table_lookup (svc->pending, &ev->tag) : NULL;
  gboolean answered = FALSE; /* the request of ev->tag, when there is one, got its reply */
  switch (ev->kind) {
  case DS_SEQUENCER_EVENT_READY:
    on_ready (svc, ev);
    break;
  case DS_SEQUENCER_EVENT_PROGRESS:
    if (p)
      send_progress (svc, p, ev->phase, ev->n_phases);
    break;
  case DS_SEQUENCER_EVENT_RESULT:
    answered = on_result (svc, p, ev);
    break;
  case DS_SEQUENCER_EVENT_FAILED:
    on_failed (svc, p, ev);
    answered = TRUE;
    break;
  case DS_SEQUENCER_EVENT_DARK:
    if (p)
      on_dark (svc, p, ev);
    answered = TRUE;
    break;
  case DS_SEQUENCER_EVENT_CONTROL:
    on_control (svc, p, ev);
    answered = TRUE;
    break;
  case DS_SEQUENCER_EVENT_DEVICE:
    on_device (svc, ev);
    break;
  case DS_SEQUENCER_EVENT_WINDOW_BROKEN:
    on_window_broken (svc, ev);
    break;
  case DS_SEQUENCER_EVENT_STREAM_STOPPED:
    on_stream_stopped (svc, ev);
    break;
  }
  if (p && answered)
    g_hash_table_remove (svc->pending, &ev->tag);
}
