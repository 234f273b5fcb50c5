/* descatter-labsim is real: a GigE Vision camera that plain Aravis streams from, and a Modbus TCP
 * controller that the Modbus backend drives; each frame shows the stripe phase the Modbus client
 * set, measured in the frame itself (proc/stripe_phase.h), and a dark frame shows no stripes.
 * Usage: test_labsim LABSIM SCENE. Binds UDP 3956 (RESOURCE_LOCK gige_port_3956). */
#include <arv.h>
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "tests/common/daemon_harness.h"
#include "drivers/aravis/aravis_camera.h"
#include "drivers/modbus/modbus_illuminator.h"
#include "drivers/sim/scene.h"
#include "period_check.h"
#include "proc/pixfmt.h"
#include "proc/stripe_phase.h"

static const char *labsim_path, *scene_path;

/* Bounds no device of a loaded machine misses: labsim renders its frames and answers Modbus in a
 * process that waits for a core like every other (at load 13 a set_phase bounded by 1 s, each
 * answer by 300 ms, failed). A Modbus answer within ANSWER_MS, a phase applied within APPLY_MS,
 * a frame within FRAME_US. What the tests assert is what the devices do, never how soon. */
#define ANSWER_MS 2000
#define APPLY_MS 10000
#define FRAME_US G_GUINT64_CONSTANT (20000000)

static ArvCamera *
open_camera (const TestLabsim *l)
{
  g_autoptr (GError) error = NULL;
  ArvCamera *cam = arv_camera_new ("127.0.0.1", &error);
  g_assert_no_error (error);
  g_autofree char *serial = g_strdup (arv_camera_get_device_serial_number (cam, &error));
  if (g_strcmp0 (serial, l->serial) != 0)
    g_error ("the GigE Vision device answering on 127.0.0.1:3956 is \"%s\", not labsim's \"%s\": another "
             "camera (arv-fake-gv-camera?) holds the port", serial, l->serial);
  return cam;
}

/* A stream with n_buffers buffers of the camera's payload, acquisition started; *payload (may
 * be NULL) gets the payload size. */
static ArvStream *
start_stream (ArvCamera *cam, guint n_buffers, guint *payload)
{
  g_autoptr (GError) error = NULL;
  ArvStream *stream = arv_camera_create_stream (cam, NULL, NULL, &error);
  g_assert_no_error (error);
  guint size = arv_camera_get_payload (cam, &error);
  g_assert_no_error (error);
  for (guint i = 0; i < n_buffers; i++)
    arv_stream_push_buffer (stream, arv_buffer_new (size, NULL));
  arv_camera_start_acquisition (cam, &error);
  g_assert_no_error (error);
  if (payload)
    *payload = size;
  return stream;
}

static DsImage *
grab_one (ArvCamera *cam, ArvStream *stream, guint width, guint height)
{
  g_autoptr (GError) error = NULL;
  arv_camera_software_trigger (cam, &error);
  g_assert_no_error (error);
  ArvBuffer *buf = arv_stream_timeout_pop_buffer (stream, FRAME_US);
  g_assert_nonnull (buf);
  g_assert_cmpint (arv_buffer_get_status (buf), ==, ARV_BUFFER_STATUS_SUCCESS);
  g_assert_cmpint (arv_buffer_get_image_width (buf), ==, (int) width);
  g_assert_cmpint (arv_buffer_get_image_height (buf), ==, (int) height);
  size_t size = 0;
  const void *data = arv_buffer_get_image_data (buf, &size);
  DsImage *img = ds_pixfmt_unpack (DS_PIXFMT_MONO16, data, size, width, height, 0, &error);
  g_assert_no_error (error);
  arv_stream_push_buffer (stream, buf);
  return img;
}

