/* labsim serves a scene whose scattering kernel is far wider than its frame, through two object
 * planes (tests/drivers/wide-kernel.scene): its lighting states are rendered before it is ready
 * and again, off the GigE Vision thread, when the phase count or period changes.
 *
 *   /labsim-wide/daemon-sets: descatterd takes whole sets at the power-up phase count and then,
 *     from the same labsim, at another (a settings change labsim renders in the background):
 *     every set equals the scene's truth, and no grab times out.
 *   /labsim-wide/settings-change: plain Aravis and the Modbus backend: a new phase count (or
 *     period) is set and a phase lit and triggered at once, while labsim has not rendered that
 *     light yet; each frame must show the phase lit at its trigger, measured in the frame
 *     (proc/stripe_phase.h), never one of the previous set.
 *
 * Usage: test_labsim_wide LABSIM SCENE. Binds UDP 3956 (RESOURCE_LOCK gige_port_3956). */
#include <arv.h>
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "tests/common/daemon_harness.h"
#include "tests/common/truth_check.h"
#include "drivers/modbus/modbus_illuminator.h"
#include "proc/pixfmt.h"
#include "proc/stripe_phase.h"

static const char *labsim_path, *scene_path;
static DsScene *the_scene;
static DsImage *truth_t, *truth_g;

static char *
daemon_config (const TestLabsim *l, guint phases)
{
  return g_strdup_printf ("[camera]\nbackend=aravis\naddress=127.0.0.1\npixel-format=Mono16\n"
                          "exposure-us=%g\ngrab-timeout-ms=30000\n"
                          "[illuminator]\nbackend=modbus\nmodbus-uri=tcp://127.0.0.1:%u\nmodbus-timeout-ms=300\n"
                          "period-px=%g\nduty=%g\n"
                          "[acquisition]\nphases=%u\naverages=1\ndark-frame=false\nphase-retries=2\n",
                          ds_scene_default_exposure_us (the_scene), l->modbus_port, ds_scene_period_px (the_scene),
                          ds_scene_duty (the_scene), phases);
}

static void
daemon_sets (const TestLabsim *l, guint phases, guint sets)
{
  g_autofree char *conf = daemon_config (l, phases);
  TestDaemon *d = test_daemon_start (conf, NULL);
  g_autoptr (DsClient) c = test_daemon_connect (d);
  for (guint i = 0; i < sets; i++) {
    g_autoptr (DsMessage) m = test_daemon_call_ok (c, "capture", NULL);
    TruthCheck tc;
    truth_check (m, the_scene, truth_t, truth_g, &tc);
    g_test_message ("%u phases, set %u: rms %.2f/%.2f DN (allowed %.2f/%.2f)", phases, i, tc.rms_transmissive,
                    tc.rms_scattered, tc.allowed_transmissive, tc.allowed_scattered);
    g_assert_true (truth_check_passed (&tc));
  }
  TestFrames f = test_daemon_frames (c);
  g_assert_cmpint (f.timeouts, ==, 0);
  g_assert_cmpint (f.folded, ==, (gint64) (phases * sets));
  test_daemon_stop_clean (d);
}

static void
test_daemon_sets (void)
{
  /* 4 phases: labsim's power-up set, rendered before its ready line; then 3 and 5, rendered
   * while the daemon already triggers. */
  TestLabsim *l = test_labsim_start (labsim_path, scene_path, NULL);
  daemon_sets (l, 4, 2);
  daemon_sets (l, 3, 2);
  daemon_sets (l, 5, 1);
  test_labsim_stop (l);
}

/* One frame for a software trigger. labsim drops a trigger whose light is not rendered 10 s
 * after it: then the trigger is sent again, as the daemon does after a grab timeout. A frame
 * of the wrong light is never allowed. */
static DsImage *
grab (ArvCamera *cam, ArvStream *stream, double *latency_ms)
{
  g_autoptr (GError) error = NULL;
  gint64 t0 = g_get_monotonic_time ();
  ArvBuffer *buf = NULL;
  for (guint attempt = 0; attempt < 3 && !buf; attempt++) {
    arv_camera_software_trigger (cam, &error);
    g_assert_no_error (error);
    buf = arv_stream_timeout_pop_buffer (stream, 15000000);
    if (!buf)
      g_test_message ("no frame 15 s after a trigger: triggering again");
  }
  g_assert_nonnull (buf);
  *latency_ms = (double) (g_get_monotonic_time () - t0) / 1000.0;
  g_assert_cmpint (arv_buffer_get_status (buf), ==, ARV_BUFFER_STATUS_SUCCESS);
  size_t size = 0;
  const void *data = arv_buffer_get_image_data (buf, &size);
  DsImage *img = ds_pixfmt_unpack (DS_PIXFMT_MONO16, data, size, ds_scene_width (the_scene),
                                   ds_scene_height (the_scene), 0, &error);
  g_assert_no_error (error);
  arv_stream_push_buffer (stream, buf);
  return img;
}

static double
stripe_phase (const DsImage *img, double period)
{
  /* Rows above the objects: stripes over the medium only. */
  DsRegion region = { 0, 0, img->width, 16 };
  DsStripePhase sp;
  g_autoptr (GError) error = NULL;
  g_assert_true (ds_stripe_phase_measure (img, period, &region, &sp, &error));
  g_assert_no_error (error);
  g_assert_true (sp.reliable);
  return sp.phase;
}

/* The stripe phase of the renderer's own noise-free frame of phase k of n at `period`: the
 * measurement's pixel-sampling bias is the same as for labsim's frames (served --noiseless, so
 * that the two agree to rounding and a frame of another light cannot pass). */
