/* descatterd: the lab service. Parses options, loads the configuration and runs the main
 * loop; everything else is DsService (daemon/service.c). */
#include <glib-unix.h>
#include <locale.h>
#include <stdio.h>
#include <systemd/sd-daemon.h>

#include "build_info.h"
#include "daemon/config/config.h"
#include "daemon/service/preflight.h"
#include "daemon/service/probe.h"
#include "daemon/service/service.h"

#define DEFAULT_CONFIG DS_SYSCONF_DIR "/descatterd.conf"

typedef struct {
  GMainLoop *loop;
  DsService *service;
  gboolean stopping;
} Signals;

static gboolean
on_term (gpointer data)
{
  Signals *s = data;
  /* A second signal while replies are still being written changes nothing. */
  if (s->stopping)
    return G_SOURCE_CONTINUE;
  s->stopping = TRUE;
  g_message ("stopping");
  sd_notify (0, "STOPPING=1");
  g_main_loop_quit (s->loop);
  return G_SOURCE_CONTINUE;
}

static gboolean
on_hup (gpointer data)
{
  Signals *s = data;
  g_autoptr (GError) error = NULL;
  if (s->stopping || !s->service)
    return G_SOURCE_CONTINUE;
  sd_notify (0, "RELOADING=1");
  if (ds_service_reload (s->service, &error))
    g_message ("configuration reloaded");
  else
    g_warning ("%s", error->message);
  sd_notify (0, "READY=1");
  return G_SOURCE_CONTINUE;
}