static void
test_phase_over_the_wire (void)
{
  g_autoptr (GError) error = NULL;
  g_autoptr (DsScene) scene = ds_scene_load (scene_path, &error);
  g_assert_no_error (error);
  guint width = ds_scene_width (scene), height = ds_scene_height (scene);
  double period = ds_scene_period_px (scene);
  TestLabsim *l = test_labsim_start (labsim_path, scene_path, NULL);

  ArvCamera *cam = open_camera (l);
  arv_camera_set_pixel_format_from_string (cam, "Mono16", &error);
  g_assert_no_error (error);
  arv_camera_set_trigger (cam, "Software", &error);
  g_assert_no_error (error);
  arv_camera_set_exposure_time (cam, ds_scene_default_exposure_us (scene), &error);
  g_assert_no_error (error);
  guint payload = 0;
  ArvStream *stream = start_stream (cam, 4, &payload);
  g_assert_cmpuint (payload, ==, width * height * 2);

  g_autofree char *uri = g_strdup_printf ("tcp://127.0.0.1:%u", l->modbus_port);
  DsIlluminator *ill = ds_modbus_illuminator_open (uri, 1, ANSWER_MS, &error);
  g_assert_no_error (error);
  const guint n = 4;
  DsStripePattern pattern = { .kind = ds_scene_pattern_is_sine (scene) ? DS_STRIPES_SINE : DS_STRIPES_SQUARE,
                              .period_px = period, .duty = ds_scene_duty (scene),
                              .black_level = ds_scene_black_level (scene), .intensity = 1, .n_phases = n };
  g_assert_true (ill->ops->set_pattern (ill->backend, &pattern, &error));
  g_assert_no_error (error);

  /* Rows above the scene's objects: stripes over the medium only. */
  DsRegion region = { 0, 0, width, MIN (height, 40u) };
  const guint order[] = { 0, 1, 2, 3, 2, 0, 3, 1 };
  double phase0 = NAN, amplitude = 0;
  for (guint i = 0; i < G_N_ELEMENTS (order); i++) {
    guint k = order[i];
    g_assert_true (ill->ops->set_phase (ill->backend, k, APPLY_MS, &error));
    g_assert_no_error (error);
    g_autoptr (DsImage) img = grab_one (cam, stream, width, height);
    DsStripePhase sp;
    g_assert_true (ds_stripe_phase_measure (img, period, &region, &sp, &error));
    g_assert_no_error (error);
    g_assert_true (sp.reliable);
    if (i == 0) {
      phase0 = sp.phase;
      amplitude = sp.amplitude;
    }
    double rel = ds_stripe_phase_diff (sp.phase, phase0);
    double want = ds_stripe_phase_diff ((double) k / n, 0);
    g_test_message ("phase %u: measured %.3f cycles (%.3f from phase 0), expected %.3f", k, sp.phase, rel, want);
    /* Half a phase step tells every phase apart. */
    g_assert_cmpfloat (fabs (ds_stripe_phase_diff (rel, want)), <, 0.5 / n);
  }
  /* Dark: the pattern is gone (ambient light only). */
  g_assert_true (ill->ops->off (ill->backend, APPLY_MS, &error));
  g_autoptr (DsImage) dark = grab_one (cam, stream, width, height);
  DsStripePhase sp;
  g_assert_true (ds_stripe_phase_measure (dark, period, &region, &sp, &error));
  g_assert_cmpfloat (sp.amplitude, <, 0.1 * amplitude);

  ds_illuminator_close (ill);
  arv_camera_stop_acquisition (cam, NULL);
  g_object_unref (stream);
  g_object_unref (cam);
  test_labsim_stop (l);
}

static double
image_mean (const DsImage *img)
{
  double sum = 0;
  for (guint y = 0; y < img->height; y++) {
    const guint8 *row = ds_image_row (img, y);
    for (guint x = 0; x < img->width; x++)
      sum += img->type == DS_SAMPLE_U8 ? row[x] : ((const guint16 *) (const void *) row)[x];
  }
  return sum / ((double) img->width * img->height);
}

/* One lit frame in Mono16 and one in Mono8 (a fresh stream each): Mono8 carries the top 8 of
 * the sensor's bits, so its mean is the Mono16 mean / 2^(depth - 8), to within the truncation
 * (at most 1 DN) and the frames' different noise. */
