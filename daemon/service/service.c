/* descatterd's lifecycle: the service built after the preflight passed (listeners, spool,
 * acquisition thread, HTTP side), the systemd watchdog, a SIGHUP's reload and the orderly stop.
 * Requests, sequencer events and the status documents live in service_requests.c,
 * service_events.c and service_status.c (the shared state: service_private.h). */
#include "daemon/service/service_private.h"

#include <glib/gstdio.h>
#include <string.h>
#include <sys/resource.h>
#include <systemd/sd-daemon.h>

#include "daemon/acquire/devices.h"
#include "daemon/output/result_meta.h"
#include "daemon/protocol/protocol.h"
#include "daemon/service/preflight.h"
#include "daemon/service/token.h"

/* ---- devices are opened on the acquisition thread from a copy of the configuration ---- */

static DsDevices *
open_devices (gpointer data, GError **error)
{
  OpenData *od = data;
  return ds_devices_open (od->config, error);
}

/* The configuration in effect: the file with the command line's overrides (--socket, --tcp;
 * --scene is already in svc->config), so that what is printed (and hashed into every result) is
 * what the daemon uses. */
char *
ds_service_effective_config_text (DsService *svc)
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

static JsonNode *
live_status (gpointer data)
{
  return ds_service_status_to_json (data);
}

static char *
render_metrics (gpointer data)
{
  return ds_service_metrics_text (data);
}

/* The HTTP token when [http] token-file names none: made at each start and written next to
 * the socket, readable by whom may use the socket, so that the live view lets in no one the
 * socket would not (`descatterctl live-url` reads it). */
static char *
loopback_token (DsService *svc, GError **error)
{
  g_autofree char *token = ds_token_generate (error);
  if (!token)
    return NULL;
  g_autofree char *path = g_strconcat (svc->config->socket_path, DS_HTTP_TOKEN_SUFFIX, NULL);
  if (!ds_token_write_for_socket (path, token, svc->config->socket_path, error))
    return NULL;
  svc->http_token_path = g_steal_pointer (&path);
  return g_steal_pointer (&token);
}

/* HTTP connections stay below the descriptor limit with room for the socket's clients, the
 * live view's bridges (two descriptors each) and the daemon's own files and devices. */
static guint
http_connection_budget (const DsConfig *c)
{
  struct rlimit rl;
  guint want = c->http_max_connections;
  if (getrlimit (RLIMIT_NOFILE, &rl) != 0 || rl.rlim_cur == RLIM_INFINITY)
    return want;
  guint64 reserve = (guint64) c->max_clients + 2 * (guint64) c->http_max_live_clients + DS_FD_RESERVE;
  guint64 room = rl.rlim_cur > reserve + 8 ? rl.rlim_cur - reserve : 8;
  if (want <= room)
    return want;
  g_warning ("[http] max-connections = %u lowered to %" G_GUINT64_FORMAT ": the descriptor limit is %" G_GUINT64_FORMAT
             " and max-clients, the live view's bridges and the daemon's own files need %" G_GUINT64_FORMAT
             " (raise LimitNOFILE)", want, room, (guint64) rl.rlim_cur, reserve);
  return (guint) room;
}

