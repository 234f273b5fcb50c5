/* The Aravis backend against Aravis's own `arv-fake-gv-camera-0.8` program (Debian's
 * aravis-tools), started as a subprocess on 127.0.0.1: a camera we did not write, over real
 * GVCP/GVSP, clean and with its `-r` GVSP packet loss. */
#include <gio/gio.h>
#include <signal.h>
#include <sys/prctl.h>
#include <string.h>

#include "drivers/aravis/aravis_camera.h"

#define ADDRESS "127.0.0.1"
#define N_BUFFERS 5

typedef struct {
  GSubprocess *proc;
  DsCamera *cam;
} Fake;

static void
die_with_parent (gpointer data)
{
  (void) data;
  prctl (PR_SET_PDEATHSIG, SIGKILL);
}

static void
fake_start (Fake *f, const char *loss)
{
  g_autoptr (GError) error = NULL;
  g_autoptr (GPtrArray) argv = g_ptr_array_new ();
  g_ptr_array_add (argv, (gpointer) DS_ARV_FAKE_GV_CAMERA);
  g_ptr_array_add (argv, (gpointer) "-i");
  g_ptr_array_add (argv, (gpointer) ADDRESS);
  g_ptr_array_add (argv, (gpointer) "-s");
  g_ptr_array_add (argv, (gpointer) "DSSUB01");
  if (loss) {
    g_ptr_array_add (argv, (gpointer) "-r");
    g_ptr_array_add (argv, (gpointer) loss);
  }
  g_ptr_array_add (argv, NULL);
  g_autoptr (GSubprocessLauncher) launcher = g_subprocess_launcher_new (G_SUBPROCESS_FLAGS_STDOUT_SILENCE);
  /* A failed assertion aborts this process: the camera must not outlive it holding UDP 3956. */
  g_subprocess_launcher_set_child_setup (launcher, die_with_parent, NULL, NULL);
  f->proc = g_subprocess_launcher_spawnv (launcher, (const char *const *) argv->pdata, &error);
  g_assert_no_error (error);
  /* The program needs a moment to bind its sockets: try for up to ~60 s (a loaded machine
   * can take seconds to start it; the bound is for one that never does). */
  for (guint i = 0; i < 300 && !f->cam; i++) {
    g_clear_error (&error);
    f->cam = ds_aravis_camera_open (ADDRESS, N_BUFFERS, &error);
    if (!f->cam) {
      g_assert_error (error, DS_CAMERA_ERROR, DS_DEVICE_ERROR_DISCONNECTED);
      g_usleep (200 * 1000);
    }
  }
  g_assert_no_error (error);
  g_assert_nonnull (f->cam);
}

static void
fake_stop (Fake *f)
{
  ds_camera_close (f->cam);
  f->cam = NULL;
  g_subprocess_send_signal (f->proc, SIGINT);
  g_autoptr (GError) error = NULL;
  g_subprocess_wait (f->proc, NULL, &error);
  g_assert_no_error (error);
  g_clear_object (&f->proc);
}

static void
configure_and_start (DsCamera *cam, guint w, guint h)
{
  DsCameraSettings s = { 0 };
  /* 10 ms and gain 0: the fake's diagonal ramp then has scale 1 (no clipping). */
  s.exposure_us = 10000;
  s.roi_width = w;
  s.roi_height = h;
  g_strlcpy (s.pixel_format, "Mono8", sizeof s.pixel_format);
  s.trigger_source = DS_CAMERA_TRIGGER_SOFTWARE;
  g_autoptr (GError) error = NULL;
  cam->ops->configure (cam->backend, &s, &error);
  g_assert_no_error (error);
  cam->ops->start (cam->backend, &error);
  g_assert_no_error (error);
}

/* Aravis's default fill pattern is a diagonal ramp: each pixel is one more (mod 255) than its
 * left neighbour. */