static void
test_mono8 (void)
{
  g_autoptr (GError) error = NULL;
  g_autoptr (DsScene) scene = ds_scene_load (scene_path, &error);
  g_assert_no_error (error);
  guint width = ds_scene_width (scene), height = ds_scene_height (scene);
  TestLabsim *l = test_labsim_start (labsim_path, scene_path, NULL);
  ArvCamera *cam = open_camera (l);
  arv_camera_set_trigger (cam, "Software", &error);
  g_assert_no_error (error);
  double means[2];
  const char *formats[2] = { "Mono16", "Mono8" };
  for (guint f = 0; f < 2; f++) {
    arv_camera_set_pixel_format_from_string (cam, formats[f], &error);
    g_assert_no_error (error);
    guint payload = 0;
    ArvStream *stream = start_stream (cam, 2, &payload);
    g_assert_cmpuint (payload, ==, width * height * (f == 0 ? 2 : 1));
    arv_camera_software_trigger (cam, &error);
    g_assert_no_error (error);
    ArvBuffer *buf = arv_stream_timeout_pop_buffer (stream, FRAME_US);
    g_assert_nonnull (buf);
    g_assert_cmpint (arv_buffer_get_status (buf), ==, ARV_BUFFER_STATUS_SUCCESS);
    size_t size = 0;
    const void *data = arv_buffer_get_image_data (buf, &size);
    g_autoptr (DsImage) img = ds_pixfmt_unpack (f == 0 ? DS_PIXFMT_MONO16 : DS_PIXFMT_MONO8, data, size,
                                                width, height, 0, &error);
    g_assert_no_error (error);
    means[f] = image_mean (img);
    arv_stream_push_buffer (stream, buf);
    arv_camera_stop_acquisition (cam, NULL);
    g_object_unref (stream);
  }
  double scale = ldexp (1.0, (int) ds_scene_bit_depth (scene) - 8);
  g_test_message ("mean Mono16 %.2f DN, Mono8 %.2f DN (x%.0f = %.2f)", means[0], means[1], scale,
                  means[1] * scale);
  g_assert_cmpfloat (means[0], >, 4 * scale); /* a frame with light in it */
  g_assert_cmpfloat (fabs (means[0] / scale - means[1]), <, 1.0 + 0.02 * means[1]);
  g_object_unref (cam);
  test_labsim_stop (l);
}

/* --camera-vanish-after 3 --camera-vanish-for 1: three frames, then the camera stops
 * answering; a second later the same camera is back and streams again. */
static void
test_camera_vanishes (void)
{
  const char *extra[] = { "--camera-vanish-after", "3", "--camera-vanish-for", "1", NULL };
  TestLabsim *l = test_labsim_start (labsim_path, scene_path, extra);
  g_autoptr (GError) error = NULL;
  ArvCamera *cam = open_camera (l);
  arv_camera_set_trigger (cam, "Software", &error);
  g_assert_no_error (error);
  ArvStream *stream = start_stream (cam, 4, NULL);
  guint got = 0;
  for (guint i = 0; i < 6; i++) {
    GError *e = NULL;
    arv_camera_software_trigger (cam, &e);
    if (e) {
      g_error_free (e);
      break;
    }
    /* The three frames before it vanishes as long as a loaded machine takes; after them none
     * may come (a short wait: a late frame would still be counted by the assertion). */
    ArvBuffer *buf = arv_stream_timeout_pop_buffer (stream, got < 3 ? FRAME_US : 1000000);
    if (!buf)
      break;
    if (arv_buffer_get_status (buf) == ARV_BUFFER_STATUS_SUCCESS)
      got++;
    arv_stream_push_buffer (stream, buf);
  }
  g_assert_cmpuint (got, ==, 3);
  arv_camera_stop_acquisition (cam, NULL);
  g_object_unref (stream);
  g_object_unref (cam);
  /* Back within a few seconds (a minute allowed on a loaded machine): poll by opening. */
  ArvCamera *again = NULL;
  for (guint i = 0; i < 300 && !again; i++) {
    g_usleep (200000);
    GError *e = NULL;
    again = arv_camera_new ("127.0.0.1", &e);
    if (e)
      g_error_free (e);
  }
  g_assert_nonnull (again);
  g_assert_cmpstr (arv_camera_get_device_serial_number (again, NULL), ==, l->serial);
  g_object_unref (again);
  test_labsim_stop (l);
}


/* The projector-sync wiring: with TriggerSource Line0 the camera exposes once per pattern the
 * controller applies (its sync output drives Line0), never on a software command; the
 * missed- and double-trigger knobs remove and add exactly the frames they say. */
/* A frame may take long to come: the first of each lighting state is rendered then, and the
 * machine may be busy. So where every apply makes a frame (check_phase) each is waited for
 * without a short bound; where some make none (the knobs), frames late for their apply's second
 * are still counted by the next one's wait, and after the last. */
