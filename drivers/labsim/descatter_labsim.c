/* descatter-labsim: one process that is two real devices on loopback, a GigE Vision camera
 * (Aravis's fake camera, images from the scene renderer) and a Modbus illuminator controller
 * (docs/registers.md) over TCP and, when asked, RTU on a serial line. They share the applied
 * phase, so each frame shows the pattern that was lit when it was triggered. Prints its
 * addresses and a ready line on stdout; SIGTERM or SIGINT stops it cleanly (exit 0). */
#include <arv.h>
#include <glib-unix.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "build_info.h"
#include "drivers/labsim/external_light.h"
#include "drivers/labsim/gpio_chip_server.h"
#include "drivers/labsim/gpio_light.h"
#include "drivers/labsim/lab_camera.h"
#include "drivers/labsim/labsim_options.h"
#include "drivers/labsim/modbus_server.h"
#include "drivers/modbus/registers.h"
#include "drivers/sim/renderer.h"
#include "drivers/sim/scene.h"

typedef struct {
  DsModbusServer *modbus;
  DsLabCamera *camera;
  double scene_period_px;
  int sync_line;
  DsExternalLight *external; /* --light-from: another controller lights the scene */
  int gpio_camera_line;
  GMutex gpio_lock;        /* gpio: set on the main thread, read on the camera thread */
  DsGpioChipServer *gpio;
  int gpio_stripe_lines, gpio_enable_line;
  gint garbled_warned;
} Lab;

#define LABSIM_GPIO_LINES 16

/* --gpio-stripe-lines: the light of the projector the chip's lines 1..N drive. */
static void
gpio_illumination (Lab *lab, DsRenderRequest *req)
{
  int levels[64] = { 0 };
  g_mutex_lock (&lab->gpio_lock);
  DsGpioChipServer *gpio = lab->gpio;
  for (int j = 0; gpio && j < lab->gpio_stripe_lines; j++)
    levels[j] = ds_gpio_chip_server_level (gpio, (guint) j + 1);
  gboolean enabled =
      gpio && (lab->gpio_enable_line < 0 || ds_gpio_chip_server_level (gpio, (guint) lab->gpio_enable_line) == 1);
  g_mutex_unlock (&lab->gpio_lock);
  guint phase = 0, n_phases = 1;
  DsGpioLight light = ds_gpio_light_read (levels, (guint) lab->gpio_stripe_lines, &phase, &n_phases);
  if (light == DS_GPIO_LIGHT_GARBLED && g_atomic_int_compare_and_exchange (&lab->garbled_warned, 0, 1))
    g_warning ("GPIO stripe lines lit in no single run: the camera sees them dark");
  req->illuminator_on = enabled && (light == DS_GPIO_LIGHT_STRIPE || light == DS_GPIO_LIGHT_ALL);
  req->all_on = light == DS_GPIO_LIGHT_ALL;
  req->phase = phase;
  req->n_phases = n_phases;
  req->period_px = 0; /* the optics': the scene's */
}

/* What the controller has lit right now, as the renderer wants it. */
static void
illumination (gpointer data, DsRenderRequest *req)
{
  Lab *lab = data;
  if (lab->gpio_stripe_lines)
    gpio_illumination (lab, req);
  else if (lab->external)
    ds_external_light_read (lab->external, req);
  else {
    DsModbusServerState st;
    ds_modbus_server_get_state (lab->modbus, &st);
    req->illuminator_on = st.enabled;
    req->all_on = st.all_on;
    req->phase = st.phase;
    req->n_phases = st.n_phases;
    req->period_px = st.period_centipx / 100.0;
  }
  /* The register holds 1/100 px: within that, it is the scene's own period (exactly). */
  if (fabs (req->period_px - lab->scene_period_px) < 0.005 + 1e-9)
    req->period_px = 0;
}

/* The projector's sync output, wired to a camera line: one pulse per applied pattern. */
static void
on_apply (gpointer data, const DsModbusServerState *state)
{
  (void) state;
  Lab *lab = data;
  ds_lab_camera_line_edge (lab->camera, (guint) lab->sync_line, TRUE);
  ds_lab_camera_line_edge (lab->camera, (guint) lab->sync_line, FALSE);
}

/* The simulated chip's line 0 is wired to a camera input: each level change is an edge there
 * (the camera keeps only those its TriggerActivation names). Lines 1..7 are not connected. */
static void
on_gpio_edge (gpointer data, guint offset, gboolean rising)
{
  Lab *lab = data;
  if (offset == 0)
    ds_lab_camera_line_edge (lab->camera, (guint) lab->gpio_camera_line, rising);
}

static gboolean
on_signal (gpointer loop)
{
  g_main_loop_quit (loop);
  return G_SOURCE_CONTINUE;
}