static double
expected_phase (const DsRenderer *r, guint k, guint n, double period)
{
  g_autoptr (GError) error = NULL;
  DsRenderRequest req = { .phase = k, .n_phases = n, .illuminator_on = TRUE,
                          .exposure_us = ds_scene_default_exposure_us (the_scene),
                          .period_px = period == ds_scene_period_px (the_scene) ? 0 : period };
  g_autoptr (DsImage) e = ds_renderer_render_expected (r, &req, &error);
  g_assert_no_error (error);
  return stripe_phase (e, period);
}

static void
test_settings_change (void)
{
  g_autoptr (GError) error = NULL;
  g_autoptr (DsRenderer) r = ds_renderer_new (the_scene, NULL, &error);
  g_assert_no_error (error);
  const char *noiseless[] = { "--noiseless", NULL };
  TestLabsim *l = test_labsim_start (labsim_path, scene_path, noiseless);
  g_autoptr (ArvCamera) cam = arv_camera_new ("127.0.0.1", &error);
  g_assert_no_error (error);
  arv_camera_set_pixel_format_from_string (cam, "Mono16", &error);
  g_assert_no_error (error);
  arv_camera_set_trigger (cam, "Software", &error);
  g_assert_no_error (error);
  g_autoptr (ArvStream) stream = arv_camera_create_stream (cam, NULL, NULL, &error);
  g_assert_no_error (error);
  guint payload = arv_camera_get_payload (cam, &error);
  for (guint i = 0; i < 4; i++)
    arv_stream_push_buffer (stream, arv_buffer_new (payload, NULL));
  arv_camera_start_acquisition (cam, &error);
  g_assert_no_error (error);
  g_autofree char *uri = g_strdup_printf ("tcp://127.0.0.1:%u", l->modbus_port);
  DsIlluminator *ill = ds_modbus_illuminator_open (uri, 1, 300, &error);
  g_assert_no_error (error);

  double period = ds_scene_period_px (the_scene);
  DsStripePattern pattern = { .kind = DS_STRIPES_SQUARE, .period_px = period, .duty = ds_scene_duty (the_scene),
                              .intensity = 1, .n_phases = 4 };
  g_assert_true (ill->ops->set_pattern (ill->backend, &pattern, &error));
  g_assert_no_error (error);
  g_assert_true (ill->ops->set_phase (ill->backend, 0, 1000, &error));
  g_assert_no_error (error);
  double latency;
  g_autoptr (DsImage) first = grab (cam, stream, &latency);
  double before = stripe_phase (first, period); /* the light lit before each step */
  g_assert_cmpfloat (fabs (ds_stripe_phase_diff (before, expected_phase (r, 0, 4, period))), <, 0.005);

  /* Each step is a set labsim has not rendered (a new phase count, then a new period), its
   * phase lit and triggered at once. Any frame of the set before shows another phase: phase k
   * of the old count, or the phase lit before. */
  static const struct { guint n, k; double period; } steps[] = {
    { 2, 1, 0 }, { 3, 2, 0 }, { 5, 3, 0 }, { 6, 1, 0 }, { 5, 1, 7.5 }, { 8, 5, 7.5 },
  };
  for (guint i = 0; i < G_N_ELEMENTS (steps); i++) {
    double p = steps[i].period > 0 ? steps[i].period : period;
    pattern.n_phases = steps[i].n;
    pattern.period_px = p;
    g_assert_true (ill->ops->set_pattern (ill->backend, &pattern, &error));
    g_assert_no_error (error);
    g_assert_true (ill->ops->set_phase (ill->backend, steps[i].k, 1000, &error));
    g_assert_no_error (error);
    g_autoptr (DsImage) img = grab (cam, stream, &latency);
    double measured = stripe_phase (img, p), want = expected_phase (r, steps[i].k, steps[i].n, p);
    /* What a frame of the previous set would show: its phase k, or the phase lit before. */
    guint n_prev = i ? steps[i - 1].n : 4;
    double p_prev = i && steps[i - 1].period > 0 ? steps[i - 1].period : period;
    /* (At another period an old frame has no reliable stripes at this one: stripe_phase fails.) */
    double old_k = steps[i].k < n_prev && p_prev == p ? expected_phase (r, steps[i].k, n_prev, p) : NAN;
    g_test_message ("phase %u of %u at %.1f px: measured %.3f cycles, lit %.3f; previous set's phase %u %.3f, "
                    "lit before %.3f (frame after %.0f ms)", steps[i].k, steps[i].n, p, measured, want, steps[i].k,
                    old_k, before, latency);
    g_assert_cmpfloat (fabs (ds_stripe_phase_diff (measured, want)), <, 0.005);
    g_assert_cmpfloat (fabs (ds_stripe_phase_diff (measured, before)), >, 0.02);
    if (!isnan (old_k))
      g_assert_cmpfloat (fabs (ds_stripe_phase_diff (measured, old_k)), >, 0.02);
    before = measured;
  }
  ds_illuminator_close (ill);
  arv_camera_stop_acquisition (cam, NULL);
  test_labsim_stop (l);
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  if (argc < 3) {
    fprintf (stderr, "usage: test_labsim_wide LABSIM SCENE\n");
    return 2;
  }
  labsim_path = argv[1];
  scene_path = argv[2];
  truth_scene_load (scene_path, &the_scene, &truth_t, &truth_g);
  g_test_add_func ("/labsim-wide/daemon-sets", test_daemon_sets);
  g_test_add_func ("/labsim-wide/settings-change", test_settings_change);
  int status = g_test_run ();
  truth_scene_free (the_scene, truth_t, truth_g);
  return status;
}
