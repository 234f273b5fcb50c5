#include "daemon/config/config.h"
#include "daemon/config/config_rules.h"

#include <errno.h>
#include <fcntl.h>
#include <glib/gstdio.h>
#include <unistd.h>
#include <math.h>
#include <stddef.h>
#include <stdlib.h>
#include <string.h>
#include <sys/un.h>

G_DEFINE_QUARK (ds-config-error-quark, ds_config_error)

G_STATIC_ASSERT (sizeof (((struct sockaddr_un *) NULL)->sun_path) == DS_CONFIG_MAX_SOCKET_PATH);

/* K_CHOICES: a comma-separated subset of `choices` (stored normalized, "a,b"). */
typedef enum { K_STRING, K_CHOICE, K_UINT, K_UINT64, K_INT, K_DOUBLE, K_BOOL, K_MODE, K_CHOICES } KeyType;

/* What SIGHUP may do with a key's new value (ds_config_restart_keys_changed).
 * LIVE: the value reaches the acquisition only through the capture defaults
 * (ds_capture_settings_from_config), which the acquisition thread takes from its command queue
 * between sets: it applies from the next set, never within one.
 * RESTART: the value was used once, at start: to open a device (which the acquisition thread
 * owns), bind a socket, set up the spool or the HTTP side, or to load the operating model and the
 * timing of automatic captures, which the acquisition thread reads without a lock. Changing it
 * under a running daemon would race with that thread or leave the daemon saying one thing and
 * doing another, so a reload that changes it is refused. */
typedef enum { RESTART, LIVE } ReloadRule;

typedef struct {
  const char *group;
  const char *key;
  KeyType type;
  ReloadRule reload;
  size_t offset;
  const char *def;      /* textual default, NULL = unset */
  double min, max;      /* numeric range */
  const char *choices;  /* '|'-separated for K_CHOICE */
  const char *doc;
} KeySpec;

#define F(field) offsetof (DsConfig, field)

