/* The documents that describe the running service: `status` (also pushed to the live view)
 * and the /metrics text, both read from the sequencer's, server's, spool's and live view's
 * snapshots, so that neither holds a lock while it is built. */
#include "daemon/service/service_private.h"

#include <math.h>
#include <string.h>

#include "build_info.h"
#include "daemon/acquire/status_dark.h"
#include "daemon/output/result_meta.h"

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

JsonNode *
ds_service_status_to_json (DsService *svc)
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
  add_string (b, "state", st.state);
  /* Ready: devices open, the configured settings taken, no device being reconnected; else
   * the reason, naming the setting and what the device allows. */
  g_autofree char *not_ready = NULL;
  if (!svc->ready)
    not_ready = strcmp (st.state, "failed") == 0 ? g_strdup_printf ("devices failed to open: %s", st.last_error)
                                                  : g_strdup ("devices are opening");
  else if (strcmp (st.state, "reconnecting") == 0)
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
  DsMetricsSources src = { .sequencer = &st, .server = &ss, .spool = svc->spool ? &sp : NULL, .live = &ls,
                           .results_published = svc->results_published,
                           .uptime_s = (double) (g_get_monotonic_time () - svc->started_us) / 1e6 };
  return ds_metrics_render (svc->metrics, &src);
}
