#include "daemon/service/metrics.h"

#include <math.h>

#include "build_info.h"

/* Result latency buckets (seconds): a fast rig publishes within milliseconds of the last frame,
 * a large frame with the robust estimator within a second or two. */
static const double bucket_bounds[] = { 0.001, 0.0025, 0.005, 0.01, 0.025, 0.05, 0.1, 0.25, 0.5, 1, 2.5, 5, 10 };
#define N_BUCKETS G_N_ELEMENTS (bucket_bounds)

struct DsMetrics {
  guint64 buckets[N_BUCKETS]; /* observations <= bound (cumulative at render time) */
  guint64 count;
  double sum;
};

DsMetrics *
ds_metrics_new (void)
{
  return g_new0 (DsMetrics, 1);
}

void
ds_metrics_free (DsMetrics *metrics)
{
  g_free (metrics);
}

void
ds_metrics_observe_result (DsMetrics *m, double latency_s)
{
  if (!isfinite (latency_s) || latency_s < 0)
    latency_s = 0;
  for (guint i = 0; i < N_BUCKETS; i++)
    if (latency_s <= bucket_bounds[i]) {
      m->buckets[i]++;
      break;
    }
  m->count++;
  m->sum += latency_s;
}

static void
family (GString *out, const char *name, const char *type, const char *help)
{
  g_string_append_printf (out, "# HELP %s %s\n# TYPE %s %s\n", name, help, name, type);
}

const char *
ds_metrics_format_value (char *buf, gsize size, double value)
{
  if (isnan (value))
    return g_strlcpy (buf, "NaN", size), buf;
  if (isinf (value))
    return g_strlcpy (buf, value > 0 ? "+Inf" : "-Inf", size), buf;
  /* Doubles hold every integer up to 2^53: counts print whole, never as 1e+06. */
  if (value == floor (value) && fabs (value) < 9007199254740992.0)
    return g_ascii_formatd (buf, size, "%.0f", value);
  /* 17 significant digits always round-trip; the first precision that does is the shortest. */
  for (int digits = 1; digits <= 17; digits++) {
    char fmt[8];
    g_snprintf (fmt, sizeof fmt, "%%.%dg", digits);
    g_ascii_formatd (buf, size, fmt, value);
    if (g_ascii_strtod (buf, NULL) == value)
      break;
  }
  return buf;
}

static void
sample (GString *out, const char *name, const char *labels, double value)
{
  char buf[G_ASCII_DTOSTR_BUF_SIZE];
  const char *v = ds_metrics_format_value (buf, sizeof buf, value);
  g_string_append_printf (out, "%s%s%s%s %s\n", name, labels ? "{" : "", labels ? labels : "", labels ? "}" : "", v);
}

static void
counter (GString *out, const char *name, const char *help, guint64 value)
{
  family (out, name, "counter", help);
  sample (out, name, NULL, (double) value);
}

static void
gauge (GString *out, const char *name, const char *help, double value)
{
  family (out, name, "gauge", help);
  sample (out, name, NULL, value);
}

/* Label values: the exposition format escapes backslash, quote and newline. */
static char *
label_value (const char *v)
{
  GString *s = g_string_new (NULL);
  for (const char *p = v; *p; p++) {
    if (*p == '\\' || *p == '"')
      g_string_append_c (s, '\\');
    if (*p == '\n')
      g_string_append (s, "\\n");
    else
      g_string_append_c (s, *p);
  }
  return g_string_free (s, FALSE);
}