static const KeySpec keys[] = {
  { "daemon", "socket", K_STRING, RESTART, F (socket_path), "/run/descatterd/descatterd.sock", 0, 0, NULL,
    "UNIX socket path (ignored when systemd passes sockets)" },
  { "daemon", "socket-mode", K_MODE, RESTART, F (socket_mode), "0660", 0, 0777, NULL,
    "permissions of the UNIX socket (octal); the group decides who may connect" },
  { "daemon", "tcp-listen", K_STRING, RESTART, F (tcp_listen), NULL, 0, 0, NULL,
    "host:port for TCP, empty = off; a non-loopback host needs tcp-token-file" },
  { "daemon", "tcp-token-file", K_STRING, RESTART, F (tcp_token_file), NULL, 0, 0, NULL,
    "file holding the token TCP clients must send in hello" },
  { "daemon", "max-clients", K_UINT, RESTART, F (max_clients), "32", 1, 1024, NULL,
    "connections served at once; when full, the connection quiet longest makes room (docs/protocol.md)" },
  { "daemon", "max-tcp-clients", K_UINT, RESTART, F (max_tcp_clients), "0", 0, 1023, NULL,
    "of which TCP at most, so that local clients always find room; 0 = half of max-clients" },
  { "daemon", "idle-timeout-ms", K_UINT, RESTART, F (idle_timeout_ms), "60000", 0, 86400000, NULL,
    "a connection without a complete request for this long is closed (subscribers and "
    "connections waiting for a reply excepted); 0 = never" },
  { "daemon", "auth-timeout-ms", K_UINT, RESTART, F (auth_timeout_ms), "5000", 100, 600000, NULL,
    "a TCP connection that owes the token must send hello within this time" },
  { "daemon", "max-queued-bytes", K_UINT64, RESTART, F (max_queued_bytes), "268435456", 65536, 17179869184.0, NULL,
    "bytes queued per client before its stream results are dropped" },
  { "daemon", "spool-dir", K_STRING, RESTART, F (spool_dir), NULL, 0, 0, NULL,
    "record every result here (float32 TIFF + JSON), empty = off" },
  { "daemon", "spool-max-bytes", K_UINT64, RESTART, F (spool_max_bytes), "10737418240", 1048576, 1e15, NULL,
    "oldest recordings are removed beyond this size" },
  { "daemon", "spool-formats", K_CHOICES, RESTART, F (spool_formats), "tiff", 0, 0,
    "tiff|png16|preview|hdf5|hdf5-run",
    "files per recorded set: float32 TIFF (+ mask PNG), 16-bit direct/global PNG, 8-bit previews, one HDF5 "
    "(NeXus) file per set, or one growing HDF5 file per continuous run" },
  { "daemon", "spool-save-phases", K_BOOL, RESTART, F (spool_save_phases), "false", 0, 0, NULL,
    "also record every set's raw phase and dark frames (a phase folder; in the HDF5 files too)" },
  { "daemon", "spool-max-pending", K_UINT, RESTART, F (spool_max_pending), "8", 1, 1024, NULL,
    "results waiting for the disk before further ones are not recorded (counted) rather than delay "
    "acquisition" },

  { "http", "listen", K_STRING, RESTART, F (http_listen), NULL, 0, 0, NULL,
    "host:port of the live view and /metrics (HTTP + WebSocket), empty = off; a non-loopback host "
    "needs token-file" },
  { "http", "token-file", K_STRING, RESTART, F (http_token_file), NULL, 0, 0, NULL,
    "file holding the token HTTP clients must present (?token= or Authorization: Bearer)" },
  { "http", "live-fps", K_DOUBLE, RESTART, F (http_live_fps), "10", 0.1, 100, NULL,
    "most raw frames per second copied for the live view" },
  { "http", "server-names", K_STRING, RESTART, F (http_server_names), NULL, 0, 0, NULL,
    "further names the page may be opened by (comma-separated, \"name\" or \"name:port\"); a request "
    "whose Host is neither these nor the listen address (or localhost on loopback) is refused" },
  { "http", "max-connections", K_UINT, RESTART, F (http_max_connections), "64", 1, 4096, NULL,
    "HTTP connections at once, WebSockets included; beyond, refused with 503 (kept below the "
    "descriptor limit with room for max-clients)" },
  { "http", "max-connections-per-peer", K_UINT, RESTART, F (http_max_per_peer), "32", 1, 4096, NULL,
    "HTTP connections at once from one address" },
  { "http", "max-header-bytes", K_UINT, RESTART, F (http_max_header_bytes), "16384", 1024, 1048576, NULL,
    "a request's headers; beyond, nothing more is read and the connection is closed" },
  { "http", "max-body-bytes", K_UINT, RESTART, F (http_max_body_bytes), "0", 0, 1048576, NULL,
    "a request's body (the server takes none); a longer Content-Length, or a chunked body, is "
    "refused with 413 before any of it is read" },
  { "http", "header-timeout-ms", K_UINT, RESTART, F (http_header_timeout_ms), "10000", 100, 600000, NULL,
    "a request's headers and body must arrive within this time of its first byte" },
  { "http", "idle-timeout-ms", K_UINT, RESTART, F (http_idle_timeout_ms), "30000", 100, 3600000, NULL,
    "a connection with no request started for this long is closed (WebSockets excepted)" },
  { "http", "max-live-clients", K_UINT, RESTART, F (http_max_live_clients), "8", 1, 256, NULL,
    "live-view pages at once; their controls take no place of [daemon] max-clients" },
  { "http", "live-send-budget-bytes", K_UINT, RESTART, F (http_live_send_budget), "1048576", 65536, 67108864, NULL,
    "unsent bytes per live-view page beyond which it gets no update until it reads (newer "
    "updates replace the waiting ones)" },

  { "camera", "backend", K_CHOICE, RESTART, F (camera_backend), NULL, 0, 0, "aravis|sim",
    "camera driver: aravis (GigE Vision) or sim (the simulated lab); no default, so that a file "
    "never runs simulated devices by omission" },
  { "camera", "address", K_STRING, RESTART, F (camera_address), NULL, 0, 0, NULL,
    "aravis: camera IP address or device id" },
  { "camera", "pixel-format", K_CHOICE, RESTART, F (pixel_format), "Mono16", 0, 0,
    "Mono8|Mono10|Mono12|Mono16|Mono10p|Mono12p|Mono12Packed", "pixel format on the wire" },
  { "camera", "exposure-us", K_DOUBLE, LIVE, F (exposure_us), "5000", 1, 10e6, NULL, "exposure time (µs)" },
  { "camera", "gain-db", K_DOUBLE, LIVE, F (gain_db), "0", 0, 48, NULL, "analogue gain (dB)" },
  { "camera", "saturation-dn", K_DOUBLE, RESTART, F (saturation_dn), "", 1, 65535, NULL,
    "level (DN) at which the sensor clips, for a full well below the pixel format's top; clipped "
    "samples are flagged and the automatic operating point keeps exposures below it; empty = the "
    "pixel format's top" },
  { "camera", "gain-dn-per-e", K_DOUBLE, LIVE, F (gain_dn_per_e), "", 1e-6, 1000, NULL,
    "the camera's system gain K (DN per electron, EMVA 1288) at the configured gain-db, with read-noise-dn "
    "the separation's per-pixel noise model (noise sigma, the motion bit's false alarms); empty = the noise "
    "read off each frame" },
  { "camera", "read-noise-dn", K_DOUBLE, LIVE, F (read_noise_dn), "", 0, 65535, NULL,
    "the camera's temporal dark noise sigma (DN) at the configured gain-db, for the noise model with "
    "gain-dn-per-e; empty = 0 when gain-dn-per-e is set" },
  { "camera", "pixel-pitch-um", K_DOUBLE, RESTART, F (pixel_pitch_um), "", 0.01, 1000, NULL,
    "the sensor's pixel pitch (µm); empty = the camera's SensorPixelWidth when it has that feature; "
    "with [optics] magnification it gives the result files' physical scale" },
  { "camera", "roi", K_STRING, RESTART, F (roi), NULL, 0, 0, NULL, "x,y,width,height; empty = full sensor" },
  { "camera", "trigger", K_CHOICE, RESTART, F (camera_trigger), "software", 0, 0, "software|line0|line1|line2|line3",
    "trigger source of the camera" },
  { "camera", "acceptance-half-angle-deg", K_DOUBLE, RESTART, F (acceptance_half_angle_deg), "", 0.01, 90, NULL,
    "half-angle of the lens's acceptance cone on the object side (degrees, from its NA); bounds the light a thin "
    "film scatters into the lens for the automatic operating point; empty = not known" },
  { "camera", "grab-timeout-ms", K_UINT, RESTART, F (grab_timeout_ms), "2000", 10, 600000, NULL,
    "deadline for a frame after its trigger, beyond the exposure" },
  { "camera", "receive-buffer-frames", K_UINT, RESTART, F (receive_buffer_frames), "4", 1, 64, NULL,
    "aravis, GigE Vision: the UDP receive buffer asked for, in frames (payloads): packets wait there "
    "while the daemon's threads have the CPUs; net.core.rmem_max caps it" },
  { "camera", "frame-retention-ms", K_UINT, RESTART, F (frame_retention_ms), "100", 1, 10000, NULL,
    "aravis, GigE Vision: how long a frame missing packets waits after its last packet for resent or "
    "late ones before it counts as incomplete" },
  { "camera", "sends-after-exposure", K_BOOL, RESTART, F (sends_after_exposure), "true", 0, 0, NULL,
    "the camera begins sending a frame only once the whole frame's exposure is over (global shutter, "
    "or a rolling shutter that reads out before sending): the illuminator then moves to the next phase "
    "during the transfer; false = only after the frame arrived" },

  { "optics", "magnification", K_DOUBLE, RESTART, F (magnification), "", 1e-6, 1e6, NULL,
    "the lens' magnification (image size over object size); the object-plane pixel size is the "
    "pixel pitch over it; empty = unknown: result files then give pixel indices, no physical scale" },

  { "illuminator", "backend", K_CHOICE, RESTART, F (illuminator_backend), NULL, 0, 0, "modbus|gpio|sim",
    "illuminator driver: modbus, gpio, or sim (the simulated lab); no default" },
  { "illuminator", "modbus-uri", K_STRING, RESTART, F (modbus_uri), NULL, 0, 0, NULL,
    "tcp://host:port or rtu:/dev/ttyUSB0?baud=115200&parity=N&data=8&stop=1" },
  { "illuminator", "modbus-unit-id", K_UINT, RESTART, F (modbus_unit_id), "1", 0, 247, NULL, "Modbus unit id" },
  { "illuminator", "modbus-timeout-ms", K_UINT, RESTART, F (modbus_timeout_ms), "200", 5, 10000, NULL,
    "response timeout per Modbus request" },
  { "illuminator", "gpio-chip", K_STRING, RESTART, F (gpio_chip), NULL, 0, 0, NULL,
    "gpio: chip name or path (libgpiod), or labsim:/path/of/its.sock for descatter-labsim's --gpio-chip" },
  { "illuminator", "gpio-lines", K_STRING, RESTART, F (gpio_lines), NULL, 0, 0, NULL,
    "gpio: comma-separated line offsets, one per stripe group" },
  { "illuminator", "gpio-enable-line", K_INT, RESTART, F (gpio_enable_line), "-1", -1, 4095, NULL,
    "gpio: enable line offset, -1 = none" },
  { "illuminator", "pattern", K_CHOICE, RESTART, F (pattern), "square", 0, 0, "square|sine", "stripe profile" },
  { "illuminator", "period-px", K_DOUBLE, RESTART, F (period_px), "16", 2, 4096, NULL,
    "stripe period as seen by the camera (pixels)" },
  { "illuminator", "duty", K_DOUBLE, RESTART, F (duty), "0.5", 0.01, 0.99, NULL, "lit fraction of a period" },
  { "illuminator", "black-level", K_DOUBLE, RESTART, F (black_level), "0", 0, 0.99, NULL,
    "off-stripe leakage relative to on (b)" },
  { "illuminator", "harmonic-gain", K_DOUBLE, RESTART, F (harmonic_gain), "", 0.001, 1, NULL,
    "stripe modulation h as the camera sees it (descatterctl calibrate); used by the sine estimator and "
    "the automatic operating point's blur; empty = the sharp pattern's" },
  { "illuminator", "edge-blur-px", K_DOUBLE, RESTART, F (edge_blur_px), "", 0, 2048, NULL,
    "Gaussian sigma of the stripes' edges on the sensor in pixels (descatterctl calibrate), for the "
    "automatic operating point; empty = from harmonic-gain, or measured by the pilot frames" },
  { "illuminator", "open-field-dn-per-ms", K_DOUBLE, RESTART, F (open_field_dn_per_ms), "", 1e-6, 1e9, NULL,
    "lit level of a fully lit pixel on a clear path above dark, DN per ms of exposure at 0 dB gain "
    "(descatterctl calibrate on a clear reference); the automatic operating point compares the scene's "
    "with it; empty = not measured" },
  { "illuminator", "open-field-pixel-format", K_STRING, RESTART, F (open_field_pixel_format), NULL, 0, 0, NULL,
    "the camera's pixel format open-field-dn-per-ms was measured in (descatterctl calibrate): its DN are that "
    "format's, so under another [camera] pixel-format it is not used; empty = not said (taken as the camera's)" },
  { "illuminator", "intensity", K_DOUBLE, RESTART, F (intensity), "1", 0, 1, NULL, "drive level" },
  { "illuminator", "settle-timeout-ms", K_UINT, RESTART, F (settle_timeout_ms), "500", 1, 60000, NULL,
    "deadline for a phase to be applied and read back" },

  { "trigger", "backend", K_CHOICE, RESTART, F (trigger_backend), "software", 0, 0,
    "software|gpio|projector-sync",
    "how frames are triggered (projector-sync: the illuminator's sync output drives the camera's line)" },
  { "trigger", "gpio-line", K_INT, RESTART, F (trigger_gpio_line), "-1", -1, 4095, NULL, "gpio: trigger line offset" },
  { "trigger", "pulse-us", K_UINT, RESTART, F (trigger_pulse_us), "100", 1, 1000000, NULL, "gpio: pulse width" },
  { "trigger", "active-low", K_BOOL, RESTART, F (trigger_active_low), "false", 0, 0, NULL, "gpio: pulse polarity" },

  { "acquisition", "phases", K_UINT, LIVE, F (phases), "8", 2, 64, NULL, "phases per set (N)" },
  { "acquisition", "averages", K_UINT, LIVE, F (averages), "1", 1, 64, NULL, "frames averaged per phase (M)" },
  { "acquisition", "estimator", K_CHOICE, LIVE, F (estimator), "maxmin", 0, 0, "maxmin|sine|robust",
    "separation estimator" },
  { "acquisition", "dark-frame", K_BOOL, LIVE, F (dark_frame), "true", 0, 0, NULL,
    "take a frame with the illuminator off and subtract it" },
  { "acquisition", "phase-retries", K_UINT, LIVE, F (phase_retries), "3", 0, 20, NULL,
    "retries of one phase before the set fails" },
  { "acquisition", "max-failed-sets", K_UINT, LIVE, F (max_failed_sets), "10", 0, 1000000, NULL,
    "continuous acquisition stops after this many sets in a row failed, saying why; 0 = never" },
  { "acquisition", "results", K_CHOICE, LIVE, F (results), "per-set", 0, 0, "per-set|per-frame",
    "continuous mode: a result per phase set, or one per frame from the latest N phases (needs averages = 1)" },
  { "acquisition", "verify-phase", K_BOOL, LIVE, F (verify_phase), "true", 0, 0, NULL,
    "measure the stripe phase in each frame and refuse frames lit with the wrong phase" },
  { "acquisition", "detect-motion", K_BOOL, LIVE, F (detect_motion), "false", 0, 0, NULL,
    "flag pixels whose phase samples depart from a still scene beyond noise (mask bit motion; N >= 4)" },
  { "acquisition", "speed-px-s", K_DOUBLE, LIVE, F (speed_px_s), "", 0, 1e6, NULL,
    "declared speed of the scene's moving objects (px/s on the sensor, across the stripes, along x) for "
    "automatic captures: every prediction gets its motion term; empty = a still scene" },
  { "acquisition", "operating-model", K_STRING, RESTART, F (operating_model), NULL, 0, 0, NULL,
    "operating model for captures with target_error/time_budget_ms (descatterctl validate --fit); empty = the "
    "installed one" },
  { "acquisition", "settle-ms", K_DOUBLE, RESTART, F (timing_settle_ms), "3", 0, 10000, NULL,
    "illuminator settle time, for the acquisition-time model of automatic captures" },
  { "acquisition", "link-mbit", K_DOUBLE, RESTART, F (timing_link_mbit), "1000", 1, 100000, NULL,
    "camera link bandwidth, for the acquisition-time model of automatic captures" },
  { "acquisition", "phase-tolerance-deg", K_DOUBLE, LIVE, F (phase_tolerance_deg), "", 1, 180, NULL,
    "largest accepted stripe-phase error; empty = half the phase step (180/N)" },
  { "acquisition", "single-frame", K_BOOL, LIVE, F (single_frame), "false", 0, 0, NULL,
    "separate each frame alone (phase 0 lit) from one stripe period around each pixel, with the estimator "
    "maxmin or sine: a result per frame for moving scenes, at a resolution of one period along x" },

  { "sim", "scene", K_STRING, RESTART, F (sim_scene), NULL, 0, 0, NULL,
    "scene file for the simulated devices; empty = the built-in demo scene" },
  { "sim", "seed", K_UINT64, RESTART, F (sim_seed), "1", 0, 1e18, NULL, "noise seed of the simulation" },
  { "sim", "faults", K_STRING, RESTART, F (sim_faults), NULL, 0, 0, NULL,
    "injected faults of the simulated devices, e.g. stale=0.05,incomplete=0.02 (docs/reliability.md); empty = none" },
  { "sim", "geometry", K_CHOICE, RESTART, F (sim_geometry), "scene", 0, 0, "scene|config",
    "the stripe pattern descatterd assumes: scene = the simulated illuminator's (the scene's), config = "
    "[illuminator] pattern, period-px, duty and black-level as configured, as with real devices, while the "
    "simulated illuminator still draws the scene's stripes (to try a configuration or a calibration against a "
    "known illuminator)" },
};

