#include "drivers/labsim/labsim_options.h"

#include <gio/gio.h>
#include <string.h>

static gboolean
split_host_port (const char *s, char **host, guint *port)
{
  const char *colon = strrchr (s, ':');
  if (!colon || colon == s)
    return FALSE;
  char *end = NULL;
  guint64 p = g_ascii_strtoull (colon + 1, &end, 10);
  if (!end || *end || end == colon + 1 || p > 65535)
    return FALSE;
  *host = g_strdup_printf ("%.*s", (int) (colon - s), s);
  *port = (guint) p;
  return TRUE;
}

/* One row per numeric option: its name as typed, where it lives, its range. */
typedef struct {
  const char *name;
  int *i;                  /* one of i, d */
  double *d;
  double min, max;
} Range;

static gboolean
check_ranges (const Range *ranges, guint n, GError **error)
{
  for (guint k = 0; k < n; k++) {
    double v = ranges[k].i ? *ranges[k].i : *ranges[k].d;
    if (!(v >= ranges[k].min && v <= ranges[k].max)) {
      g_set_error (error, G_OPTION_ERROR, G_OPTION_ERROR_BAD_VALUE, "--%s %g: expected %g..%g", ranges[k].name,
                   v, ranges[k].min, ranges[k].max);
      return FALSE;
    }
  }
  return TRUE;
}