/* The live view and /metrics, when [http] listen (or --http) asks for them (checked by preflight). */
static gboolean
start_http (DsService *svc, const DsPreflight *pf, GError **error)
{
  if (!pf->http_host)
    return TRUE;
  const DsConfig *c = svc->config;
  g_autofree char *own_token = pf->http_token ? NULL : loopback_token (svc, error);
  if (!pf->http_token && !own_token)
    return FALSE;
  DsLiveViewLimits live = { .max_fps = c->http_live_fps, .max_clients = c->http_max_live_clients,
                            .send_budget_bytes = c->http_live_send_budget };
  svc->live = ds_live_view_new (g_main_loop_get_context (svc->loop), svc->server, &live, live_status, svc);
  g_auto (GStrv) names = c->http_server_names ? g_strsplit (c->http_server_names, ",", -1) : NULL;
  for (guint i = 0; names && names[i]; i++)
    g_strstrip (names[i]);
  guint max_connections = http_connection_budget (c);
  DsHttpOptions o = { .host = pf->http_host,
                      .port = pf->http_port,
                      .token = pf->http_token ? pf->http_token : own_token,
                      .server_names = (const char *const *) names,
                      .limits = { .max_connections = max_connections,
                                  .max_per_peer = MIN (c->http_max_per_peer, max_connections),
                                  .max_header_bytes = c->http_max_header_bytes,
                                  .header_timeout_ms = c->http_header_timeout_ms,
                                  .idle_timeout_ms = c->http_idle_timeout_ms },
                      .max_body_bytes = c->http_max_body_bytes };
  svc->http = ds_http_server_new (&o, svc->live, render_metrics, svc, error);
  if (!svc->http)
    return FALSE;
  ds_sequencer_set_frame_hook (svc->sequencer, ds_live_view_on_frame, svc->live);
  g_message ("live view and /metrics at %s%s", ds_http_server_url (svc->http),
             svc->http_token_path ? " (its token: `descatterctl live-url`)" : "");
  return TRUE;
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
  g_autofree char *text = ds_service_effective_config_text (svc);
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
  svc->started_unix_us = g_get_real_time ();
  svc->metrics = ds_metrics_new ();
  svc->pending = g_hash_table_new_full (g_int64_hash, g_int64_equal, NULL, ds_service_pending_free);
  svc->config = g_steal_pointer (&pf->config);
  DsServerLimits limits = { .max_clients = svc->config->max_clients,
                            .max_tcp_clients = svc->config->max_tcp_clients,
                            .max_line = DS_PROTOCOL_MAX_LINE,
                            .max_queued_bytes = svc->config->max_queued_bytes,
                            .token = pf->token, /* copied by the server */
                            .idle_timeout_ms = svc->config->idle_timeout_ms,
                            .auth_timeout_ms = svc->config->auth_timeout_ms };
  svc->server = ds_server_new (&limits, ds_service_on_request, svc);
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
                                     g_main_loop_get_context (loop), ds_service_on_sequencer_event, svc);
  ds_sequencer_set_preview_hook (svc->sequencer, ds_service_on_preview_frame, svc);
  if (svc->model)
    ds_sequencer_set_operating_model (svc->sequencer, svc->model, svc->config->timing_settle_ms,
                                      svc->config->timing_link_mbit);
  if (!start_http (svc, pf, error))
    return NULL;
  if (sd_watchdog_enabled (0, &svc->watchdog_usec) > 0)
    svc->watchdog_source = g_timeout_add ((guint) (svc->watchdog_usec / 4000), watchdog_tick, svc);
  return g_steal_pointer (&svc);
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
  ov.running = TRUE;
  g_autoptr (DsPreflight) pf = ds_preflight_run (fresh, &ov, error);
  if (!pf) {
    g_prefix_error (error, "reload refused, keeping the running configuration: ");
    return FALSE;
  }
  g_clear_pointer (&fresh, ds_config_free);
  fresh = g_steal_pointer (&pf->config);
  /* The key table's reload column decides (daemon/config/config.c): a key used only at start
   * cannot change under the running acquisition thread. The file is then refused as a whole,
   * so that the daemon never runs half of it. */
  g_autofree char *restart_keys = ds_config_restart_keys_changed (svc->config, fresh);
  if (restart_keys) {
    g_autofree char *live_keys = ds_config_live_keys ();
    g_set_error (error, DS_CONFIG_ERROR, DS_CONFIG_ERROR_INCONSISTENT,
                 "reload refused, keeping the running configuration: %s changes keys that need a restart: %s "
                 "(a reload applies only %s, from the next set)",
                 svc->config_path, restart_keys, live_keys);
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
  if (svc->http_token_path)
    g_unlink (svc->http_token_path);
  g_clear_pointer (&svc->http_token_path, g_free);
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