static gboolean
is_text (const KeySpec *k)
{
  return k->type == K_STRING || k->type == K_CHOICE || k->type == K_CHOICES;
}

static gpointer
field (DsConfig *c, const KeySpec *k)
{
  return (guint8 *) c + k->offset;
}

static gboolean
bad_value (GError **error, const char *name, const KeySpec *k, const char *value, const char *why)
{
  g_set_error (error, DS_CONFIG_ERROR, DS_CONFIG_ERROR_BAD_VALUE, "%s: [%s] %s = \"%s\": %s", name, k->group,
               k->key, value, why);
  return FALSE;
}

static gboolean
parse_value (DsConfig *c, const KeySpec *k, const char *raw, const char *name, GError **error)
{
  g_autofree char *v = g_strstrip (g_strdup (raw));
  char *end = NULL;
  switch (k->type) {
  case K_STRING: {
    char **p = field (c, k);
    g_free (*p);
    *p = v[0] ? g_strdup (v) : NULL;
    return TRUE;
  }
  case K_CHOICES: {
    g_auto (GStrv) options = g_strsplit (k->choices, "|", -1);
    g_auto (GStrv) parts = g_strsplit (v, ",", -1);
    GString *norm = g_string_new (NULL);
    for (guint i = 0; parts[i]; i++) {
      const char *part = g_strstrip (parts[i]);
      if (!*part)
        continue;
      if (!g_strv_contains ((const char *const *) options, part)) {
        g_string_free (norm, TRUE);
        g_autofree char *why = g_strdup_printf ("\"%s\" is not one of %s (a comma-separated list)", part, k->choices);
        return bad_value (error, name, k, v, why);
      }
      g_string_append_printf (norm, "%s%s", norm->len ? "," : "", part);
    }
    char **p = field (c, k);
    g_free (*p);
    *p = g_string_free (norm, FALSE);
    return TRUE;
  }
  case K_CHOICE: {
    if (!v[0] && !(k->def && k->def[0])) { /* a choice without a default may stay unset */
      char **p = field (c, k);
      g_clear_pointer (p, g_free);
      return TRUE;
    }
    g_auto (GStrv) options = g_strsplit (k->choices, "|", -1);
    if (!g_strv_contains ((const char *const *) options, v)) {
      g_autofree char *why = g_strdup_printf ("must be one of %s", k->choices);
      return bad_value (error, name, k, v, why);
    }
    char **p = field (c, k);
    g_free (*p);
    *p = g_strdup (v);
    return TRUE;
  }
  case K_UINT:
  case K_UINT64:
  case K_INT:
  case K_MODE: {
    errno = 0;
    long long n = strtoll (v, &end, k->type == K_MODE ? 8 : 10);
    if (!v[0] || *end || errno) {
      const char *what = k->type == K_MODE ? "an octal mode" : "an integer";
      g_autofree char *why = g_strdup_printf ("must be %s in %.0f..%.0f", what, k->min, k->max);
      return bad_value (error, name, k, v, why);
    }
    if ((double) n < k->min || (double) n > k->max) {
      g_autofree char *why = g_strdup_printf ("outside %.0f..%.0f", k->min, k->max);
      return bad_value (error, name, k, v, why);
    }
    if (k->type == K_UINT64)
      *(guint64 *) field (c, k) = (guint64) n;
    else if (k->type == K_INT)
      *(int *) field (c, k) = (int) n;
    else
      *(guint *) field (c, k) = (guint) n;
    return TRUE;
  }
  case K_DOUBLE: {
    if (!v[0]) { /* empty: "automatic", stored as NAN */
      *(double *) field (c, k) = NAN;
      return TRUE;
    }
    double d = g_ascii_strtod (v, &end);
    if (*end || !isfinite (d) || d < k->min || d > k->max) {
      g_autofree char *why = g_strdup_printf ("must be a number in %g..%g", k->min, k->max);
      return bad_value (error, name, k, v, why);
    }
    *(double *) field (c, k) = d;
    return TRUE;
  }
  case K_BOOL:
    if (g_strcmp0 (v, "true") == 0 || g_strcmp0 (v, "false") == 0) {
      *(gboolean *) field (c, k) = v[0] == 't';
      return TRUE;
    }
    return bad_value (error, name, k, v, "must be true or false");
  }
  return FALSE;
}