int
main (int argc, char **argv)
{
  setlocale (LC_ALL, "");
  g_autofree char *config_path = NULL, *socket_path = NULL, *tcp = NULL, *scene = NULL, *http = NULL;
  gboolean sim = FALSE, check = FALSE, probe = FALSE, no_systemd = FALSE, version = FALSE;
  GOptionEntry entries[] = {
    { "version", 'V', 0, G_OPTION_ARG_NONE, &version, "Print the version and exit", NULL },
    { "config", 'c', 0, G_OPTION_ARG_FILENAME, &config_path, "Configuration file (default " DEFAULT_CONFIG ")", "FILE" },
    { "sim", 0, 0, G_OPTION_ARG_NONE, &sim, "Run on the built-in simulated lab (no configuration file)", NULL },
    { "check", 0, 0, G_OPTION_ARG_NONE, &check, "Validate the configuration, print the effective settings and exit", NULL },
    { "probe", 0, 0, G_OPTION_ARG_NONE, &probe, "With --check: also open the devices, give them the configured settings as start does, print what they are and allow, and fail on any refusal", NULL },
    { "socket", 's', 0, G_OPTION_ARG_FILENAME, &socket_path, "UNIX socket path (overrides [daemon] socket)", "PATH" },
    { "tcp", 0, 0, G_OPTION_ARG_STRING, &tcp, "TCP listen address host:port (overrides [daemon] tcp-listen)", "ADDR" },
    { "http", 0, 0, G_OPTION_ARG_STRING, &http, "Live view and /metrics on host:port (overrides [http] listen)", "ADDR" },
    { "scene", 0, 0, G_OPTION_ARG_FILENAME, &scene, "Scene file for the simulated lab (overrides [sim] scene)", "FILE" },
    { "no-socket-activation", 0, 0, G_OPTION_ARG_NONE, &no_systemd, "Ignore sockets passed by systemd", NULL },
    { NULL },
  };
  g_autoptr (GOptionContext) ctx = g_option_context_new ("- near-infrared descattering lab service");
  g_option_context_add_main_entries (ctx, entries, NULL);
  g_autoptr (GError) error = NULL;
  if (!g_option_context_parse (ctx, &argc, &argv, &error)) {
    fprintf (stderr, "descatterd: %s\n", error->message);
    return 2;
  }
  if (version) {
    printf ("descatterd %s (%s)\n", DS_VERSION, DS_GIT_DESCRIBE);
    return 0;
  }
  if (sim && config_path) {
    fprintf (stderr, "descatterd: --sim and --config exclude each other\n");
    return 2;
  }
  if (probe && !check) {
    fprintf (stderr, "descatterd: --probe is a part of --check: use --check --probe\n");
    return 2;
  }
  g_autoptr (DsConfig) config = NULL;
  if (sim)
    config = ds_config_new_sim ();
  else {
    if (!config_path)
      config_path = g_strdup (DEFAULT_CONFIG);
    config = ds_config_load_file (config_path, &error);
  }
  if (!config) {
    fprintf (stderr, "descatterd: %s\n", error->message);
    return 1;
  }
  if (check) {
    /* The very checks start-up runs (preflight.h), with the same overrides. */
    DsPreflightOverrides ov = { .config_name = config_path, .socket_path = socket_path, .tcp_listen = tcp,
                                .scene_path = scene, .http_listen = http };
    g_autoptr (DsPreflight) pf = ds_preflight_run (config, &ov, &error);
    if (!pf) {
      fprintf (stderr, "descatterd: %s\n", error->message);
      return 1;
    }
    g_autofree char *text = ds_config_to_data (pf->config);
    printf ("# effective configuration (%s)\n", config_path ? config_path : "built-in");
    if (pf->model_note)
      printf ("# automatic operating point off: %s\n", pf->model_note);
    else
      printf ("# operating model: %s\n", pf->model_path);
    printf ("%s", text);
    fflush (stdout);
    if (probe) {
      printf ("# probing the devices\n");
      if (!ds_probe_run (pf, stdout, &error)) {
        fprintf (stderr, "descatterd: %s\n", error->message);
        return 1;
      }
      printf ("# the devices took the configured settings\n");
    }
    return 0;
  }
  g_autoptr (GMainLoop) loop = g_main_loop_new (NULL, FALSE);
  DsServiceOptions opts = { .config_path = config_path, .socket_path = socket_path,
                            .tcp_listen = tcp, .http_listen = http, .scene_path = scene,
                            .no_systemd_sockets = no_systemd };
  /* The handlers come before the service: once its socket exists a client may already send
   * SIGTERM (a test, systemd), which must stop the daemon cleanly, not kill it. */
  Signals sig = { loop, NULL, FALSE };
  guint s1 = g_unix_signal_add (SIGTERM, on_term, &sig);
  guint s2 = g_unix_signal_add (SIGINT, on_term, &sig);
  guint s3 = g_unix_signal_add (SIGHUP, on_hup, &sig);
  g_autoptr (DsService) service = ds_service_new (g_steal_pointer (&config), &opts, loop, &error);
  if (!service) {
    fprintf (stderr, "descatterd: %s\n", error->message);
    g_source_remove (s1);
    g_source_remove (s2);
    g_source_remove (s3);
    return 1;
  }
  sig.service = service;
  if (ds_service_socket_path (service))
    printf ("descatterd: listening on %s\n", ds_service_socket_path (service));
  if (ds_service_tcp_port (service))
    printf ("descatterd: listening on tcp port %u\n", ds_service_tcp_port (service));
  if (ds_service_http_url (service))
    printf ("descatterd: live view and /metrics at %s\n", ds_service_http_url (service));
  fflush (stdout);
  /* A signal handled while the service started has already asked to stop. */
  if (!sig.stopping)
    g_main_loop_run (loop);
  sig.stopping = TRUE;
  gboolean failed = ds_service_devices_failed (service);
  /* The handlers stay until the service is gone: stopping runs the main context to write the
   * last replies, and a second SIGTERM meanwhile must not kill the process with them unsent. */
  g_clear_pointer (&service, ds_service_free);
  g_source_remove (s1);
  g_source_remove (s2);
  g_source_remove (s3);
  return failed ? 1 : 0;
}