static void
check_ramp (const DsImage *im)
{
  for (guint y = 0; y < im->height; y++) {
    const guint8 *row = ds_image_row (im, y);
    for (guint x = 1; x < im->width; x++)
      if (row[x] != (row[x - 1] + 1) % 255)
        g_error ("pixel %u,%u = %u after %u: not the fake camera's diagonal ramp", x, y, row[x], row[x - 1]);
  }
}

static void
test_clean (void)
{
  Fake f = { 0 };
  fake_start (&f, NULL);
  DsCameraInfo info;
  f.cam->ops->get_info (f.cam->backend, &info);
  g_assert_cmpstr (info.serial, ==, "DSSUB01");
  g_assert_cmpuint (info.sensor_width, >, 0);
  configure_and_start (f.cam, 64, 32);
  guint64 last = 0;
  for (guint i = 0; i < 20; i++) {
    g_autoptr (GError) error = NULL;
    g_assert_true (f.cam->ops->trigger (f.cam->backend, &error));
    g_autoptr (DsFrame) fr = f.cam->ops->grab (f.cam->backend, 3000, &error);
    g_assert_no_error (error);
    g_assert_cmpuint (fr->image->width, ==, 64);
    g_assert_cmpuint (fr->image->height, ==, 32);
    check_ramp (fr->image);
    if (last)
      g_assert_cmpuint (fr->frame_id, ==, last + 1);
    g_assert_cmpuint (fr->ids_skipped, ==, 0);
    last = fr->frame_id;
  }
  f.cam->ops->stop (f.cam->backend);
  guint in, out, pool;
  ds_aravis_camera_pool_counts (f.cam, &in, &out, &pool);
  g_assert_cmpuint (in, ==, N_BUFFERS);
  g_assert_cmpuint (out, ==, 0);
  fake_stop (&f);
}

static void
test_packet_loss (void)
{
  Fake f = { 0 };
  fake_start (&f, DS_ARV_FAKE_LOSS);
  /* 512x128 Mono8 is ~35 GVSP packets: most frames lose one at this ratio. */
  configure_and_start (f.cam, 512, 128);
  guint ok = 0, incomplete = 0, timeouts = 0;
  for (guint i = 0; i < 25; i++) {
    g_autoptr (GError) error = NULL;
    if (!f.cam->ops->trigger (f.cam->backend, &error))
      g_error ("trigger under packet loss: %s", error->message); /* GVCP is not dropped */
    g_autoptr (DsFrame) fr = f.cam->ops->grab (f.cam->backend, 3000, &error);
    if (fr) {
      check_ramp (fr->image);
      ok++;
    } else if (g_error_matches (error, DS_CAMERA_ERROR, DS_DEVICE_ERROR_INCOMPLETE))
      incomplete++;
    else if (g_error_matches (error, DS_CAMERA_ERROR, DS_DEVICE_ERROR_TIMEOUT))
      timeouts++;
    else
      g_error ("untyped failure under packet loss: %s", error->message);
  }
  g_test_message ("25 frames with -r %s: %u good, %u incomplete, %u timeouts", DS_ARV_FAKE_LOSS, ok,
                  incomplete, timeouts);
  g_assert_cmpuint (incomplete, >, 0);
  DsCameraStats st;
  f.cam->ops->get_stats (f.cam->backend, &st);
  g_assert_cmpuint (st.completed, ==, ok);
  g_assert_cmpuint (st.failures, ==, incomplete);
  g_assert_cmpuint (st.missing_packets, >, 0);
  f.cam->ops->stop (f.cam->backend);
  guint in, out, pool;
  ds_aravis_camera_pool_counts (f.cam, &in, &out, &pool);
  g_assert_cmpuint (in, ==, N_BUFFERS); /* every buffer back in the pool */
  g_assert_cmpuint (out, ==, 0);
  fake_stop (&f);
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  g_test_add_func ("/aravis-fake-program/clean", test_clean);
  g_test_add_func ("/aravis-fake-program/packet-loss", test_packet_loss);
  return g_test_run ();
}