static DsModbusServer *
start_controller (const DsLabsimOptions *o, double scene_period_px, GError **error)
{
  DsModbusServerConfig mcfg;
  ds_modbus_server_config_init (&mcfg);
  mcfg.settle_us = (guint) (o->settle_ms * 1000);
  mcfg.delay_ms = (guint) o->delay_ms;
  mcfg.delay_every = o->delay_ms > 0 && o->delay_every == 0 ? 1 : (guint) o->delay_every;
  mcfg.exception_rate = o->exception_rate;
  mcfg.exception_code = (guint) o->exception_code;
  mcfg.drop_every = (guint) o->drop_every;
  mcfg.short_every = (guint) o->short_every;
  mcfg.silent_every = (guint) o->silent_every;
  mcfg.bad_crc_every = (guint) o->bad_crc_every;
  mcfg.stuck_not_ready = o->stuck;
  mcfg.wrong_phase = o->wrong_phase;
  mcfg.fault = o->fault;
  mcfg.over_temperature = o->over_temp;
  mcfg.seed = (guint64) o->seed;
  /* Its own period is the scene's; a projector that can change it draws 2 .. 655.35 px. */
  mcfg.period_centipx = (guint) CLAMP (round (scene_period_px * 100), DS_MB_CENTIPX_MIN, DS_MB_CENTIPX_MAX);
  mcfg.period_fixed = o->fixed_period;
  mcfg.map_revision_1 = o->map_revision == 1;
  DsModbusServer *s = ds_modbus_server_new (o->modbus_host, o->modbus_port, &mcfg, error);
  if (!s)
    return NULL;
  if (o->modbus_rtu) {
    DsModbusRtuConfig rc = {
      .device = o->modbus_rtu, .link = o->modbus_rtu_link, .unit_id = (guint) o->modbus_unit_id,
      .vanish_after = (guint) o->rtu_vanish_after, .vanish_for_ms = (guint) (o->rtu_vanish_for * 1000),
    };
    if (!ds_modbus_server_add_rtu (s, &rc, error)) {
      ds_modbus_server_free (s);
      return NULL;
    }
  }
  return s;
}