DsConfig *
ds_config_new_default (void)
{
  DsConfig *c = g_new0 (DsConfig, 1);
  for (guint i = 0; i < G_N_ELEMENTS (keys); i++) {
    gboolean ok = parse_value (c, &keys[i], keys[i].def ? keys[i].def : "", "defaults", NULL);
    g_assert (ok); /* the table's own defaults are in range */
  }
  return c;
}

DsConfig *
ds_config_new_sim (void)
{
  DsConfig *c = ds_config_new_default ();
  c->camera_backend = g_strdup ("sim");
  c->illuminator_backend = g_strdup ("sim");
  return c;
}

void
ds_config_free (DsConfig *config)
{
  if (!config)
    return;
  for (guint i = 0; i < G_N_ELEMENTS (keys); i++)
    if (is_text (&keys[i]))
      g_free (*(char **) field (config, &keys[i]));
  g_free (config);
}

DsConfig *
ds_config_copy (const DsConfig *config)
{
  DsConfig *c = g_memdup2 (config, sizeof *config);
  for (guint i = 0; i < G_N_ELEMENTS (keys); i++)
    if (is_text (&keys[i])) {
      char **p = field (c, &keys[i]);
      *p = g_strdup (*p);
    }
  return c;
}

static const KeySpec *
find_key (const char *group, const char *key)
{
  for (guint i = 0; i < G_N_ELEMENTS (keys); i++)
    if (strcmp (keys[i].group, group) == 0 && strcmp (keys[i].key, key) == 0)
      return &keys[i];
  return NULL;
}

