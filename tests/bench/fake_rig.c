#include "fake_rig.h"

#include <arv.h>
#include <math.h>
#include <pthread.h>
#include <sched.h>
#include <stdio.h>
#include <string.h>

struct FakeRig {
  ArvGvFakeCamera *gv;
  DsModbusServer *modbus;
  DsModbusServerConfig modbus_config;
  guint width, height, n_phases;
  guint16 **lit;           /* one frame per phase */
  guint16 *dark;           /* illuminator off */
  gint frames;             /* atomic */
};

static guint16
scene_value (guint x, guint phase, guint n)
{
  double u = (x + 0.5) / FAKE_RIG_PERIOD_PX - (double) phase / n;
  u -= floor (u + 0.5);
  double lit = fabs (u) < 0.25 ? 1.0 : 0.0;
  return (guint16) lround (FAKE_RIG_DIRECT_DN * lit + FAKE_RIG_GLOBAL_DN * 0.5 + FAKE_RIG_DARK_DN);
}

/* The fake camera's thread: copy the frame of the phase lit now. */
static void
fill (ArvBuffer *buffer, void *data, guint32 exposure_time_us, guint32 gain, ArvPixelFormat format)
{
  (void) exposure_time_us;
  (void) gain;
  FakeRig *rig = data;
  guint8 *out = (guint8 *) arv_buffer_get_data (buffer, NULL);
  gint x0 = 0, y0 = 0, w = 0, h = 0;
  arv_buffer_get_image_region (buffer, &x0, &y0, &w, &h);
  if (!out || format != ARV_PIXEL_FORMAT_MONO_16 || (guint) w != rig->width || (guint) h != rig->height)
    return;
  DsModbusServerState st;
  ds_modbus_server_get_state (rig->modbus, &st);
  const guint16 *src = st.enabled ? rig->lit[st.phase % rig->n_phases] : rig->dark;
  memcpy (out, src, (gsize) rig->width * rig->height * 2);
  g_atomic_int_inc (&rig->frames);
}

/* Aravis's fake camera thread polls its sockets with a timeout in whole milliseconds: with the
 * trigger polled every 0.5 ms the timeout is always 0, and the thread spins on a core for as
 * long as it streams. run_rate_bench.sh gives the benchmark real-time priority 2, which the
 * thread would inherit: it would then hold one of the machine's two cores outright, and the
 * daemon (a real camera does its work on its own hardware) would run on the other. So the
 * camera is made on a thread one real-time priority lower (the normal class when there is none
 * lower), which its thread inherits: it takes what the daemon's and the ceiling's threads
 * leave, a core whenever they wait, and still comes before the other users' processes. The rest
 * of the rig (the Modbus controller) keeps the caller's priority. */
static gpointer
new_camera_thread (gpointer data)
{
  (void) data;
  int policy;
  struct sched_param sp;
  if (pthread_getschedparam (pthread_self (), &policy, &sp) == 0 && policy != SCHED_OTHER) {
    /* lowering needs no privilege */
    if (sp.sched_priority > sched_get_priority_min (policy)) {
      sp.sched_priority--;
      pthread_setschedparam (pthread_self (), policy, &sp);
    } else {
      struct sched_param normal = { .sched_priority = 0 };
      pthread_setschedparam (pthread_self (), SCHED_OTHER, &normal);
    }
  }
  return g_object_new (ARV_TYPE_GV_FAKE_CAMERA, "interface-name", "127.0.0.1", "serial-number",
                       "FR0001", NULL);
}

FakeRig *
fake_rig_new (guint width, guint height, guint n_phases, guint settle_us)
{
  FakeRig *rig = g_new0 (FakeRig, 1);
  rig->width = width;
  rig->height = height;
  rig->n_phases = n_phases;
  gsize npix = (gsize) width * height;
  rig->lit = g_new0 (guint16 *, n_phases);
  for (guint k = 0; k < n_phases; k++) {
    rig->lit[k] = g_new (guint16, npix);
    for (guint x = 0; x < width; x++)
      rig->lit[k][x] = scene_value (x, k, n_phases);
    for (guint y = 1; y < height; y++)
      memcpy (rig->lit[k] + (gsize) y * width, rig->lit[k], width * 2);
  }
  rig->dark = g_new (guint16, npix);
  for (gsize i = 0; i < npix; i++)
    rig->dark[i] = (guint16) FAKE_RIG_DARK_DN;

  g_autoptr (GError) error = NULL;
  ds_modbus_server_config_init (&rig->modbus_config);
  rig->modbus_config.settle_us = settle_us;
  rig->modbus = ds_modbus_server_new ("127.0.0.1", 0, &rig->modbus_config, &error);
  if (!rig->modbus) {
    fprintf (stderr, "fake rig: Modbus server: %s\n", error->message);
    fake_rig_free (rig);
    return NULL;
  }
  rig->gv = g_thread_join (g_thread_new ("fake-rig-camera", new_camera_thread, NULL));
  if (!rig->gv || !arv_gv_fake_camera_is_running (rig->gv)) {
    fprintf (stderr, "fake rig: the GigE Vision fake camera cannot serve on 127.0.0.1:3956 "
                     "(port taken? run in a private network namespace)\n");
    fake_rig_free (rig);
    return NULL;
  }
  ArvFakeCamera *fake = arv_gv_fake_camera_get_fake_camera (rig->gv);
  arv_fake_camera_write_register (fake, ARV_FAKE_CAMERA_REGISTER_SENSOR_WIDTH, width);
  arv_fake_camera_write_register (fake, ARV_FAKE_CAMERA_REGISTER_SENSOR_HEIGHT, height);
  arv_fake_camera_write_register (fake, ARV_FAKE_CAMERA_REGISTER_WIDTH, width);
  arv_fake_camera_write_register (fake, ARV_FAKE_CAMERA_REGISTER_HEIGHT, height);
  arv_fake_camera_write_register (fake, ARV_FAKE_CAMERA_REGISTER_PIXEL_FORMAT, ARV_PIXEL_FORMAT_MONO_16);
  arv_fake_camera_write_register (fake, ARV_FAKE_CAMERA_REGISTER_EXPOSURE_TIME_US, 1000);
  /* 8 KiB GVSP packets, as a GigE Vision link with jumbo frames carries them (and as labsim
   * serves): the fake camera has no test packet, so Aravis's packet size negotiation keeps it. */
  arv_fake_camera_write_register (fake, 0xd04 /* GigE Vision SCPS0: stream packet size */, 8192);
  /* The software trigger is polled, not signalled: at 2 kHz the poll adds 0.25 ms on average. */
  arv_fake_camera_set_trigger_frequency (fake, 2000.0);
  arv_fake_camera_set_fill_pattern (fake, fill, rig);
  return rig;
}

void
fake_rig_free (FakeRig *rig)
{
  if (!rig)
    return;
  g_clear_object (&rig->gv);
  g_clear_pointer (&rig->modbus, ds_modbus_server_free);
  for (guint k = 0; rig->lit && k < rig->n_phases; k++)
    g_free (rig->lit[k]);
  g_free (rig->lit);
  g_free (rig->dark);
  g_free (rig);
}

guint
fake_rig_modbus_port (const FakeRig *rig)
{
  return ds_modbus_server_port (rig->modbus);
}

void
fake_rig_set_settle_us (FakeRig *rig, guint settle_us)
{
  rig->modbus_config.settle_us = settle_us;
  ds_modbus_server_set_config (rig->modbus, &rig->modbus_config);
}

guint64
fake_rig_frames (FakeRig *rig)
{
  return (guint64) g_atomic_int_get (&rig->frames);
}