static int
run (const DsLabsimOptions *o)
{
  g_autoptr (GError) error = NULL;
  g_autoptr (DsScene) scene = ds_scene_load (o->scene_path, &error);
  if (!scene) {
    fprintf (stderr, "descatter-labsim: %s\n", error->message);
    return 1;
  }
  g_autoptr (DsRenderer) renderer = ds_renderer_new (scene, o->psf_cache_dir, &error);
  if (!renderer) {
    fprintf (stderr, "descatter-labsim: %s\n", error->message);
    return 1;
  }
  Lab lab = { 0 };
  g_mutex_init (&lab.gpio_lock);
  lab.scene_period_px = ds_scene_period_px (scene);
  lab.modbus = start_controller (o, lab.scene_period_px, &error);
  if (!lab.modbus) {
    fprintf (stderr, "descatter-labsim: %s\n", error->message);
    return 1;
  }
  if (o->light_from && !(lab.external = ds_external_light_new (o->light_from, &error))) {
    fprintf (stderr, "descatter-labsim: %s\n", error->message);
    ds_modbus_server_free (lab.modbus);
    return 1;
  }
  const char *camera_address = o->camera_address ? o->camera_address : "127.0.0.1";
  DsLabCameraConfig ccfg = {
    .address = camera_address,
    .serial = o->camera_serial,
    .gvsp_lost_ratio = o->gvsp_lost_ratio,
    .vanish_after_frames = (guint) o->vanish_after,
    .vanish_for_s = o->vanish_for,
    .seed = (guint64) o->seed,
    .noiseless = o->noiseless,
    .line_miss_every = (guint) o->line_miss_every,
    .line_double_every = (guint) o->line_double_every,
    .pixel_formats = o->pixel_formats,
    .gain_max_db = o->gain_max_db,
  };
  DsLabCamera *camera = ds_lab_camera_new (&ccfg, renderer, illumination, &lab, &error);
  if (!camera) {
    fprintf (stderr, "descatter-labsim: %s\n", error->message);
    ds_modbus_server_free (lab.modbus);
    ds_external_light_free (lab.external);
    return 1;
  }

  lab.camera = camera;
  lab.sync_line = o->sync_line;
  if (o->sync_line >= 0)
    ds_modbus_server_set_apply_callback (lab.modbus, on_apply, &lab);
  lab.gpio_camera_line = o->gpio_camera_line;
  lab.gpio_enable_line = o->gpio_enable_line;
  lab.gpio_stripe_lines = o->gpio_stripe_lines;
  DsGpioChipServer *gpio = NULL;
  if (o->gpio_chip &&
      !(gpio = ds_gpio_chip_server_new (o->gpio_chip, LABSIM_GPIO_LINES, "descatter-labsim", on_gpio_edge, &lab,
                                        &error))) {
    fprintf (stderr, "descatter-labsim: %s\n", error->message);
    ds_modbus_server_set_apply_callback (lab.modbus, NULL, NULL);
    ds_lab_camera_free (camera);
    ds_modbus_server_free (lab.modbus);
    ds_external_light_free (lab.external);
    return 1;
  }
  g_mutex_lock (&lab.gpio_lock);
  lab.gpio = gpio;
  g_mutex_unlock (&lab.gpio_lock);
  g_autoptr (GMainLoop) loop = g_main_loop_new (NULL, FALSE);
  guint sig_term = g_unix_signal_add (SIGTERM, on_signal, loop);
  guint sig_int = g_unix_signal_add (SIGINT, on_signal, loop);
  printf ("descatter-labsim: camera %s serial %s %ux%u %u-bit (GigE Vision, UDP 3956)\n", camera_address,
          o->camera_serial ? o->camera_serial : "DSLAB01", ds_scene_width (scene), ds_scene_height (scene),
          ds_scene_bit_depth (scene));
  guint prepared = 0;
  double prepared_s = 0;
  ds_lab_camera_prepared (camera, &prepared, &prepared_s);
  printf ("descatter-labsim: rendered %u lighting states in %.2f s (%.3f s each) before serving; a new phase "
          "count or period renders again in the background\n", prepared, prepared_s,
          prepared ? prepared_s / prepared : 0.0);
  printf ("descatter-labsim: modbus %s:%u (settle %.1f ms, period %s %.2f px, docs/registers.md)\n",
          o->modbus_host, ds_modbus_server_port (lab.modbus), o->settle_ms,
          o->map_revision == 1 ? "map revision 1, drawn at" : o->fixed_period ? "fixed at" : "adjustable, power-up",
          lab.scene_period_px);
  const char *rtu = ds_modbus_server_rtu_path (lab.modbus);
  if (rtu)
    printf ("descatter-labsim: modbus RTU on %s, unit %d\n", rtu, o->modbus_unit_id);
  if (gpio)
    printf ("descatter-labsim: GPIO chip of %d lines on %s, line 0 wired to camera Line%d%s\n", LABSIM_GPIO_LINES,
            o->gpio_chip, o->gpio_camera_line,
            o->gpio_stripe_lines ? ", lines 1.. to the stripe groups the camera sees" : "");
  /* Parsers look for "ready", then for key=value pairs: new keys go at the end. */
  printf ("descatter-labsim: ready camera=%s modbus=%s:%u%s%s%s%s\n", camera_address, o->modbus_host,
          ds_modbus_server_port (lab.modbus), rtu ? " rtu=" : "", rtu ? rtu : "", gpio ? " gpio=" : "",
          gpio ? o->gpio_chip : "");
  fflush (stdout);
  g_main_loop_run (loop);

  g_source_remove (sig_term);
  g_source_remove (sig_int);
  ds_modbus_server_set_apply_callback (lab.modbus, NULL, NULL);
  g_mutex_lock (&lab.gpio_lock); /* the camera thread may be reading the stripe lines */
  lab.gpio = NULL;
  g_mutex_unlock (&lab.gpio_lock);
  ds_gpio_chip_server_free (gpio); /* before the camera its edges reach */
  guint64 frames = ds_lab_camera_frames (camera);
  DsLabTriggerStats trig;
  ds_lab_camera_trigger_stats (camera, &trig);
  ds_lab_camera_free (camera);
  DsModbusServerState st;
  ds_modbus_server_get_state (lab.modbus, &st);
  ds_modbus_server_free (lab.modbus);
  ds_external_light_free (lab.external);
  g_mutex_clear (&lab.gpio_lock);
  fprintf (stderr, "descatter-labsim: stopped after %" G_GUINT64_FORMAT " frames, %" G_GUINT64_FORMAT
                   " Modbus requests, %" G_GUINT64_FORMAT " triggers dropped unrendered\n", frames, st.requests,
           trig.not_rendered);
  return 0;
}

int
main (int argc, char **argv)
{
  DsLabsimOptions o;
  g_autoptr (GError) error = NULL;
  if (!ds_labsim_options_parse (&o, &argc, &argv, &error)) {
    fprintf (stderr, "descatter-labsim: %s\n", error->message);
    ds_labsim_options_clear (&o);
    return 2;
  }
  if (o.version) {
    printf ("descatter-labsim %s (%s)\n", DS_VERSION, DS_GIT_DESCRIBE);
    ds_labsim_options_clear (&o);
    return 0;
  }
  int status = run (&o);
  ds_labsim_options_clear (&o);
  arv_shutdown ();
  return status;
}