static gboolean
group_known (const char *group)
{
  for (guint i = 0; i < G_N_ELEMENTS (keys); i++)
    if (strcmp (keys[i].group, group) == 0)
      return TRUE;
  return FALSE;
}

/* GKeyFile keeps no line numbers; a person fixing a file wants one, so find it in the text. */
static guint
find_line (const char *data, const char *group, const char *key)
{
  g_auto (GStrv) lines = g_strsplit (data, "\n", -1);
  gboolean in_group = FALSE;
  for (guint i = 0; lines[i]; i++) {
    char *l = g_strstrip (lines[i]);
    if (l[0] == '[') {
      char *close = strchr (l, ']');
      in_group = close && (gsize) (close - l - 1) == strlen (group) && strncmp (l + 1, group, strlen (group)) == 0;
      if (in_group && !key)
        return i + 1;
      continue;
    }
    if (!in_group || !key)
      continue;
    char *eq = strchr (l, '=');
    if (!eq)
      continue;
    *eq = '\0';
    if (strcmp (g_strstrip (l), key) == 0)
      return i + 1;
  }
  return 0;
}

static void
add_line (GError *error, const char *data, const char *group, const char *key)
{
  guint line = find_line (data, group, key);
  if (line) {
    char *msg = g_strdup_printf ("%s (line %u)", error->message, line);
    g_free (error->message);
    error->message = msg;
  }
}

