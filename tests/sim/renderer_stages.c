/* The renderer's stages against independent expectations: Beer-Lambert, Fresnel at normal
 * incidence, object shadows, the blurred stripes, determinism, the light/sensor split, and stages
 * the scene does not declare being absent and changing nothing. Scattering: renderer_scattering.c. */
#include <glib/gstdio.h>

#include "tests/sim/renderer_fixture.h"

static void
test_beer_lambert (void)
{
  g_autoptr (DsScene) s = scene_from ("[medium]\nthickness-mm=2\nmua=0.5\nmus=0\n", NULL);
  g_autoptr (GError) error = NULL;
  g_autoptr (DsRenderer) r = ds_renderer_new (s, NULL, &error);
  g_assert_no_error (error);
  g_assert_true (ds_renderer_has_stage (r, DS_RENDER_STAGE_BALLISTIC));
  g_assert_false (ds_renderer_has_stage (r, DS_RENDER_STAGE_SCATTERING));
  g_assert_false (ds_renderer_has_stage (r, DS_RENDER_STAGE_BOUNDARY));
  g_autoptr (DsImage) t = NULL;
  g_autoptr (DsImage) sc = NULL;
  truth (r, &t, &sc);
  assert_uniform (t, open_dn () * exp (-1.0), 1e-5);
  assert_uniform (sc, 0, 0);
}

static void
test_fresnel (void)
{
  g_autoptr (DsScene) s = scene_from ("[medium]\nthickness-mm=1\nmua=0.1\nmus=0\nn=1.5\n", NULL);
  g_autoptr (GError) error = NULL;
  g_autoptr (DsRenderer) r = ds_renderer_new (s, NULL, &error);
  g_assert_no_error (error);
  g_assert_true (ds_renderer_has_stage (r, DS_RENDER_STAGE_BOUNDARY));
  g_autoptr (DsImage) t = NULL;
  g_autoptr (DsImage) sc = NULL;
  truth (r, &t, &sc);
  /* ((1 - 1.5) / (1 + 1.5))^2 = 0.04 at each face. */
  assert_uniform (t, open_dn () * 0.96 * 0.96 * exp (-0.1), 1e-5);
}

static void
test_object_shadow (void)
{
  g_autoptr (DsScene) s = scene_from ("[object.r]\nshape=rect\nposition=16;8\nsize=20;30\ntransmittance=0.25\n", NULL);
  g_autoptr (GError) error = NULL;
  g_autoptr (DsRenderer) r = ds_renderer_new (s, NULL, &error);
  g_assert_no_error (error);
  g_autoptr (DsImage) t = NULL;
  g_autoptr (DsImage) sc = NULL;
  truth (r, &t, &sc);
  /* Pixel x covers [x - 1/2, x + 1/2]: fully inside for 16.5 <= x - 1/2 and x + 1/2 <= 36. */
  for (guint y = 0; y < 48; y++)
    for (guint x = 0; x < 64; x++) {
      double cover_x = MAX (0.0, MIN (x + 0.5, 36.0) - MAX (x - 0.5, 16.0));
      double cover_y = MAX (0.0, MIN (y + 0.5, 38.0) - MAX (y - 0.5, 8.0));
      double cover = cover_x * cover_y;
      double expect = open_dn () * (1 - cover + 0.25 * cover);
      if (fabs (px (t, x, y) - expect) > 1e-4 * open_dn ())
        g_error ("(%u, %u): %g, expected %g", x, y, px (t, x, y), expect);
    }
}

/* Square pattern lit fraction of pixel x at phase k of n, or -1 near an edge. */
static double
blurred_square_at (double t, double period, double duty, double shift, double sigma)
{
  double v = 0;
  for (int j = -40; j <= 40; j++) {
    double c = period * (j + shift), l = c - duty * period / 2, h = c + duty * period / 2;
    v += 0.5 * (erf ((t - l) / (sigma * G_SQRT2)) - erf ((t - h) / (sigma * G_SQRT2)));
  }
  return v;
}

