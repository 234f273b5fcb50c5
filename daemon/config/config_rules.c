/* The configuration's cross-key rules (config_rules.h): each states what a file must hold
 * together and says how to fix it when it does not. */
#include "daemon/config/config_rules.h"

#include <math.h>
#include <string.h>

/* The largest sample a pixel format of the [camera] pixel-format choices carries (DN): MonoB,
 * MonoBp and MonoBPacked hold B bits. */
static double
pixel_format_top (const char *name)
{
  guint64 bits = g_ascii_strtoull (name + strlen ("Mono"), NULL, 10);
  return bits >= 8 && bits <= 16 ? (double) ((1u << bits) - 1) : 65535.0;
}

gboolean
ds_config_check_consistency (const DsConfig *c, const char *name, GError **error)
{
#define INCONSISTENT(...)                                                                          \
  do {                                                                                             \
    g_autofree char *msg_ = g_strdup_printf (__VA_ARGS__);                                         \
    g_set_error (error, DS_CONFIG_ERROR, DS_CONFIG_ERROR_INCONSISTENT, "%s: %s", name, msg_);      \
    return FALSE;                                                                                  \
  } while (0)
  if (c->single_frame && strcmp (c->estimator, "robust") == 0)
    INCONSISTENT ("[acquisition] single-frame = true with estimator = robust: one frame holds one stripe period "
                  "per pixel, too few samples for robust; use maxmin or sine");
  if (!c->camera_backend)
    INCONSISTENT ("[camera] backend is not set: aravis for a GigE Vision camera, or sim for the "
                  "simulated lab (descatterd --sim runs that without a file)");
  if (!c->illuminator_backend)
    INCONSISTENT ("[illuminator] backend is not set: modbus or gpio for a stripe projector, or sim "
                  "for the simulated lab (descatterd --sim runs that without a file)");
  gboolean sim_camera = strcmp (c->camera_backend, "sim") == 0;
  gboolean sim_illuminator = strcmp (c->illuminator_backend, "sim") == 0;
  if (sim_camera != sim_illuminator)
    INCONSISTENT ("[camera] backend = %s with [illuminator] backend = %s: the simulated camera sees only "
                  "the simulated illuminator's stripes and the simulated illuminator lights only the "
                  "simulated scene; use sim for both, or real devices for both",
                  c->camera_backend, c->illuminator_backend);
  if (!sim_camera && (c->sim_scene || c->sim_faults))
    INCONSISTENT ("[sim] %s is set but no device is simulated ([camera] backend = %s): it would be "
                  "ignored; remove it", c->sim_scene ? "scene" : "faults", c->camera_backend);
  if (strcmp (c->camera_backend, "aravis") == 0 && !c->camera_address)
    INCONSISTENT ("[camera] backend = aravis needs [camera] address");
  if (strcmp (c->illuminator_backend, "modbus") == 0 && !c->modbus_uri)
    INCONSISTENT ("[illuminator] backend = modbus needs [illuminator] modbus-uri");
  if (strcmp (c->illuminator_backend, "gpio") == 0 && (!c->gpio_chip || !c->gpio_lines))
    INCONSISTENT ("[illuminator] backend = gpio needs [illuminator] gpio-chip and gpio-lines");
  if (strcmp (c->trigger_backend, "gpio") == 0 && (c->trigger_gpio_line < 0 || !c->gpio_chip))
    INCONSISTENT ("[trigger] backend = gpio needs [trigger] gpio-line and [illuminator] gpio-chip");
  if (strcmp (c->trigger_backend, "gpio") == 0 && strcmp (c->camera_trigger, "software") == 0)
    INCONSISTENT ("[trigger] backend = gpio pulses a line, so [camera] trigger must name a line, not software");
  if (strcmp (c->trigger_backend, "software") == 0 && strcmp (c->camera_trigger, "software") != 0)
    INCONSISTENT ("[camera] trigger = %s waits for a pulse on that line, but [trigger] backend = software "
                  "sends none: set [trigger] backend = gpio with its gpio-line, or [camera] trigger = software",
                  c->camera_trigger);
  if (strcmp (c->trigger_backend, "gpio") == 0 && sim_camera)
    INCONSISTENT ("[trigger] backend = gpio pulses a line wired to a camera input, and the simulated camera "
                  "([camera] backend = sim) has none: use a GigE Vision camera ([camera] backend = aravis; "
                  "descatter-labsim's camera sees its own chip, [illuminator] gpio-chip = labsim:PATH)");
  if (c->gpio_chip && g_str_has_prefix (c->gpio_chip, "labsim:") && !g_path_is_absolute (c->gpio_chip + 7))
    INCONSISTENT ("[illuminator] gpio-chip = \"%s\": labsim: must be followed by the absolute path of "
                  "descatter-labsim's --gpio-chip socket", c->gpio_chip);
  guint roi[4];
  if (c->roi && !ds_config_parse_roi (c->roi, roi, error)) {
    g_prefix_error (error, "%s: ", name);
    return FALSE;
  }
  /* Paths: a relative one depends on the directory the daemon happens to start in (/ under
   * systemd); a socket path must fit sockaddr_un or bind would cut it short. */
  const struct { const char *group, *key, *value; } paths[] = {
    { "daemon", "socket", c->socket_path },        { "daemon", "spool-dir", c->spool_dir },
    { "daemon", "tcp-token-file", c->tcp_token_file }, { "acquisition", "operating-model", c->operating_model },
    { "sim", "scene", c->sim_scene },              { "http", "token-file", c->http_token_file },
  };
  for (guint i = 0; i < G_N_ELEMENTS (paths); i++)
    if (paths[i].value && !g_path_is_absolute (paths[i].value))
      INCONSISTENT ("[%s] %s = \"%s\" must be an absolute path", paths[i].group, paths[i].key, paths[i].value);
  if (c->socket_path && strlen (c->socket_path) >= DS_CONFIG_MAX_SOCKET_PATH)
    INCONSISTENT ("[daemon] socket = \"%s\" is %zu bytes long; a UNIX socket path has at most %d",
                  c->socket_path, strlen (c->socket_path), DS_CONFIG_MAX_SOCKET_PATH - 1);
  if (c->max_tcp_clients && c->max_tcp_clients >= c->max_clients)
    INCONSISTENT ("[daemon] max-tcp-clients = %u must be below max-clients = %u, so that local "
                  "clients always find room", c->max_tcp_clients, c->max_clients);
  if (strcmp (c->trigger_backend, "projector-sync") == 0 && strcmp (c->camera_trigger, "software") == 0)
    INCONSISTENT ("[trigger] backend = projector-sync: the sync output drives a camera line, so [camera] trigger "
                  "must name that line, not software");
  if (strcmp (c->trigger_backend, "projector-sync") == 0 && sim_camera)
    INCONSISTENT ("[trigger] backend = projector-sync needs a camera whose line the projector drives; the "
                  "simulated camera has none");
  if (!isnan (c->edge_blur_px) && !(c->edge_blur_px < c->period_px / 2))
    INCONSISTENT ("[illuminator] edge-blur-px = %g must be below half the period (period-px = %g): blur that "
                  "wide leaves no stripes to separate", c->edge_blur_px, c->period_px);
  if (!isnan (c->saturation_dn) && c->saturation_dn > pixel_format_top (c->pixel_format))
    INCONSISTENT ("[camera] saturation-dn = %g is above the top of pixel-format = %s (%.0f DN): samples never "
                  "reach it", c->saturation_dn, c->pixel_format, pixel_format_top (c->pixel_format));
  if (!isnan (c->read_noise_dn) && isnan (c->gain_dn_per_e))
    INCONSISTENT ("[camera] read-noise-dn = %g without gain-dn-per-e: the noise model needs the system gain "
                  "(DN per electron) for the shot noise; set both or neither", c->read_noise_dn);
  if (strcmp (c->estimator, "sine") == 0 && c->phases < 3)
    INCONSISTENT ("[acquisition] estimator = sine needs phases >= 3 (got %u)", c->phases);
  if (strcmp (c->results, "per-frame") == 0 && c->averages > 1)
    INCONSISTENT ("[acquisition] results = per-frame needs averages = 1 (got %u): the sliding window holds one "
                  "frame per phase and does not average", c->averages);
  if (strcmp (c->results, "per-frame") == 0 && c->single_frame)
    INCONSISTENT ("[acquisition] results = per-frame with single-frame = true: a single-frame result is "
                  "already one per frame");
  if (c->spool_dir && (!c->spool_formats || !*c->spool_formats))
    INCONSISTENT ("[daemon] spool-formats is empty: name at least one of tiff, png16, preview, hdf5, hdf5-run");
  if (c->http_listen && !ds_config_parse_host_port (c->http_listen, NULL, NULL))
    INCONSISTENT ("[http] listen = \"%s\" must be IP:PORT (a numeric address, port 0..65535)", c->http_listen);
  if (c->tcp_listen && !ds_config_parse_host_port (c->tcp_listen, NULL, NULL))
    INCONSISTENT ("[daemon] tcp-listen = \"%s\" must be IP:PORT (a numeric address, port 0..65535)",
                  c->tcp_listen);
  if (c->http_max_live_clients >= c->http_max_connections)
    INCONSISTENT ("[http] max-live-clients = %u must be below max-connections = %u (a page's WebSocket is one "
                  "of them, its page and /metrics need others)", c->http_max_live_clients, c->http_max_connections);
  if (c->http_server_names) {
    g_auto (GStrv) names = g_strsplit (c->http_server_names, ",", -1);
    for (guint i = 0; names[i]; i++) {
      g_strstrip (names[i]);
      if (!*names[i] || strpbrk (names[i], " \t/@?#") != NULL)
        INCONSISTENT ("[http] server-names: \"%s\" is not a host name (name or name:port, comma-separated)",
                      names[i]);
    }
  }
#undef INCONSISTENT
  return TRUE;
}
