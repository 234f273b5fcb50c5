/* The documents that describe the running service: `status` (also pushed to the live view)
 * and the /metrics text, both read from the sequencer's, server's, spool's and live view's
 * snapshots, so that neither holds a lock while it is built. */
#include "daemon/service/service_private.h"

#include <math.h>
#include <string.h>

#include "build_info.h"
#include "daemon/acquire/status_dark.h"
#include "daemon/output/result_meta.h"
#include "daemon/service/json_build.h"

/* Ready: devices open, the configured settings taken, no device being reconnected; else the
 * reason, naming the setting and what the device allows. NULL when ready. */
static char *
not_ready_reason (const DsService *svc, const DsSequencerStatus *st)
{
  if (!svc->ready)
    return st->state == DS_SEQUENCER_STATE_FAILED ? g_strdup_printf ("devices failed to open: %s", st->last_error)
                                              : g_strdup ("devices are opening");
  if (st->state == DS_SEQUENCER_STATE_RECONNECTING)
    return g_strdup_printf ("reconnecting: %s", st->last_error);
  if (!st->settings_ok)
    return g_strdup_printf ("devices refuse the configured settings: %s", st->settings_error);
  return NULL;
}

char *
ds_service_not_ready_reason (DsService *svc)
{
  DsSequencerStatus st;
  ds_sequencer_get_status (svc->sequencer, &st);
  return not_ready_reason (svc, &st);
}

/* Without a model, captures with target_error/time_budget_ms are refused: say so up front. */
static void
add_operating_model (JsonBuilder *b, const DsService *svc)
{
  ds_json_begin_member_object (b, "operating_model");
  ds_json_add_bool (b, "loaded", svc->model != NULL);
  ds_json_add_string (b, "path", svc->model_path ? svc->model_path : "");
  if (!svc->model)
    ds_json_add_string (b, "error", svc->model_error ? svc->model_error : "not loaded");
  json_builder_end_object (b);
}

static void
add_camera (JsonBuilder *b, const DsSequencerStatus *st)
{
  ds_json_begin_member_object (b, "camera");
  ds_json_add_string (b, "vendor", st->camera_info.vendor);
  ds_json_add_string (b, "model", st->camera_info.model);
  ds_json_add_string (b, "serial", st->camera_info.serial);
  ds_json_add_string (b, "address", st->camera_info.address);
  ds_json_add_uint (b, "width", st->camera_info.sensor_width);
  ds_json_add_uint (b, "height", st->camera_info.sensor_height);
  ds_json_add_bool (b, "connected", st->camera_info.connected);
  ds_json_add_uint (b, "completed", st->camera_stats.completed);
  ds_json_add_uint (b, "failures", st->camera_stats.failures);
  ds_json_add_uint (b, "missing_packets", st->camera_stats.missing_packets);
  ds_json_add_uint (b, "resend_requests", st->camera_stats.resend_requests);
  ds_json_add_uint (b, "timeouts", st->camera_stats.timeouts);
  ds_json_add_uint (b, "ids_skipped", st->camera_stats.ids_skipped);
  ds_json_add_uint (b, "reconnects", st->camera_stats.reconnects);
  ds_json_add_uint (b, "unfilled_buffers", st->camera_stats.unfilled_buffers);
  json_builder_end_object (b);
}

static void
add_illuminator (JsonBuilder *b, const DsSequencerStatus *st)
{
  ds_json_begin_member_object (b, "illuminator");
  ds_json_add_bool (b, "ready", st->illuminator.ready);
  ds_json_add_bool (b, "fault", st->illuminator.fault);
  ds_json_add_bool (b, "over_temperature", st->illuminator.over_temperature);
  ds_json_add_int (b, "applied_phase", st->illuminator.applied_phase);
  ds_json_add_uint (b, "apply_count", st->illuminator.apply_count);
  ds_json_add_double_or_null (b, "temperature_c", st->illuminator.temperature_c);
  /* Whether a second stripe period can be asked for (docs/registers.md, CAPABILITIES). */
  ds_json_add_bool (b, "period_adjustable", st->illuminator.period_adjustable);
  ds_json_add_double_or_null (b, "period_min_px", st->illuminator.period_min_px);
  ds_json_add_double_or_null (b, "period_max_px", st->illuminator.period_max_px);
  /* Retried requests slow the sets without failing them: where they went is said here. */
  ds_json_add_uint (b, "failed_attempts", st->illuminator.failed_attempts);
  ds_json_add_uint (b, "failed_accesses", st->illuminator.failed_accesses);
  ds_json_add_string (b, "last_link_problem", st->illuminator.last_link_problem);
  json_builder_end_object (b);
}

static void
add_clients (JsonBuilder *b, const DsService *svc)
{
  DsServerStats ss;
  ds_server_get_stats (svc->server, &ss);
  ds_json_begin_member_object (b, "clients");
  ds_json_add_uint (b, "connected", ss.clients);
  ds_json_add_uint (b, "tcp", ss.tcp_clients);
  ds_json_add_uint (b, "subscribers", ss.subscribers);
  ds_json_add_uint (b, "accepted", ss.accepted);
  ds_json_add_uint (b, "refused", ss.refused);
  ds_json_add_uint (b, "evicted", ss.evicted);
  ds_json_add_uint (b, "timed_out", ss.timed_out);
  ds_json_add_uint (b, "requests", ss.requests);
  ds_json_add_uint (b, "bad_requests", ss.bad_requests);
  ds_json_begin_member_object (b, "error_replies");
  for (guint i = 1; i < G_N_ELEMENTS (ss.error_replies); i++)
    if (ss.error_replies[i])
      ds_json_add_uint (b, ds_protocol_error_name ((DsProtocolError) i), ss.error_replies[i]);
  json_builder_end_object (b);
  ds_json_add_uint (b, "results_published", svc->results_published);
  ds_json_add_uint (b, "results_dropped", ss.dropped);
  ds_json_add_uint (b, "queued_bytes", ss.queued_bytes);
  json_builder_end_object (b);
}