static DsConfig *
load_keyfile (GKeyFile *kf, const char *data, const char *name, GError **error)
{
  g_autoptr (DsConfig) c = ds_config_new_default ();
  gsize n_groups = 0;
  g_auto (GStrv) groups = g_key_file_get_groups (kf, &n_groups);
  for (gsize g = 0; g < n_groups; g++) {
    if (!group_known (groups[g])) {
      GError *local = g_error_new (DS_CONFIG_ERROR, DS_CONFIG_ERROR_UNKNOWN_GROUP,
                                   "%s: unknown group [%s] (known: daemon, http, camera, optics, "
                                   "illuminator, trigger, acquisition, sim)", name, groups[g]);
      add_line (local, data, groups[g], NULL);
      g_propagate_error (error, local);
      return NULL;
    }
    gsize n_keys = 0;
    g_auto (GStrv) names = g_key_file_get_keys (kf, groups[g], &n_keys, NULL);
    for (gsize i = 0; i < n_keys; i++) {
      const KeySpec *k = find_key (groups[g], names[i]);
      if (!k) {
        GError *local = g_error_new (DS_CONFIG_ERROR, DS_CONFIG_ERROR_UNKNOWN_KEY, "%s: [%s] unknown key \"%s\"",
                                     name, groups[g], names[i]);
        add_line (local, data, groups[g], names[i]);
        g_propagate_error (error, local);
        return NULL;
      }
      g_autofree char *raw = g_key_file_get_value (kf, groups[g], names[i], NULL);
      GError *local = NULL;
      if (!parse_value (c, k, raw, name, &local)) {
        add_line (local, data, groups[g], names[i]);
        g_propagate_error (error, local);
        return NULL;
      }
    }
  }
  if (!ds_config_check_consistency (c, name, error))
    return NULL;
  return g_steal_pointer (&c);
}

/* What GKeyFile passes over in silence: a NUL byte ends its text (the keys after it, even
 * invalid ones, would be ignored), a key given twice keeps its last value, a group given twice
 * is merged into one (so a reader of the file who finds the first copy misses the keys of the
 * second), a locale key (backend[fr]=) is kept beside the key and never read, and a key
 * without a name (=value) is stored under "". Each is refused with its line. */