static void
test_edge_blur (void)
{
  /* Defocus is an optical blur of the continuous pattern, before the pixel integrates it: pixel x
   * sees the mean of the erf expression above over [x - 1/2, x + 1/2] (Simpson, 64 intervals,
   * against the renderer's closed form), not a blur of the already pixel-sampled pattern. */
  const double P = 8, duty = 0.35, b = 0.1, sigma = 1.3;
  g_autoptr (DsScene) s = scene_from ("", "duty=0.35\nblack-level=0.1\nedge-blur-px=1.3\n");
  g_autoptr (GError) error = NULL;
  g_autoptr (DsRenderer) r = ds_renderer_new (s, NULL, &error);
  g_assert_no_error (error);
  double dark_dn = K * 1.0;
  for (guint k = 0; k < 4; k++) {
    DsRenderRequest req = { .phase = k, .n_phases = 4, .illuminator_on = TRUE, .exposure_us = EXPOSURE_US };
    g_autoptr (DsImage) e = ds_renderer_render_expected (r, &req, &error);
    g_assert_no_error (error);
    for (guint x = 0; x < 64; x++) {
      double acc = 0;
      for (int i = 0; i <= 64; i++) {
        double t = x - 0.5 + i / 64.0, w = (i == 0 || i == 64) ? 1 : (i % 2 ? 4 : 2);
        acc += w * blurred_square_at (t, P, duty, k / 4.0, sigma);
      }
      double lit = acc / (3 * 64);
      double expect = (b + (1 - b) * lit) * open_dn () + dark_dn;
      if (fabs (px (e, x, 10) - expect) > 1e-5 * open_dn ())
        g_error ("phase %u x %u: %.6g, expected %.6g", k, x, px (e, x, 10), expect);
    }
  }
  /* The blur of a sine keeps its shape and scales its amplitude by exp(-2 pi^2 sigma^2 / P^2). */
  g_autoptr (DsScene) s2 = scene_from ("", "pattern=sine\nedge-blur-px=1.3\n");
  g_autoptr (DsRenderer) r2 = ds_renderer_new (s2, NULL, &error);
  g_assert_no_error (error);
  DsRenderRequest req = { .phase = 1, .n_phases = 3, .illuminator_on = TRUE, .exposure_us = EXPOSURE_US };
  g_autoptr (DsImage) e2 = ds_renderer_render_expected (r2, &req, &error);
  g_assert_no_error (error);
  double amp = exp (-2 * G_PI * G_PI * sigma * sigma / (P * P));
  for (guint x = 0; x < 64; x++) {
    double expect = 0.5 * (1 + amp * cos (2 * G_PI * (x / P - 1.0 / 3))) * open_dn () + dark_dn;
    g_assert_cmpfloat (fabs (px (e2, x, 3) - expect), <, 1e-5 * open_dn ());
  }
}

static void
test_deterministic (void)
{
  g_autoptr (DsScene) s = scene_from ("[ambient]\nlevel=0.01\n[object.g]\nshape=grid\npitch=16\nline-width=2\n", NULL);
  g_autoptr (GError) error = NULL;
  g_autoptr (DsRenderer) r = ds_renderer_new (s, NULL, &error);
  g_assert_no_error (error);
  DsRenderRequest req = { .phase = 1, .n_phases = 3, .illuminator_on = TRUE, .exposure_us = 800, .seed = 5 };
  g_autoptr (DsImage) a = ds_renderer_render (r, &req, &error);
  g_autoptr (DsImage) b = ds_renderer_render (r, &req, &error);
  req.seed = 6;
  g_autoptr (DsImage) c = ds_renderer_render (r, &req, &error);
  g_assert_no_error (error);
  gsize bytes = a->stride * a->height;
  g_assert_cmpmem (a->data, bytes, b->data, bytes);
  g_assert_true (memcmp (a->data, c->data, bytes) != 0);
  g_assert_cmpuint (a->bit_depth, ==, 16);
  /* In two steps (light once, then the sensor per frame, as labsim does): the same bits. The
   * light is the expectation before the sensor: K (QE photons + dark) is the expected frame. */
  req.seed = 5;
  g_autoptr (DsImage) light = ds_renderer_render_photons (r, &req, &error);
  g_assert_no_error (error);
  g_autoptr (DsImage) two = ds_renderer_expose (r, light, &req, &error);
  g_assert_no_error (error);
  g_assert_cmpmem (a->data, bytes, two->data, two->stride * two->height);
  g_assert_cmpuint (two->bit_depth, ==, 16);
  g_autoptr (DsImage) mean = ds_renderer_render_expected (r, &req, &error);
  for (guint y = 0; y < 48; y += 5)
    for (guint x = 0; x < 64; x++) {
      double expect = K * (QE * px (light, x, y) + 1000 * 800e-6);
      g_assert_cmpfloat (fabs (px (mean, x, y) - expect), <, 1e-5 * expect);
    }
  g_autoptr (DsImage) wrong = ds_image_new (DS_SAMPLE_F32, 32, 48, &error);
  g_assert_null (ds_renderer_expose (r, wrong, &req, &error));
  g_assert_error (error, DS_SIM_ERROR, DS_SIM_ERROR_INVALID);
  g_clear_error (&error);
  /* Bad requests fail with a reason. */
  req.phase = 3;
  g_autoptr (DsImage) bad = ds_renderer_render (r, &req, &error);
  g_assert_null (bad);
  g_assert_error (error, DS_SIM_ERROR, DS_SIM_ERROR_INVALID);
}