gboolean
ds_labsim_options_parse (DsLabsimOptions *o, int *argc, char ***argv, GError **error)
{
  memset (o, 0, sizeof *o);
  o->seed = 1;
  o->vanish_for = 2.0;
  o->settle_ms = 3.0;
  o->exception_code = 6;
  o->modbus_unit_id = 1;
  o->map_revision = 2;
  o->rtu_vanish_for = 1.0;
  o->sync_line = 0;
  o->gpio_camera_line = 0;
  o->gpio_enable_line = -1;
  const GOptionEntry main_entries[] = {
    { "version", 'V', 0, G_OPTION_ARG_NONE, &o->version, "Print the version and exit", NULL },
    { "scene", 0, 0, G_OPTION_ARG_FILENAME, &o->scene_path, "Scene file (required)", "FILE" },
    { "psf-cache-dir", 0, 0, G_OPTION_ARG_FILENAME, &o->psf_cache_dir, "Scattering kernel cache", "DIR" },
    { "seed", 0, 0, G_OPTION_ARG_INT64, &o->seed, "Noise seed of the first frame (default 1)", "N" },
    { NULL },
  };
  const GOptionEntry camera_entries[] = {
    { "camera-address", 0, 0, G_OPTION_ARG_STRING, &o->camera_address,
      "IPv4 address the GigE Vision camera serves on (default 127.0.0.1; UDP 3956)", "ADDR" },
    { "camera-serial", 0, 0, G_OPTION_ARG_STRING, &o->camera_serial, "Camera serial number (default DSLAB01)", "S" },
    { "gvsp-lost-ratio", 0, 0, G_OPTION_ARG_DOUBLE, &o->gvsp_lost_ratio,
      "Fault: fraction of GVSP packets not sent (0..1)", "R" },
    { "camera-vanish-after", 0, 0, G_OPTION_ARG_INT, &o->vanish_after,
      "Fault: the camera disappears after N frames ...", "N" },
    { "camera-vanish-for", 0, 0, G_OPTION_ARG_DOUBLE, &o->vanish_for, "... for S seconds (default 2)", "S" },
    { "noiseless", 0, 0, G_OPTION_ARG_NONE, &o->noiseless,
      "Frames are the scene's expected values rounded to whole DN, without sensor noise", NULL },
    { "sync-line", 0, 0, G_OPTION_ARG_INT, &o->sync_line,
      "The projector's sync output (a pulse per applied pattern) drives this camera line "
      "(default 0; -1: not wired)", "N" },
    { "line-miss-every", 0, 0, G_OPTION_ARG_INT, &o->line_miss_every,
      "Fault: every Nth line trigger makes no frame (a missed trigger)", "N" },
    { "line-double-every", 0, 0, G_OPTION_ARG_INT, &o->line_double_every,
      "Fault: every Nth line trigger makes two frames (a double trigger)", "N" },
    { "pixel-formats", 0, 0, G_OPTION_ARG_STRING, &o->pixel_formats,
      "The PixelFormat entries the camera offers (default all: Mono8, Mono10, Mono12, Mono16, "
      "Mono10p, Mono12p, Mono12Packed), as a camera that lacks some would", "LIST" },
    { "gain-max", 0, 0, G_OPTION_ARG_DOUBLE, &o->gain_max_db,
      "The camera's gain range is 0..DB (default 24)", "DB" },
    { "light-from", 0, 0, G_OPTION_ARG_STRING, &o->light_from,
      "The camera sees the phase another controller lights (its registers read over Modbus TCP)",
      "tcp://HOST:PORT" },
    { "gpio-chip", 0, 0, G_OPTION_ARG_FILENAME, &o->gpio_chip,
      "Serve a simulated GPIO chip of 16 lines on this UNIX socket (drivers/gpio/gpio_wire.h); its line 0 "
      "is wired to a camera line input (descatterd: [illuminator] gpio-chip=labsim:PATH)", "PATH" },
    { "gpio-camera-line", 0, 0, G_OPTION_ARG_INT, &o->gpio_camera_line,
      "The camera line input the GPIO chip's line 0 drives (default 0)", "N" },
    { "gpio-stripe-lines", 0, 0, G_OPTION_ARG_INT, &o->gpio_stripe_lines,
      "The GPIO chip's lines 1..N drive N stripe groups per period: the camera sees that projector "
      "instead of the Modbus controller's (default 0: none)", "N" },
    { "gpio-enable-line", 0, 0, G_OPTION_ARG_INT, &o->gpio_enable_line,
      "With --gpio-stripe-lines: the chip line that must be high for the stripes to light (default -1: none)",
      "N" },
    { NULL },
  };
  const GOptionEntry modbus_entries[] = {
    { "modbus", 0, 0, G_OPTION_ARG_STRING, &o->modbus_address,
      "Modbus TCP address:port (default 127.0.0.1:1502; port 0 = any free port)", "HOST:PORT" },
    { "modbus-rtu", 0, 0, G_OPTION_ARG_STRING, &o->modbus_rtu,
      "Serve Modbus RTU too: on a pty created here (\"pty\") or a serial device "
      "(rtu:/dev/ttyX?baud=..&parity=..)", "pty|DEVICE" },
    { "modbus-rtu-link", 0, 0, G_OPTION_ARG_FILENAME, &o->modbus_rtu_link,
      "A symlink kept pointing at the pty (stable across the line going away)", "PATH" },
    { "modbus-unit-id", 0, 0, G_OPTION_ARG_INT, &o->modbus_unit_id, "RTU unit id (default 1)", "N" },
    { "map-revision", 0, 0, G_OPTION_ARG_INT, &o->map_revision,
      "Register map of the controller: 2 (default), or 1, from before CAPABILITIES: PERIOD_CENTIPX "
      "is stored and range-checked but the scene's period is drawn, as a projector whose period is "
      "its optics' and that does not say so", "N" },
    { "fixed-period", 0, 0, G_OPTION_ARG_NONE, &o->fixed_period,
      "The projector cannot change its stripe period: it draws the scene's only (CAPABILITIES "
      "without PERIOD_ADJUSTABLE; default: any period of 2 .. 655.35 px written to PERIOD_CENTIPX)", NULL },
    { "settle-ms", 0, 0, G_OPTION_ARG_DOUBLE, &o->settle_ms,
      "Time from a register write to the pattern being lit (default 3)", "MS" },
    { "modbus-delay-ms", 0, 0, G_OPTION_ARG_INT, &o->delay_ms, "Fault: Modbus response delay", "MS" },
    { "modbus-delay-every", 0, 0, G_OPTION_ARG_INT, &o->delay_every,
      "Fault: delay every Nth request (default 1 when a delay is given)", "N" },
    { "modbus-exception-rate", 0, 0, G_OPTION_ARG_DOUBLE, &o->exception_rate,
      "Fault: fraction of requests answered with an exception", "R" },
    { "modbus-exception-code", 0, 0, G_OPTION_ARG_INT, &o->exception_code,
      "Fault: that exception's code (default 6, server busy)", "C" },
    { "modbus-drop-every", 0, 0, G_OPTION_ARG_INT, &o->drop_every,
      "Fault: close the connection (RTU: say nothing) instead of answering every Nth request", "N" },
    { "modbus-short-every", 0, 0, G_OPTION_ARG_INT, &o->short_every,
      "Fault: answer every Nth read of 2+ registers one register short", "N" },
    { "modbus-silent-every", 0, 0, G_OPTION_ARG_INT, &o->silent_every,
      "Fault: do not answer every Nth request (a response timeout)", "N" },
    { "modbus-bad-crc-every", 0, 0, G_OPTION_ARG_INT, &o->bad_crc_every,
      "Fault: RTU: every Nth answer goes out with a corrupted CRC", "N" },
    { "modbus-rtu-vanish-after", 0, 0, G_OPTION_ARG_INT, &o->rtu_vanish_after,
      "Fault: the serial line goes away after N requests on it ...", "N" },
    { "modbus-rtu-vanish-for", 0, 0, G_OPTION_ARG_DOUBLE, &o->rtu_vanish_for,
      "... for S seconds, then comes back (default 1)", "S" },
    { "stuck-not-ready", 0, 0, G_OPTION_ARG_NONE, &o->stuck, "Fault: the illuminator never becomes ready", NULL },
    { "wrong-phase", 0, 0, G_OPTION_ARG_NONE, &o->wrong_phase, "Fault: the illuminator lights PHASE + 1", NULL },
    { "illuminator-fault", 0, 0, G_OPTION_ARG_NONE, &o->fault, "Fault: STATUS.FAULT set", NULL },
    { "over-temperature", 0, 0, G_OPTION_ARG_NONE, &o->over_temp, "Fault: STATUS.OVER_TEMPERATURE set", NULL },
    { NULL },
  };
  g_autoptr (GOptionContext) ctx =
      g_option_context_new ("- a GigE Vision camera and a Modbus illuminator on loopback");
  g_option_context_add_main_entries (ctx, main_entries, NULL);
  GOptionGroup *camera = g_option_group_new ("camera", "The GigE Vision camera:", "Camera options", NULL, NULL);
  g_option_group_add_entries (camera, camera_entries);
  g_option_context_add_group (ctx, camera);
  GOptionGroup *modbus = g_option_group_new ("modbus", "The Modbus illuminator controller:", "Modbus options",
                                             NULL, NULL);
  g_option_group_add_entries (modbus, modbus_entries);
  g_option_context_add_group (ctx, modbus);
  if (!g_option_context_parse (ctx, argc, argv, error))
    return FALSE;
  if (o->version)
    return TRUE;
  if (!o->scene_path) {
    g_set_error (error, G_OPTION_ERROR, G_OPTION_ERROR_FAILED, "--scene FILE is required");
    return FALSE;
  }
  const Range ranges[] = {
    { "gvsp-lost-ratio", NULL, &o->gvsp_lost_ratio, 0, 1 },
    { "camera-vanish-after", &o->vanish_after, NULL, 0, G_MAXINT },
    { "camera-vanish-for", NULL, &o->vanish_for, 0, 3600 },
    { "sync-line", &o->sync_line, NULL, -1, 3 },
    { "gpio-camera-line", &o->gpio_camera_line, NULL, 0, 3 },
    { "gpio-stripe-lines", &o->gpio_stripe_lines, NULL, 0, 14 },
    { "gpio-enable-line", &o->gpio_enable_line, NULL, -1, 15 },
    { "line-miss-every", &o->line_miss_every, NULL, 0, G_MAXINT },
    { "line-double-every", &o->line_double_every, NULL, 0, G_MAXINT },
    { "gain-max", NULL, &o->gain_max_db, 0, 24 },
    { "modbus-unit-id", &o->modbus_unit_id, NULL, 1, 247 },
    { "map-revision", &o->map_revision, NULL, 1, 2 },
    { "settle-ms", NULL, &o->settle_ms, 0, 10000 },
    { "modbus-delay-ms", &o->delay_ms, NULL, 0, 60000 },
    { "modbus-delay-every", &o->delay_every, NULL, 0, G_MAXINT },
    { "modbus-exception-rate", NULL, &o->exception_rate, 0, 1 },
    { "modbus-exception-code", &o->exception_code, NULL, 1, 11 },
    { "modbus-drop-every", &o->drop_every, NULL, 0, G_MAXINT },
    { "modbus-short-every", &o->short_every, NULL, 0, G_MAXINT },
    { "modbus-silent-every", &o->silent_every, NULL, 0, G_MAXINT },
    { "modbus-bad-crc-every", &o->bad_crc_every, NULL, 0, G_MAXINT },
    { "modbus-rtu-vanish-after", &o->rtu_vanish_after, NULL, 0, G_MAXINT },
    { "modbus-rtu-vanish-for", NULL, &o->rtu_vanish_for, 0, 3600 },
  };
  if (!check_ranges (ranges, G_N_ELEMENTS (ranges), error))
    return FALSE;
  if (o->modbus_rtu_link && (!o->modbus_rtu || strcmp (o->modbus_rtu, "pty") != 0)) {
    g_set_error (error, G_OPTION_ERROR, G_OPTION_ERROR_BAD_VALUE, "--modbus-rtu-link needs --modbus-rtu pty");
    return FALSE;
  }
  if (o->gpio_chip && o->sync_line == o->gpio_camera_line) {
    /* One input, two outputs: every apply and every pulse would both expose, as miswired. */
    g_set_error (error, G_OPTION_ERROR, G_OPTION_ERROR_BAD_VALUE,
                 "--gpio-chip: the chip's line 0 and the projector's sync output (--sync-line %d) would both "
                 "drive camera Line%d: unwire the sync (--sync-line -1) or wire the chip to another input "
                 "(--gpio-camera-line N)", o->sync_line, o->gpio_camera_line);
    return FALSE;
  }
  if ((o->gpio_stripe_lines || o->gpio_enable_line >= 0) && !o->gpio_chip) {
    g_set_error (error, G_OPTION_ERROR, G_OPTION_ERROR_BAD_VALUE, "--gpio-stripe-lines and --gpio-enable-line "
                 "need --gpio-chip PATH");
    return FALSE;
  }
  if (o->gpio_stripe_lines == 1 || (o->gpio_enable_line >= 0 && o->gpio_enable_line <= o->gpio_stripe_lines) ||
      (o->gpio_enable_line >= 0 && !o->gpio_stripe_lines)) {
    g_set_error (error, G_OPTION_ERROR, G_OPTION_ERROR_BAD_VALUE, "--gpio-stripe-lines %d --gpio-enable-line %d: "
                 "expected 2..14 stripe lines (chip lines 1..N; line 0 is the camera's trigger) and an enable "
                 "line above them, or -1", o->gpio_stripe_lines, o->gpio_enable_line);
    return FALSE;
  }
  if (o->gpio_stripe_lines && o->light_from) {
    g_set_error (error, G_OPTION_ERROR, G_OPTION_ERROR_BAD_VALUE,
                 "--gpio-stripe-lines and --light-from both say what lights the scene: give one");
    return FALSE;
  }
  o->modbus_port = 1502;
  if (!split_host_port (o->modbus_address ? o->modbus_address : "127.0.0.1:1502", &o->modbus_host,
                        &o->modbus_port)) {
    g_set_error (error, G_OPTION_ERROR, G_OPTION_ERROR_BAD_VALUE, "--modbus \"%s\": expected HOST:PORT",
                 o->modbus_address);
    return FALSE;
  }
  return TRUE;
}

void
ds_labsim_options_clear (DsLabsimOptions *o)
{
  g_free (o->scene_path);
  g_free (o->psf_cache_dir);
  g_free (o->camera_address);
  g_free (o->camera_serial);
  g_free (o->modbus_address);
  g_free (o->modbus_host);
  g_free (o->modbus_rtu);
  g_free (o->modbus_rtu_link);
  g_free (o->light_from);
  g_free (o->pixel_formats);
  g_free (o->gpio_chip);
  memset (o, 0, sizeof *o);
}