static gboolean
check_line (const char *l, guint line, const char *name, char **group, GHashTable *seen, GError **error)
{
  if (l[0] == '[') {
    char *close = strchr (l, ']');
    g_free (*group);
    *group = close ? g_strndup (l + 1, (gsize) (close - l - 1)) : g_strdup (l);
    /* Groups and keys share the table: "[camera]" cannot be a key's "[group] key". */
    g_autofree char *header = g_strdup_printf ("[%s]", *group);
    guint first = GPOINTER_TO_UINT (g_hash_table_lookup (seen, header));
    if (first) {
      g_set_error (error, DS_CONFIG_ERROR, DS_CONFIG_ERROR_SYNTAX,
                   "%s: line %u: group %s appears twice (first at line %u): write its keys in one group", name,
                   line, header, first);
      return FALSE;
    }
    g_hash_table_insert (seen, g_steal_pointer (&header), GUINT_TO_POINTER (line));
    return TRUE;
  }
  char *eq = strchr (l, '=');
  if (l[0] == '#' || !eq)
    return TRUE;
  g_autofree char *key = g_strstrip (g_strndup (l, (gsize) (eq - l)));
  if (!*key) {
    g_set_error (error, DS_CONFIG_ERROR, DS_CONFIG_ERROR_SYNTAX, "%s: line %u: a value without a key name", name,
                 line);
    return FALSE;
  }
  if (strchr (key, '[')) {
    g_set_error (error, DS_CONFIG_ERROR, DS_CONFIG_ERROR_SYNTAX,
                 "%s: line %u: [%s] %s: a localized key; a configuration has no translations", name, line, *group,
                 key);
    return FALSE;
  }
  char *full = g_strdup_printf ("[%s] %s", *group, key);
  guint first = GPOINTER_TO_UINT (g_hash_table_lookup (seen, full));
  if (first) {
    g_set_error (error, DS_CONFIG_ERROR, DS_CONFIG_ERROR_SYNTAX, "%s: %s is set twice (lines %u and %u)", name, full,
                 first, line);
    g_free (full);
    return FALSE;
  }
  g_hash_table_insert (seen, full, GUINT_TO_POINTER (line));
  return TRUE;
}

static gboolean
check_text (const char *data, gsize len, const char *name, GError **error)
{
  const char *nul = memchr (data, '\0', len);
  const char *bad = NULL;
  if (nul || !g_utf8_validate (data, (gssize) len, &bad)) {
    const char *at = nul ? nul : bad;
    guint line = 1;
    for (const char *p = data; p < at; p++)
      line += *p == '\n';
    g_set_error (error, DS_CONFIG_ERROR, DS_CONFIG_ERROR_SYNTAX, "%s: line %u: %s (a configuration is UTF-8 text)",
                 name, line, nul ? "NUL byte" : "not UTF-8");
    return FALSE;
  }
  g_autoptr (GHashTable) seen = g_hash_table_new_full (g_str_hash, g_str_equal, g_free, NULL);
  g_autofree char *group = g_strdup ("");
  g_auto (GStrv) lines = g_strsplit (data, "\n", -1);
  for (guint i = 0; lines[i]; i++)
    if (!check_line (g_strstrip (lines[i]), i + 1, name, &group, seen, error))
      return FALSE;
  return TRUE;
}

static DsConfig *
load_text (const char *data, gsize len, const char *name, GError **error)
{
  if (!check_text (data, len, name, error))
    return NULL;
  g_autoptr (GKeyFile) kf = g_key_file_new ();
  g_autoptr (GError) local = NULL;
  if (!g_key_file_load_from_data (kf, data, len, G_KEY_FILE_NONE, &local)) {
    g_set_error (error, DS_CONFIG_ERROR, DS_CONFIG_ERROR_SYNTAX, "%s: %s", name, local->message);
    return NULL;
  }
  return load_keyfile (kf, data, name, error);
}

DsConfig *
ds_config_load_data (const char *data, const char *name_for_errors, GError **error)
{
  return load_text (data, strlen (data), name_for_errors, error);
}

DsConfig *
ds_config_load_file (const char *path, GError **error)
{
  /* Read with a bound: `--check --config /dev/zero` must end, with an error. */
  int fd = g_open (path, O_RDONLY | O_CLOEXEC, 0);
  if (fd < 0) {
    int e = errno;
    g_set_error (error, DS_CONFIG_ERROR, DS_CONFIG_ERROR_IO, "%s: %s", path, g_strerror (e));
    return NULL;
  }
  GByteArray *buf = g_byte_array_sized_new (4096);
  guint8 chunk[16384];
  gboolean too_big = FALSE;
  int read_errno = 0;
  for (;;) {
    gssize n = read (fd, chunk, sizeof chunk);
    if (n < 0 && errno == EINTR)
      continue;
    if (n < 0)
      read_errno = errno;
    if (n <= 0)
      break;
    if (buf->len + (gsize) n > DS_CONFIG_MAX_BYTES) {
      too_big = TRUE;
      break;
    }
    g_byte_array_append (buf, chunk, (guint) n);
  }
  close (fd);
  g_autoptr (GBytes) bytes = g_byte_array_free_to_bytes (buf);
  if (read_errno) {
    g_set_error (error, DS_CONFIG_ERROR, DS_CONFIG_ERROR_IO, "%s: %s", path, g_strerror (read_errno));
    return NULL;
  }
  if (too_big) {
    g_set_error (error, DS_CONFIG_ERROR, DS_CONFIG_ERROR_IO,
                 "%s: more than %d bytes: not a configuration file", path, DS_CONFIG_MAX_BYTES);
    return NULL;
  }
  gsize len = 0;
  const guint8 *data = g_bytes_get_data (bytes, &len);
  /* A terminated copy: the line lookups split it as a string (check_text finds a NUL within). */
  g_autofree char *text = g_malloc (len + 1);
  if (len)
    memcpy (text, data, len);
  text[len] = '\0';
  return load_text (text, len, path, error);
}