char *
ds_metrics_render (DsMetrics *m, const DsMetricsSources *src)
{
  GString *out = g_string_new (NULL);
  const DsSequencerStatus *st = src->sequencer;
  const DsFrameCounters *f = &st->frames;

  g_autofree char *version = label_value (DS_VERSION), *build = label_value (DS_GIT_DESCRIBE);
  g_autofree char *info = g_strdup_printf ("version=\"%s\",build=\"%s\"", version, build);
  family (out, "descatter_build_info", "gauge", "The version and build of descatterd (always 1).");
  sample (out, "descatter_build_info", info, 1);
  /* The standard process metric: a query computes uptime as time() - this, and a restart shows
   * as a step that no counter reset can hide. */
  gauge (out, "process_start_time_seconds", "Start time of the process since the Unix epoch in seconds.",
         src->start_unix_s);
  gauge (out, "descatter_ready", "1 when the devices are open, the settings taken and nothing reconnects (status.ready).",
         src->ready ? 1 : 0);
  /* A state set: every state is a series, so a query or an alert on one state always has data
   * (absent series read as "no data", not as 0). */
  family (out, "descatter_acquisition_state", "gauge", "The acquisition thread's state: 1 for the current one, 0 for the others.");
  for (guint i = 0; i < DS_SEQUENCER_STATE_N; i++) {
    g_autofree char *state = label_value (ds_sequencer_state_name ((DsSequencerState) i));
    g_autofree char *state_label = g_strdup_printf ("state=\"%s\"", state);
    sample (out, "descatter_acquisition_state", state_label, st->state == (DsSequencerState) i ? 1 : 0);
  }

  family (out, "descatter_sets_total", "counter", "Phase sets completed (done), failed or cancelled.");
  sample (out, "descatter_sets_total", "outcome=\"done\"", (double) st->sets_done);
  sample (out, "descatter_sets_total", "outcome=\"failed\"", (double) st->sets_failed);
  sample (out, "descatter_sets_total", "outcome=\"cancelled\"", (double) st->sets_cancelled);
  family (out, "descatter_results_total", "counter", "Results made, per mode: per-set (one per phase set) or per-frame (sliding window).");
  sample (out, "descatter_results_total", "mode=\"per-set\"", (double) st->sets_done);
  sample (out, "descatter_results_total", "mode=\"per-frame\"", (double) st->frame_results);
  counter (out, "descatter_window_breaks_total", "Sliding windows broken by a lost or refused frame or new settings.",
           st->window_breaks);
  counter (out, "descatter_frames_acquired_total", "Frames that came out of the camera.", f->acquired);
  counter (out, "descatter_frames_folded_total", "Frames folded into published results.", f->folded);
  family (out, "descatter_frames_dropped_total", "counter", "Frames not folded, by reason (docs/protocol.md, \"Frame accounting\").");
  for (guint i = 0; i < DS_DROP_N_REASONS; i++) {
    g_autofree char *l = g_strdup_printf ("reason=\"%s\"", ds_drop_reason_name (i));
    sample (out, "descatter_frames_dropped_total", l, (double) f->by_reason[i]);
  }
  counter (out, "descatter_frame_retries_total", "Re-acquisitions after a drop or a device error.", f->retries);
  counter (out, "descatter_grab_timeouts_total", "Grabs that returned no frame in time.", f->timeouts);
  counter (out, "descatter_device_errors_total", "Illuminator, camera or trigger operations that failed.",
           f->device_errors);
  counter (out, "descatter_camera_missing_packets_total", "Stream packets the camera library counted as lost.",
           st->camera_stats.missing_packets);
  counter (out, "descatter_camera_resend_requests_total", "Packet resends the camera library asked for.",
           st->camera_stats.resend_requests);
  counter (out, "descatter_camera_reconnects_total", "Times the devices were reconnected.", st->camera_stats.reconnects);
  gauge (out, "descatter_illuminator_temperature_celsius", "The illuminator's temperature (NaN: it reports none).",
         st->illuminator.temperature_c);

  family (out, "descatter_result_latency_seconds", "histogram",
          "From a set's last frame to its result being published to clients.");
  guint64 cumulative = 0;
  for (guint i = 0; i < N_BUCKETS; i++) {
    cumulative += m->buckets[i];
    char le[G_ASCII_DTOSTR_BUF_SIZE];
    /* Bucket labels as a query writes them (le="0.0025"): the shortest text that reads back as
     * the bound, as Prometheus's own Go client prints them. */
    g_autofree char *l = g_strdup_printf ("le=\"%s\"", ds_metrics_format_value (le, sizeof le, bucket_bounds[i]));
    sample (out, "descatter_result_latency_seconds_bucket", l, (double) cumulative);
  }
  sample (out, "descatter_result_latency_seconds_bucket", "le=\"+Inf\"", (double) m->count);
  sample (out, "descatter_result_latency_seconds_sum", NULL, m->sum);
  sample (out, "descatter_result_latency_seconds_count", NULL, (double) m->count);

  const DsServerStats *ss = src->server;
  counter (out, "descatter_results_published_total", "Results published to subscribers.", src->results_published);
  if (src->last_result_unix_s > 0)
    gauge (out, "descatter_last_result_timestamp_seconds", "When the last result was published (Unix time, seconds).",
           src->last_result_unix_s);
  family (out, "descatter_results_dropped_total", "counter",
          "Result deliveries lost to slow clients: socket subscribers, or live-view updates replaced by newer ones.");
  sample (out, "descatter_results_dropped_total", "client=\"socket\"", (double) ss->dropped);
  sample (out, "descatter_results_dropped_total", "client=\"live\"", src->live ? (double) src->live->superseded : 0);
  family (out, "descatter_clients", "gauge", "Connected clients by kind.");
  sample (out, "descatter_clients", "kind=\"socket\"", ss->clients);
  sample (out, "descatter_clients", "kind=\"subscriber\"", ss->subscribers);
  sample (out, "descatter_clients", "kind=\"live\"", src->live ? src->live->clients : 0);
  counter (out, "descatter_socket_requests_total", "Requests received on the socket.", ss->requests);
  counter (out, "descatter_socket_bad_requests_total",
           "Requests refused for what the client sent (malformed, unknown command, bad argument, no token).",
           ss->bad_requests);
  family (out, "descatter_socket_error_replies_total", "counter",
          "Error replies by wire code (docs/protocol.md, \"Error codes\"): device errors, busy, cancelled...");
  for (guint i = 1; i < G_N_ELEMENTS (ss->error_replies); i++) {
    if (i == DS_PROTOCOL_ERROR_BAD_REPLY) /* a client-side code: the daemon never sends it */
      continue;
    g_autofree char *l = g_strdup_printf ("code=\"%s\"", ds_protocol_error_name ((DsProtocolError) i));
    sample (out, "descatter_socket_error_replies_total", l, (double) ss->error_replies[i]);
  }
  gauge (out, "descatter_socket_queued_bytes", "Bytes queued to socket clients now.", (double) ss->queued_bytes);
  if (src->live) {
    counter (out, "descatter_http_requests_total", "HTTP requests (page, metrics, WebSocket upgrades).",
             src->live->http_requests);
    counter (out, "descatter_http_unauthorized_total", "HTTP requests refused for a missing or wrong token.",
             src->live->http_unauthorized);
    counter (out, "descatter_live_updates_sent_total", "Live-view updates sent to browsers.", src->live->sent);
    gauge (out, "descatter_http_connections", "HTTP connections open now, WebSockets included.",
           src->live->http_connections);
    counter (out, "descatter_http_connections_refused_total",
             "HTTP connections refused over max-connections or max-connections-per-peer.", src->live->http_refused);
    counter (out, "descatter_http_connections_timed_out_total",
             "HTTP connections closed for header-timeout-ms or idle-timeout-ms.", src->live->http_timed_out);
    counter (out, "descatter_http_accept_paused_total", "Times accepting HTTP paused for want of descriptors.",
             src->live->http_accept_paused);
  }
  if (src->spool) {
    const DsSpoolStats *sp = src->spool;
    gauge (out, "descatter_spool_bytes", "Bytes in the spool directory.", (double) sp->bytes);
    gauge (out, "descatter_spool_pending", "Results waiting for the spool's writer.", sp->pending);
    family (out, "descatter_spool_sets_total", "counter",
            "Results by what the spool did with them: written, removed for space, failed, or dropped (writer behind).");
    sample (out, "descatter_spool_sets_total", "outcome=\"written\"", (double) sp->sets_written);
    sample (out, "descatter_spool_sets_total", "outcome=\"removed\"", (double) sp->sets_removed);
    sample (out, "descatter_spool_sets_total", "outcome=\"failed\"", (double) sp->errors);
    sample (out, "descatter_spool_sets_total", "outcome=\"dropped\"", (double) sp->dropped);
  }
  return g_string_free (out, FALSE);
}
