/* descatter-labsim serves a moving object over GigE Vision: each frame shows it where it is at
 * that frame's trigger (docs/scene-format.md, "Motion").
 *
 * Independent expectation: a dark bar moving at v px/s; two frames triggered with plain Aravis a
 * second apart, every stripe lit (Modbus backend, all on). Between the two triggers labsim saw,
 * the bar moved v times the time between them, and that time lies between the host's clock
 * readings around the two grabs (the same monotonic clock: both processes run here). So the
 * shadow's centroid moved by at least v (trigger B sent - frame A received) and at most
 * v (frame B received - trigger A sent). These bounds hold however loaded the machine is.
 *
 * Usage: test_labsim_motion LABSIM. Binds UDP 3956 (RESOURCE_LOCK gige_port_3956). */
#include <arv.h>
#include <glib/gstdio.h>
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "tests/common/daemon_harness.h"
#include "drivers/modbus/modbus_illuminator.h"
#include "proc/pixfmt.h"

#define W 256
#define H 32
#define SPEED 15.0
#define BAR_W 12
#define ANSWER_MS 2000
#define APPLY_MS 10000
#define FRAME_US G_GUINT64_CONSTANT (20000000)

static const char *labsim_path;

static const char scene_text[] =
  "[sensor]\nwidth=256\nheight=32\nexposure-us=1000\n"
  "[illuminator]\nperiod-px=8\nirradiance=5\n"
  "[object.bar]\nshape=rect\nposition=10;-10\nsize=12;60\nvelocity=15, 0\n";

/* The bar's shadow: darkness summed over the frame's rows, centred where? Open level from the
 * frame's last 24 columns, which the bar does not reach within the test. */
static double
shadow_centre (const DsImage *img, double *area)
{
  double open = 0;
  for (guint y = 0; y < H; y++)
    for (guint x = W - 24; x < W; x++)
      open += ((const guint16 *) ds_image_row (img, y))[x] / (24.0 * H);
  double a = 0, m = 0;
  for (guint y = 0; y < H; y++)
    for (guint x = 0; x < W - 24; x++) {
      double d = 1.0 - ((const guint16 *) ds_image_row (img, y))[x] / open;
      d = d < 0.05 ? 0 : d; /* noise of the open field is not shadow */
      a += d;
      m += d * x;
    }
  *area = a / H;
  return m / a;
}

static DsImage *
grab (ArvCamera *cam, ArvStream *stream, gint64 *sent, gint64 *received)
{
  g_autoptr (GError) error = NULL;
  *sent = g_get_monotonic_time ();
  arv_camera_software_trigger (cam, &error);
  g_assert_no_error (error);
  ArvBuffer *buf = arv_stream_timeout_pop_buffer (stream, FRAME_US);
  *received = g_get_monotonic_time ();
  g_assert_nonnull (buf);
  g_assert_cmpint (arv_buffer_get_status (buf), ==, ARV_BUFFER_STATUS_SUCCESS);
  size_t size = 0;
  const void *data = arv_buffer_get_image_data (buf, &size);
  DsImage *img = ds_pixfmt_unpack (DS_PIXFMT_MONO16, data, size, W, H, 0, &error);
  g_assert_no_error (error);
  arv_stream_push_buffer (stream, buf);
  return img;
}

static void
test_moves_between_triggers (void)
{
  g_autoptr (GError) error = NULL;
  g_autofree char *dir = g_dir_make_tmp ("ds-labsim-motion-XXXXXX", &error);
  g_assert_no_error (error);
  g_autofree char *scene = g_build_filename (dir, "moving.scene", NULL);
  g_assert_true (g_file_set_contents (scene, scene_text, -1, &error));
  TestLabsim *l = test_labsim_start (labsim_path, scene, NULL);
  ArvCamera *cam = arv_camera_new ("127.0.0.1", &error);
  g_assert_no_error (error);
  g_assert_cmpstr (arv_camera_get_device_serial_number (cam, NULL), ==, l->serial);
  arv_camera_set_pixel_format_from_string (cam, "Mono16", &error);
  g_assert_no_error (error);
  arv_camera_set_trigger (cam, "Software", &error);
  g_assert_no_error (error);
  arv_camera_set_exposure_time (cam, 1000, &error);
  g_assert_no_error (error);
  ArvStream *stream = arv_camera_create_stream (cam, NULL, NULL, &error);
  g_assert_no_error (error);
  guint size = arv_camera_get_payload (cam, &error);
  for (guint i = 0; i < 3; i++)
    arv_stream_push_buffer (stream, arv_buffer_new (size, NULL));
  arv_camera_start_acquisition (cam, &error);
  g_assert_no_error (error);
  g_autofree char *uri = g_strdup_printf ("tcp://127.0.0.1:%u", l->modbus_port);
  DsIlluminator *ill = ds_modbus_illuminator_open (uri, 1, ANSWER_MS, &error);
  g_assert_no_error (error);
  g_assert_true (ds_illuminator_all_on (ill, APPLY_MS, &error));
  g_assert_no_error (error);

  gint64 sent_a, got_a, sent_b, got_b;
  g_autoptr (DsImage) a = grab (cam, stream, &sent_a, &got_a);
  g_usleep (G_USEC_PER_SEC);
  g_autoptr (DsImage) b = grab (cam, stream, &sent_b, &got_b);
  double area_a, area_b;
  double ca = shadow_centre (a, &area_a), cb = shadow_centre (b, &area_b);
  double lo = SPEED * (double) (sent_b - got_a) / 1e6, hi = SPEED * (double) (got_b - sent_a) / 1e6;
  g_test_message ("bar at %.2f px then %.2f px: moved %.2f px, between %.2f and %.2f by the clock (shadows %.1f, "
                  "%.1f px wide)", ca, cb, cb - ca, lo, hi, area_a, area_b);
  /* Both frames hold the whole bar, in the part of the frame measured. */
  g_assert_cmpfloat (fabs (area_a - BAR_W), <, 1.0);
  g_assert_cmpfloat (fabs (area_b - BAR_W), <, 1.0);
  /* The centroid is good to a fraction of a pixel: the noise's share. */
  g_assert_cmpfloat (cb - ca, >=, lo - 0.3);
  g_assert_cmpfloat (cb - ca, <=, hi + 0.3);

  ds_illuminator_close (ill);
  arv_camera_stop_acquisition (cam, NULL);
  g_object_unref (stream);
  g_object_unref (cam);
  test_labsim_stop (l);
  g_unlink (scene);
  g_rmdir (dir);
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  if (argc < 2) {
    fprintf (stderr, "usage: test_labsim_motion LABSIM\n");
    return 2;
  }
  labsim_path = argv[1];
  g_test_add_func ("/labsim/motion/moves-between-triggers", test_moves_between_triggers);
  return g_test_run ();
}