static guint
frames_for_applies (ArvStream *stream, DsIlluminator *ill, guint applies, guint expect, double period,
                    guint n, gboolean check_phase)
{
  g_autoptr (GError) error = NULL;
  guint got = 0;
  double phase0 = NAN;
  for (guint i = 0; i < applies; i++) {
    g_assert_true (ill->ops->set_phase (ill->backend, i % n, APPLY_MS, &error));
    g_assert_no_error (error);
    ArvBuffer *buf;
    /* Frames of this apply: the first (within a second when some applies make none), any
     * second one shortly after. */
    guint64 wait_us = check_phase ? FRAME_US : 1000000;
    while ((buf = arv_stream_timeout_pop_buffer (stream, wait_us))) {
      g_assert_cmpint (arv_buffer_get_status (buf), ==, ARV_BUFFER_STATUS_SUCCESS);
      if (check_phase) {
        size_t size = 0;
        const void *data = arv_buffer_get_data (buf, &size);
        g_autoptr (DsImage) img = ds_pixfmt_unpack (DS_PIXFMT_MONO16, data, size, (guint) arv_buffer_get_image_width (buf),
                                                    (guint) arv_buffer_get_image_height (buf), 0, &error);
        g_assert_no_error (error);
        DsRegion region = { 0, 0, img->width, MIN (img->height, 40u) };
        DsStripePhase sp;
        g_assert_true (ds_stripe_phase_measure (img, period, &region, &sp, &error));
        if (i == 0)
          phase0 = sp.phase;
        double want = ds_stripe_phase_diff ((double) (i % n) / n, 0);
        g_assert_cmpfloat (fabs (ds_stripe_phase_diff (ds_stripe_phase_diff (sp.phase, phase0), want)), <, 0.5 / n);
      }
      arv_stream_push_buffer (stream, buf);
      got++;
      wait_us = 150000;
    }
  }
  /* Frames still to come after the last apply: each of those expected waited for as long as a
   * render may take on a loaded machine; then a second for any beyond them. */
  ArvBuffer *late;
  while ((late = arv_stream_timeout_pop_buffer (stream, got < expect ? FRAME_US : 1000000))) {
    arv_stream_push_buffer (stream, late);
    got++;
  }
  return got;
}

static void
run_projector_sync (const char *const *extra, guint applies, guint expect_frames, gboolean check_phase)
{
  g_autoptr (GError) error = NULL;
  g_autoptr (DsScene) scene = ds_scene_load (scene_path, &error);
  g_assert_no_error (error);
  TestLabsim *l = test_labsim_start (labsim_path, scene_path, extra);
  ArvCamera *cam = open_camera (l);
  arv_camera_set_pixel_format_from_string (cam, "Mono16", &error);
  arv_camera_set_trigger (cam, "Line0", &error);
  g_assert_no_error (error);
  g_assert_cmpstr (arv_camera_get_trigger_source (cam, NULL), ==, "Line0");
  ArvStream *stream = start_stream (cam, 4, NULL);
  g_autofree char *uri = g_strdup_printf ("tcp://127.0.0.1:%u", l->modbus_port);
  DsIlluminator *ill = ds_modbus_illuminator_open (uri, 1, ANSWER_MS, &error);
  g_assert_no_error (error);
  const guint n = 4;
  DsStripePattern pattern = { .kind = ds_scene_pattern_is_sine (scene) ? DS_STRIPES_SINE : DS_STRIPES_SQUARE,
                              .period_px = ds_scene_period_px (scene), .duty = ds_scene_duty (scene),
                              .black_level = ds_scene_black_level (scene), .intensity = 1, .n_phases = n };
  g_assert_true (ill->ops->set_pattern (ill->backend, &pattern, &error));
  /* set_pattern's own write is an apply too (line trigger 1, which no knob removes): its frame
   * (dark) is not counted below. Waited for as long as its first render takes: one coming
   * after the window below would be taken for a frame of the software command. */
  ArvBuffer *first = arv_stream_timeout_pop_buffer (stream, FRAME_US);
  g_assert_nonnull (first);
  arv_stream_push_buffer (stream, first);
  /* A software command with a line source makes no frame. */
  arv_camera_software_trigger (cam, &error);
  g_assert_no_error (error);
  g_assert_null (arv_stream_timeout_pop_buffer (stream, 300000));
  guint got = frames_for_applies (stream, ill, applies, expect_frames, ds_scene_period_px (scene), n, check_phase);
  g_test_message ("%u applies: %u frames (expected %u)", applies, got, expect_frames);
  g_assert_cmpuint (got, ==, expect_frames);
  ds_illuminator_close (ill);
  arv_camera_stop_acquisition (cam, NULL);
  g_object_unref (stream);
  g_object_unref (cam);
  test_labsim_stop (l);
}

static void
test_projector_sync (void)
{
  run_projector_sync (NULL, 8, 8, TRUE);
  /* Line triggers counted from set_pattern's apply (1): applies 2..13 are line triggers 2..13;
   * every 4th is missed (4, 8, 12), every 5th doubled (5, 10). */
  const char *faults[] = { "--line-miss-every", "4", "--line-double-every", "5", NULL };
  run_projector_sync (faults, 12, 12 - 3 + 2, FALSE);
}

