/* descatter-labsim: one process that is two real devices on loopback, a GigE Vision camera
 * (Aravis's fake camera, images from the scene renderer) and a Modbus TCP illuminator
 * controller (docs/registers.md). They share the applied phase, so each frame shows the
 * pattern that was lit when it was triggered. Prints its addresses and a ready line on
 * stdout; SIGTERM or SIGINT stops it cleanly (exit 0). */
#include <arv.h>
#include <glib-unix.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "drivers/labsim/lab_camera.h"
#include "drivers/labsim/modbus_server.h"
#include "drivers/sim/renderer.h"
#include "drivers/sim/scene.h"

typedef struct {
  DsModbusServer *modbus;
} Lab;

/* What the controller has lit right now, as the renderer wants it. */
static void
illumination (gpointer data, DsRenderRequest *req)
{
  Lab *lab = data;
  DsModbusServerState st;
  ds_modbus_server_get_state (lab->modbus, &st);
  req->illuminator_on = st.enabled;
  req->phase = st.phase;
  req->n_phases = st.n_phases;
}

static gboolean
on_signal (gpointer loop)
{
  g_main_loop_quit (loop);
  return G_SOURCE_CONTINUE;
}

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
  *host = g_strndup (s, (gsize) (colon - s));
  *port = (guint) p;
  return TRUE;
}