typedef struct {
  const DsRenderer *r;
  DsImage *out;
} ThreadJob;

static gpointer
render_thread (gpointer p)
{
  ThreadJob *j = p;
  DsRenderRequest req = { .phase = 0, .n_phases = 2, .illuminator_on = TRUE, .exposure_us = 900, .seed = 77 };
  j->out = ds_renderer_render (j->r, &req, NULL);
  return NULL;
}

static void
test_concurrent (void)
{
  g_autoptr (DsScene) s = scene_from ("[medium]\nthickness-mm=1\nmua=0.05\nmus=1\n", NULL);
  g_autoptr (DsImage) kernel = gaussian_kernel (10, 3, 0.3);
  g_autoptr (GError) error = NULL;
  g_autoptr (DsRenderer) r = ds_renderer_new_with_kernels (s, kernel, NULL, NULL, &error);
  g_assert_no_error (error);
  ThreadJob jobs[3] = { { r, NULL }, { r, NULL }, { r, NULL } };
  GThread *th[2];
  for (guint i = 0; i < 2; i++)
    th[i] = g_thread_new ("render", render_thread, &jobs[i]);
  render_thread (&jobs[2]);
  for (guint i = 0; i < 2; i++)
    g_thread_join (th[i]);
  gsize bytes = jobs[2].out->stride * jobs[2].out->height;
  for (guint i = 0; i < 2; i++) {
    g_assert_cmpmem (jobs[i].out->data, bytes, jobs[2].out->data, bytes);
    ds_image_free (jobs[i].out);
  }
  ds_image_free (jobs[2].out);
  g_assert_cmpuint (ds_renderer_stage_runs (r, DS_RENDER_STAGE_SCATTERING), ==, 3);
}