static void
add_http (JsonBuilder *b, const DsService *svc)
{
  DsLiveStats ls;
  ds_live_view_get_stats (svc->live, &ls);
  ds_json_begin_member_object (b, "http");
  ds_json_add_string (b, "url", ds_http_server_url (svc->http));
  ds_json_add_uint (b, "live_clients", ls.clients);
  ds_json_add_uint (b, "live_updates_sent", ls.sent);
  ds_json_add_uint (b, "live_updates_superseded", ls.superseded);
  DsHttpListenerStats hs;
  ds_http_server_get_listener_stats (svc->http, &hs);
  ds_json_add_uint (b, "connections", hs.connections);
  ds_json_add_uint (b, "connections_refused", hs.refused);
  ds_json_add_uint (b, "connections_timed_out", hs.timed_out);
  ds_json_add_uint (b, "accept_paused", hs.accept_paused);
  json_builder_end_object (b);
}

static void
add_spool (JsonBuilder *b, const DsService *svc)
{
  DsSpoolStats sp;
  ds_spool_get_stats (svc->spool, &sp);
  ds_json_begin_member_object (b, "spool");
  ds_json_add_uint (b, "bytes", sp.bytes);
  ds_json_add_uint (b, "sets_written", sp.sets_written);
  ds_json_add_uint (b, "sets_removed", sp.sets_removed);
  ds_json_add_uint (b, "errors", sp.errors);
  ds_json_add_uint (b, "dropped", sp.dropped);
  ds_json_add_uint (b, "pending", sp.pending);
  ds_json_add_bool (b, "run_open", sp.run_open);
  ds_json_add_string (b, "last_error", sp.last_error);
  json_builder_end_object (b);
}

JsonNode *
ds_service_status_to_json (DsService *svc)
{
  DsSequencerStatus st;
  ds_sequencer_get_status (svc->sequencer, &st);
  g_autoptr (JsonBuilder) b = ds_json_object_begin ();
  ds_json_add_string (b, "version", DS_VERSION);
  ds_json_add_string (b, "git", DS_GIT_DESCRIBE);
  ds_json_add_double_or_null (b, "uptime_s", (double) (g_get_monotonic_time () - svc->started_us) / 1e6);
  ds_json_add_string (b, "state", ds_sequencer_state_name (st.state));
  g_autofree char *not_ready = not_ready_reason (svc, &st);
  ds_json_add_bool (b, "ready", not_ready == NULL);
  ds_json_add_string (b, "not_ready_reason", not_ready);
  ds_json_add_bool (b, "continuous", st.continuous);
  ds_json_add_node (b, "preview", ds_service_preview_status_json (&st));
  ds_json_add_uint (b, "pending", st.pending);
  ds_json_add_uint (b, "sets_done", st.sets_done);
  ds_json_add_uint (b, "sets_failed", st.sets_failed);
  ds_json_add_uint (b, "sets_cancelled", st.sets_cancelled);
  ds_json_add_uint (b, "frame_results", st.frame_results);
  ds_json_begin_member_object (b, "window");
  ds_json_add_uint (b, "breaks", st.window_breaks);
  ds_json_add_string (b, "last_break", st.last_window_break);
  json_builder_end_object (b);
  ds_json_add_string (b, "last_error", st.last_error);
  ds_json_add_bool (b, "has_dark", st.has_dark);
  ds_json_add_node (b, "dark", ds_status_dark_to_json (&st, g_get_real_time ()));
  ds_json_add_double_or_null (b, "phase_offset_cycles", st.phase_offset_cycles);
  ds_json_add_node (b, "frames", ds_frame_counters_to_json (&st.frames));
  ds_service_status_add_camera_live (b, &st);
  add_operating_model (b, svc);
  ds_json_begin_member_object (b, "stage_mean_ms");
  for (guint i = 0; i < DS_STAGE_N; i++)
    ds_json_add_double_or_null (b, ds_stage_name (i),
                                st.stages[i].count ? st.stages[i].total_ms / st.stages[i].count : NAN);
  json_builder_end_object (b);
  ds_json_begin_member_object (b, "devices");
  ds_json_add_string (b, "backends", st.devices);
  add_camera (b, &st);
  add_illuminator (b, &st);
  json_builder_end_object (b);
  add_clients (b, svc);
  if (svc->http)
    add_http (b, svc);
  if (svc->spool)
    add_spool (b, svc);
  return ds_json_object_end (b);
}

char *
ds_service_metrics_text (DsService *svc)
{
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
  g_autofree char *not_ready = not_ready_reason (svc, &st);
  DsHttpListenerStats hs;
  ds_http_server_get_listener_stats (svc->http, &hs);
  ls.http_connections = hs.connections;
  ls.http_refused = hs.refused;
  ls.http_timed_out = hs.timed_out;
  ls.http_accept_paused = hs.accept_paused;
  DsMetricsSources src = { .sequencer = &st, .server = &ss, .spool = svc->spool ? &sp : NULL, .live = &ls,
                           .results_published = svc->results_published,
                           .ready = not_ready == NULL,
                           .start_unix_s = (double) svc->started_unix_us / 1e6,
                           .last_result_unix_s = (double) svc->last_result_unix_us / 1e6 };
  return ds_metrics_render (svc->metrics, &src);
}