int
main (int argc, char **argv)
{
  g_autofree char *scene_path = NULL, *camera_address = NULL, *modbus_address = NULL;
  g_autofree char *psf_cache = NULL, *serial = NULL;
  double settle_ms = 3.0, gvsp_lost_ratio = 0, exception_rate = 0, vanish_for = 2.0;
  int delay_ms = 0, delay_every = 0, exception_code = 6, drop_every = 0, short_every = 0, vanish_after = 0;
  gint64 seed = 1;
  gboolean stuck = FALSE, wrong_phase = FALSE, fault = FALSE, over_temp = FALSE;
  const GOptionEntry entries[] = {
    { "scene", 0, 0, G_OPTION_ARG_FILENAME, &scene_path, "Scene file (required)", "FILE" },
    { "camera-address", 0, 0, G_OPTION_ARG_STRING, &camera_address,
      "IPv4 address the GigE Vision camera serves on (default 127.0.0.1; UDP 3956)", "ADDR" },
    { "camera-serial", 0, 0, G_OPTION_ARG_STRING, &serial, "Camera serial number (default DSLAB01)", "S" },
    { "modbus", 0, 0, G_OPTION_ARG_STRING, &modbus_address,
      "Modbus TCP address:port (default 127.0.0.1:1502; port 0 = any free port)", "HOST:PORT" },
    { "settle-ms", 0, 0, G_OPTION_ARG_DOUBLE, &settle_ms,
      "Time from a register write to the pattern being lit (default 3)", "MS" },
    { "psf-cache-dir", 0, 0, G_OPTION_ARG_FILENAME, &psf_cache, "Scattering kernel cache", "DIR" },
    { "seed", 0, 0, G_OPTION_ARG_INT64, &seed, "Noise seed of the first frame (default 1)", "N" },
    { "gvsp-lost-ratio", 0, 0, G_OPTION_ARG_DOUBLE, &gvsp_lost_ratio,
      "Fault: fraction of GVSP packets not sent (0..1)", "R" },
    { "modbus-delay-ms", 0, 0, G_OPTION_ARG_INT, &delay_ms, "Fault: Modbus response delay", "MS" },
    { "modbus-delay-every", 0, 0, G_OPTION_ARG_INT, &delay_every,
      "Fault: delay every Nth request (default 1 when a delay is given)", "N" },
    { "modbus-exception-rate", 0, 0, G_OPTION_ARG_DOUBLE, &exception_rate,
      "Fault: fraction of requests answered with an exception", "R" },
    { "modbus-exception-code", 0, 0, G_OPTION_ARG_INT, &exception_code,
      "Fault: that exception's code (default 6, server busy)", "C" },
    { "modbus-drop-every", 0, 0, G_OPTION_ARG_INT, &drop_every,
      "Fault: close the connection instead of answering every Nth request", "N" },
    { "modbus-short-every", 0, 0, G_OPTION_ARG_INT, &short_every,
      "Fault: answer every Nth read of 2+ registers one register short", "N" },
    { "stuck-not-ready", 0, 0, G_OPTION_ARG_NONE, &stuck, "Fault: the illuminator never becomes ready", NULL },
    { "wrong-phase", 0, 0, G_OPTION_ARG_NONE, &wrong_phase, "Fault: the illuminator lights PHASE + 1", NULL },
    { "illuminator-fault", 0, 0, G_OPTION_ARG_NONE, &fault, "Fault: STATUS.FAULT set", NULL },
    { "over-temperature", 0, 0, G_OPTION_ARG_NONE, &over_temp, "Fault: STATUS.OVER_TEMPERATURE set", NULL },
    { "camera-vanish-after", 0, 0, G_OPTION_ARG_INT, &vanish_after,
      "Fault: the camera disappears after N frames ...", "N" },
    { "camera-vanish-for", 0, 0, G_OPTION_ARG_DOUBLE, &vanish_for, "... for S seconds (default 2)", "S" },
    { NULL },
  };
  g_autoptr (GOptionContext) ctx = g_option_context_new ("- a GigE Vision camera and a Modbus illuminator on loopback");
  g_option_context_add_main_entries (ctx, entries, NULL);
  g_autoptr (GError) error = NULL;
  if (!g_option_context_parse (ctx, &argc, &argv, &error)) {
    fprintf (stderr, "descatter-labsim: %s\n", error->message);
    return 2;
  }
  if (!scene_path) {
    fprintf (stderr, "descatter-labsim: --scene FILE is required\n");
    return 2;
  }
  if (gvsp_lost_ratio < 0 || gvsp_lost_ratio > 1 || exception_rate < 0 || exception_rate > 1 ||
      settle_ms < 0 || settle_ms > 10000 || delay_ms < 0 || delay_every < 0 || drop_every < 0 || short_every < 0 ||
      vanish_after < 0 || vanish_for < 0 || exception_code < 1 || exception_code > 11) {
    fprintf (stderr, "descatter-labsim: a fault option is out of range (ratios 0..1, counts >= 0, "
                     "exception code 1..11, settle 0..10000 ms)\n");
    return 2;
  }
  g_autofree char *mb_host = NULL;
  guint mb_port = 1502;
  if (!split_host_port (modbus_address ? modbus_address : "127.0.0.1:1502", &mb_host, &mb_port)) {
    fprintf (stderr, "descatter-labsim: --modbus \"%s\": expected HOST:PORT\n", modbus_address);
    return 2;
  }

  g_autoptr (DsScene) scene = ds_scene_load (scene_path, &error);
  if (!scene) {
    fprintf (stderr, "descatter-labsim: %s\n", error->message);
    return 1;
  }
  g_autoptr (DsRenderer) renderer = ds_renderer_new (scene, psf_cache, &error);
  if (!renderer) {
    fprintf (stderr, "descatter-labsim: %s\n", error->message);
    return 1;
  }

  DsModbusServerConfig mcfg;
  ds_modbus_server_config_init (&mcfg);
  mcfg.settle_us = (guint) (settle_ms * 1000);
  mcfg.delay_ms = (guint) delay_ms;
  mcfg.delay_every = delay_ms > 0 && delay_every == 0 ? 1 : (guint) delay_every;
  mcfg.exception_rate = exception_rate;
  mcfg.exception_code = (guint) exception_code;
  mcfg.drop_every = (guint) drop_every;
  mcfg.short_every = (guint) short_every;
  mcfg.stuck_not_ready = stuck;
  mcfg.wrong_phase = wrong_phase;
  mcfg.fault = fault;
  mcfg.over_temperature = over_temp;
  mcfg.seed = (guint64) seed;
  Lab lab = { 0 };
  lab.modbus = ds_modbus_server_new (mb_host, mb_port, &mcfg, &error);
  if (!lab.modbus) {
    fprintf (stderr, "descatter-labsim: %s\n", error->message);
    return 1;
  }

  DsLabCameraConfig ccfg = {
    .address = camera_address ? camera_address : "127.0.0.1",
    .serial = serial,
    .gvsp_lost_ratio = gvsp_lost_ratio,
    .vanish_after_frames = (guint) vanish_after,
    .vanish_for_s = vanish_for,
    .seed = (guint64) seed,
  };
  DsLabCamera *camera = ds_lab_camera_new (&ccfg, renderer, illumination, &lab, &error);
  if (!camera) {
    fprintf (stderr, "descatter-labsim: %s\n", error->message);
    ds_modbus_server_free (lab.modbus);
    return 1;
  }

  g_autoptr (GMainLoop) loop = g_main_loop_new (NULL, FALSE);
  guint sig_term = g_unix_signal_add (SIGTERM, on_signal, loop);
  guint sig_int = g_unix_signal_add (SIGINT, on_signal, loop);
  printf ("descatter-labsim: camera %s serial %s %ux%u %u-bit (GigE Vision, UDP 3956)\n", ccfg.address,
          serial ? serial : "DSLAB01", ds_scene_width (scene), ds_scene_height (scene),
          ds_scene_bit_depth (scene));
  printf ("descatter-labsim: modbus %s:%u (settle %.1f ms, docs/registers.md)\n", mb_host,
          ds_modbus_server_port (lab.modbus), settle_ms);
  printf ("descatter-labsim: ready camera=%s modbus=%s:%u\n", ccfg.address, mb_host,
          ds_modbus_server_port (lab.modbus));
  fflush (stdout);
  g_main_loop_run (loop);

  g_source_remove (sig_term);
  g_source_remove (sig_int);
  guint64 frames = ds_lab_camera_frames (camera);
  ds_lab_camera_free (camera);
  DsModbusServerState st;
  ds_modbus_server_get_state (lab.modbus, &st);
  ds_modbus_server_free (lab.modbus);
  fprintf (stderr, "descatter-labsim: stopped after %" G_GUINT64_FORMAT " frames, %" G_GUINT64_FORMAT
                   " Modbus requests\n", frames, st.requests);
  arv_shutdown ();
  return 0;
}