static void
test_undeclared_stage (void)
{
  /* Same scene without [ambient] and with [ambient] level=0: the first has no ambient stage,
   * never runs one, and renders bit-identically to the second, which does run it. */
  const char *common = "[object.g]\nshape=grid\npitch=16\nline-width=2\n";
  g_autoptr (DsScene) without = scene_from (common, NULL);
  g_autofree char *with_text = g_strconcat (common, "[ambient]\nlevel=0\n", NULL);
  g_autoptr (DsScene) with = scene_from (with_text, NULL);
  g_autoptr (GError) error = NULL;
  g_autoptr (DsRenderer) r0 = ds_renderer_new (without, NULL, &error);
  g_autoptr (DsRenderer) r1 = ds_renderer_new (with, NULL, &error);
  g_assert_no_error (error);
  g_assert_false (ds_renderer_has_stage (r0, DS_RENDER_STAGE_AMBIENT));
  g_assert_true (ds_renderer_has_stage (r1, DS_RENDER_STAGE_AMBIENT));
  g_assert_cmpuint (ds_renderer_n_stages (r1), ==, ds_renderer_n_stages (r0) + 1);
  g_assert_cmpstr (ds_renderer_stage_name (r1, ds_renderer_n_stages (r1) - 2), ==, "ambient");
  /* No medium: none of the medium's stages exist either. */
  for (guint i = 0; i < ds_renderer_n_stages (r0); i++) {
    DsRenderStage k = ds_renderer_stage (r0, i);
    g_assert_true (k == DS_RENDER_STAGE_PATTERN || k == DS_RENDER_STAGE_OBJECTS || k == DS_RENDER_STAGE_SENSOR);
    g_assert_nonnull (ds_renderer_stage_reason (r0, i));
    g_assert_cmpstr (ds_renderer_stage_name (r0, i), ==, ds_render_stage_name (k));
  }
  for (guint k = 0; k < 4; k++) {
    DsRenderRequest req = { .phase = k, .n_phases = 4, .illuminator_on = k < 3, .exposure_us = 700, .seed = 11 + k };
    double secs0[DS_RENDER_N_STAGES] = { 0 };
    g_autoptr (DsImage) a = ds_renderer_render_timed (r0, &req, secs0, &error);
    g_autoptr (DsImage) b = ds_renderer_render (r1, &req, &error);
    g_assert_no_error (error);
    g_assert_cmpmem (a->data, a->stride * a->height, b->data, b->stride * b->height);
    g_assert_cmpfloat (secs0[DS_RENDER_STAGE_AMBIENT], ==, 0);
    g_assert_cmpfloat (secs0[DS_RENDER_STAGE_SCATTERING], ==, 0);
  }
  g_assert_cmpuint (ds_renderer_stage_runs (r0, DS_RENDER_STAGE_AMBIENT), ==, 0);
  g_assert_cmpuint (ds_renderer_stage_runs (r0, DS_RENDER_STAGE_SCATTERING), ==, 0);
  g_assert_cmpuint (ds_renderer_stage_runs (r0, DS_RENDER_STAGE_BALLISTIC), ==, 0);
  g_assert_cmpuint (ds_renderer_stage_runs (r1, DS_RENDER_STAGE_AMBIENT), ==, 4);
  g_assert_cmpuint (ds_renderer_stage_runs (r0, DS_RENDER_STAGE_SENSOR), ==, 4);
}

static void
test_mask_object (void)
{
  /* A mask file beside the scene: white rows 10..19 at transmittance 0.5, grey (128/255) rows
   * 30..39, black elsewhere; relative paths resolve against the scene file's folder. */
  g_autoptr (GError) error = NULL;
  g_autofree char *dir = g_dir_make_tmp ("ds-mask-XXXXXX", &error);
  g_assert_no_error (error);
  g_autoptr (DsImage) mask = ds_image_new (DS_SAMPLE_U8, 64, 48, &error);
  for (guint y = 0; y < 48; y++)
    memset (ds_image_row (mask, y), y >= 10 && y < 20 ? 255 : y >= 30 && y < 40 ? 128 : 0, 64);
  g_autofree char *mask_path = g_build_filename (dir, "m.png", NULL);
  g_assert_true (ds_image_write (mask, mask_path, &error));
  g_autofree char *scene_path = g_build_filename (dir, "s.scene", NULL);
  g_autofree char *text = g_strdup_printf (
    "[sensor]\nwidth=64\nheight=48\nquantum-efficiency=%g\nsystem-gain=%g\n[illuminator]\nperiod-px=8\nirradiance=1\n"
    "[object.m]\nshape=mask\nmask=m.png\ntransmittance=0.5\n", QE, K);
  g_autoptr (DsScene) s = ds_scene_load_data (text, strlen (text), scene_path, &error);
  g_assert_no_error (error);
  g_autoptr (DsRenderer) r = ds_renderer_new (s, NULL, &error);
  g_assert_no_error (error);
  g_autoptr (DsImage) t = NULL;
  g_autoptr (DsImage) sc = NULL;
  truth (r, &t, &sc);
  double open = open_dn ();
  g_assert_cmpfloat (fabs (px (t, 5, 15) - 0.5 * open), <, 1e-4 * open);
  g_assert_cmpfloat (fabs (px (t, 5, 35) - (1 - 128.0 / 255 * 0.5) * open), <, 1e-4 * open);
  g_assert_cmpfloat (fabs (px (t, 5, 25) - open), <, 1e-4 * open);
  /* A mask of the wrong size is refused, naming the file. */
  g_autoptr (DsImage) small = ds_image_new (DS_SAMPLE_U8, 32, 48, &error);
  g_assert_true (ds_image_write (small, mask_path, &error));
  g_autoptr (DsRenderer) r2 = ds_renderer_new (s, NULL, &error);
  g_assert_null (r2);
  g_assert_error (error, DS_SIM_ERROR, DS_SIM_ERROR_INVALID);
  g_assert_nonnull (strstr (error->message, "m.png"));
  g_unlink (mask_path);
  g_rmdir (dir);
}