/* The controller's PERIOD_CENTIPX sets the period labsim's camera sees (issue 12), through the
 * daemon's own backends: Modbus for the projector, Aravis for the camera. With --fixed-period
 * the controller says it cannot, and the backend refuses another period before writing it. */
static void
run_period (gboolean fixed)
{
  g_autoptr (GError) error = NULL;
  g_autoptr (DsScene) scene = ds_scene_load (scene_path, &error);
  g_assert_no_error (error);
  double period = ds_scene_period_px (scene);
  const char *fixed_args[] = { "--fixed-period", NULL };
  TestLabsim *l = test_labsim_start (labsim_path, scene_path, fixed ? fixed_args : NULL);
  g_autofree char *uri = g_strdup_printf ("tcp://127.0.0.1:%u", l->modbus_port);
  DsIlluminator *ill = ds_modbus_illuminator_open (uri, 1, ANSWER_MS, &error);
  g_assert_no_error (error);
  DsCamera *cam = ds_aravis_camera_open ("127.0.0.1", 4, &error);
  g_assert_no_error (error);
  DsCameraSettings cs = { .exposure_us = ds_scene_default_exposure_us (scene), .pixel_format = "Mono16",
                          .trigger_source = DS_CAMERA_TRIGGER_SOFTWARE };
  g_assert_true (cam->ops->configure (cam->backend, &cs, &error));
  g_assert_true (cam->ops->start (cam->backend, &error));
  g_assert_no_error (error);

  DsIlluminatorStatus st;
  g_assert_true (ill->ops->get_status (ill->backend, &st, &error));
  g_assert_cmpint (st.period_adjustable, ==, !fixed);
  /* Rows above the scene's objects: stripes over the medium only. */
  DsRegion region = { 0, 0, ds_scene_width (scene), MIN (ds_scene_height (scene), 40u) };
  DsStripePattern p = { .kind = ds_scene_pattern_is_sine (scene) ? DS_STRIPES_SINE : DS_STRIPES_SQUARE,
                        .period_px = period, .duty = ds_scene_duty (scene),
                        .black_level = ds_scene_black_level (scene), .intensity = 1, .n_phases = 4 };
  if (!fixed) {
    g_assert_cmpfloat (st.period_min_px, ==, 2.0);
    g_assert_cmpfloat (st.period_max_px, ==, 655.35);
    /* Register values (1/100 px) other than the scene's, shorter and longer. */
    const double periods[] = { period, 4.37, 1.5 * period, 2.5 * period };
    for (guint i = 0; i < G_N_ELEMENTS (periods); i++) {
      p.period_px = periods[i];
      period_check_frames (ill, cam, &p, &region, 0.005);
    }
  } else {
    g_assert_cmpfloat (st.period_min_px, ==, round (period * 100) / 100);
    g_assert_cmpfloat (st.period_max_px, ==, st.period_min_px);
    p.period_px = 1.5 * period;
    g_assert_false (ill->ops->set_pattern (ill->backend, &p, &error));
    g_assert_error (error, DS_ILLUMINATOR_ERROR, DS_DEVICE_ERROR_UNSUPPORTED);
    g_test_message ("%s", error->message);
    g_autofree char *fixed_at = g_strdup_printf ("fixed at %.2f px", period);
    g_autofree char *asked = g_strdup_printf ("asked for %.2f px", 1.5 * period);
    g_assert_nonnull (strstr (error->message, "PERIOD_CENTIPX"));
    g_assert_nonnull (strstr (error->message, fixed_at));
    g_assert_nonnull (strstr (error->message, asked));
    p.period_px = period;
    period_check_frames (ill, cam, &p, &region, 0.005);
  }
  ds_camera_close (cam);
  ds_illuminator_close (ill);
  test_labsim_stop (l);
}

static void
test_period (void)
{
  run_period (FALSE);
}

static void
test_fixed_period (void)
{
  run_period (TRUE);
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  if (argc < 3) {
    fprintf (stderr, "usage: test_labsim LABSIM SCENE\n");
    return 2;
  }
  labsim_path = argv[1];
  scene_path = argv[2];
  g_test_add_func ("/labsim/phase-over-the-wire", test_phase_over_the_wire);
  g_test_add_func ("/labsim/mono8", test_mono8);
  g_test_add_func ("/labsim/camera-vanishes", test_camera_vanishes);
  g_test_add_func ("/labsim/projector-sync", test_projector_sync);
  g_test_add_func ("/labsim/period", test_period);
  g_test_add_func ("/labsim/fixed-period", test_fixed_period);
  int status = g_test_run ();
  arv_shutdown ();
  return status;
}