static char *
format_value (const DsConfig *c, const KeySpec *k)
{
  gpointer p = field ((DsConfig *) c, k);
  switch (k->type) {
  case K_STRING:
  case K_CHOICE:
  case K_CHOICES: return g_strdup (*(char **) p ? *(char **) p : "");
  case K_UINT: return g_strdup_printf ("%u", *(guint *) p);
  case K_MODE: return g_strdup_printf ("%04o", *(guint *) p);
  case K_UINT64: return g_strdup_printf ("%" G_GUINT64_FORMAT, *(guint64 *) p);
  case K_INT: return g_strdup_printf ("%d", *(int *) p);
  case K_DOUBLE: {
    double d = *(double *) p;
    if (isnan (d))
      return g_strdup ("");
    char buf[G_ASCII_DTOSTR_BUF_SIZE];
    return g_strdup (g_ascii_dtostr (buf, sizeof buf, d));
  }
  case K_BOOL: return g_strdup (*(gboolean *) p ? "true" : "false");
  }
  return g_strdup ("");
}

/* Whether a key holds the same value in a and b. Text compares with unset as empty, as
 * ds_config_to_data writes it; an empty double (NAN, "automatic") equals another. */
static gboolean
value_equal (const DsConfig *a, const DsConfig *b, const KeySpec *k)
{
  gconstpointer pa = field ((DsConfig *) a, k), pb = field ((DsConfig *) b, k);
  switch (k->type) {
  case K_STRING:
  case K_CHOICE:
  case K_CHOICES: {
    const char *sa = *(char *const *) pa, *sb = *(char *const *) pb;
    return strcmp (sa ? sa : "", sb ? sb : "") == 0;
  }
  case K_UINT:
  case K_MODE: return *(const guint *) pa == *(const guint *) pb;
  case K_UINT64: return *(const guint64 *) pa == *(const guint64 *) pb;
  case K_INT: return *(const int *) pa == *(const int *) pb;
  case K_DOUBLE: {
    double da = *(const double *) pa, db = *(const double *) pb;
    return da == db || (isnan (da) && isnan (db));
  }
  case K_BOOL: return !*(const gboolean *) pa == !*(const gboolean *) pb;
  }
  return FALSE;
}

/* "[camera] exposure-us, gain-db; [acquisition] phases" for the keys picked: a group named once
 * for each run of its keys. NULL when none is picked. */
static char *
key_list (const gboolean *picked)
{
  GString *out = g_string_new (NULL);
  const char *group = NULL;
  for (guint i = 0; i < G_N_ELEMENTS (keys); i++) {
    if (!picked[i])
      continue;
    if (!group || strcmp (group, keys[i].group) != 0)
      g_string_append_printf (out, "%s[%s] ", group ? "; " : "", keys[i].group);
    else
      g_string_append (out, ", ");
    g_string_append (out, keys[i].key);
    group = keys[i].group;
  }
  return out->len ? g_string_free (out, FALSE) : (g_string_free (out, TRUE), NULL);
}

char *
ds_config_restart_keys_changed (const DsConfig *running, const DsConfig *fresh)
{
  gboolean changed[G_N_ELEMENTS (keys)];
  for (guint i = 0; i < G_N_ELEMENTS (keys); i++)
    changed[i] = keys[i].reload == RESTART && !value_equal (running, fresh, &keys[i]);
  return key_list (changed);
}

char *
ds_config_live_keys (void)
{
  gboolean live[G_N_ELEMENTS (keys)];
  for (guint i = 0; i < G_N_ELEMENTS (keys); i++)
    live[i] = keys[i].reload == LIVE;
  return key_list (live);
}

char *
ds_config_to_data (const DsConfig *config)
{
  GString *out = g_string_new (NULL);
  const char *group = NULL;
  for (guint i = 0; i < G_N_ELEMENTS (keys); i++) {
    if (!group || strcmp (group, keys[i].group) != 0) {
      g_string_append_printf (out, "%s[%s]\n", group ? "\n" : "", keys[i].group);
      group = keys[i].group;
    }
    g_autofree char *v = format_value (config, &keys[i]);
    g_string_append_printf (out, "%s=%s\n", keys[i].key, v);
  }
  return g_string_free (out, FALSE);
}

char *
ds_config_describe_keys (void)
{
  GString *out = g_string_new ("| group | key | values | default | on reload | meaning |\n"
                                "|---|---|---|---|---|---|\n");
  for (guint i = 0; i < G_N_ELEMENTS (keys); i++) {
    const KeySpec *k = &keys[i];
    g_autofree char *range = NULL;
    switch (k->type) {
    case K_STRING: range = g_strdup ("text"); break;
    case K_CHOICE: range = g_strdelimit (g_strdup (k->choices), "|", '/'); break;
    case K_CHOICES: range = g_strdup_printf ("comma-separated: %s", k->choices); break;
    case K_BOOL: range = g_strdup ("true/false"); break;
    case K_MODE: range = g_strdup ("octal mode"); break;
    case K_DOUBLE: range = g_strdup_printf ("%g..%g", k->min, k->max); break;
    default: range = g_strdup_printf ("%.0f..%.0f", k->min, k->max); break;
    }
    g_string_append_printf (out, "| %s | %s | %s | %s | %s | %s |\n", k->group, k->key, range,
                            k->def && k->def[0] ? k->def : "(empty)",
                            k->reload == LIVE ? "applies from the next set" : "needs a restart", k->doc);
  }
  return g_string_free (out, FALSE);
}