static void
test_ambient_level (void)
{
  /* Ambient light shows in the black frame: K QE (level x 1e4 photons/px/ms x 1 ms) + dark. */
  g_autoptr (DsScene) s = scene_from ("[ambient]\nlevel=0.2\n", NULL);
  g_autoptr (GError) error = NULL;
  g_autoptr (DsRenderer) r = ds_renderer_new (s, NULL, &error);
  DsRenderRequest req = { .illuminator_on = FALSE, .exposure_us = EXPOSURE_US };
  g_autoptr (DsImage) e = ds_renderer_render_expected (r, &req, &error);
  g_assert_no_error (error);
  assert_uniform (e, K * (QE * 0.2 * PX_PHOTONS_PER_MS + 1.0), 1e-5);
}

/* An illuminator that changes its period (the PERIOD register): a frame requested at another
 * period is the frame of the same scene declaring that period, bit for bit; a period outside
 * the scene format's range is refused. */
static void
test_period_override (void)
{
  const char *extra = "[ambient]\nlevel=0.01\n[object.g]\nshape=grid\npitch=16\nline-width=2\n";
  g_autoptr (DsScene) s8 = scene_from (extra, "edge-blur-px=0.7\n");
  g_autofree char *text = g_strdup_printf (
    "[sensor]\nwidth=64\nheight=48\nbit-depth=16\nquantum-efficiency=%g\nsystem-gain=%g\nread-noise-e=3\n"
    "dark-current-e-per-s=1000\nfull-well-e=1e6\nexposure-us=%g\n"
    "[illuminator]\nperiod-px=13.5\nirradiance=1\nedge-blur-px=0.7\n%s", QE, K, EXPOSURE_US, extra);
  g_autoptr (GError) error = NULL;
  g_autoptr (DsScene) s13 = ds_scene_load_data (text, strlen (text), "renderer-test.scene", &error);
  g_assert_no_error (error);
  g_autoptr (DsRenderer) r8 = ds_renderer_new (s8, NULL, &error);
  g_autoptr (DsRenderer) r13 = ds_renderer_new (s13, NULL, &error);
  g_assert_no_error (error);
  DsRenderRequest req = { .phase = 2, .n_phases = 5, .illuminator_on = TRUE, .exposure_us = 800, .seed = 9 };
  g_autoptr (DsImage) native = ds_renderer_render (r13, &req, &error);
  req.period_px = 13.5;
  g_autoptr (DsImage) changed = ds_renderer_render (r8, &req, &error);
  g_assert_no_error (error);
  g_assert_cmpmem (native->data, native->stride * native->height, changed->data, changed->stride * changed->height);
  req.period_px = 0;
  g_autoptr (DsImage) own = ds_renderer_render (r8, &req, &error);
  g_assert_true (memcmp (own->data, changed->data, own->stride * own->height) != 0);
  req.period_px = 1.5;
  g_assert_null (ds_renderer_render (r8, &req, &error));
  g_assert_error (error, DS_SIM_ERROR, DS_SIM_ERROR_INVALID);
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  g_test_add_func ("/sim/renderer/beer-lambert", test_beer_lambert);
  g_test_add_func ("/sim/renderer/fresnel-normal", test_fresnel);
  g_test_add_func ("/sim/renderer/object-shadow", test_object_shadow);
  g_test_add_func ("/sim/renderer/edge-blur", test_edge_blur);
  g_test_add_func ("/sim/renderer/deterministic", test_deterministic);
  g_test_add_func ("/sim/renderer/concurrent", test_concurrent);
  g_test_add_func ("/sim/renderer/undeclared-stage", test_undeclared_stage);
  g_test_add_func ("/sim/renderer/ambient-level", test_ambient_level);
  g_test_add_func ("/sim/renderer/mask-object", test_mask_object);
  g_test_add_func ("/sim/renderer/period-override", test_period_override);
  return g_test_run ();
}
