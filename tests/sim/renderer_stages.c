/* The renderer against independent expectations: Beer-Lambert, Fresnel at normal incidence,
 * object shadows, scattering with a known kernel, truth consistent with the frames,
 * determinism, and stages the scene does not declare being absent and changing nothing. */
#include <glib/gstdio.h>
#include <math.h>
#include <string.h>

#include "drivers/sim/renderer.h"
#include "drivers/sim/transport.h"

/* 64x48 px, 0.1 mm pixels (5 um / 0.05): 1 photon/um^2/ms is 1e4 photons/px/ms. */
#define PX_PHOTONS_PER_MS 1e4
#define EXPOSURE_US 1000.0
#define QE 0.5
#define K 0.25

static DsScene *
scene_from (const char *extra, const char *illum)
{
  g_autofree char *text = g_strdup_printf (
    "[sensor]\nwidth=64\nheight=48\nbit-depth=16\nquantum-efficiency=%g\nsystem-gain=%g\nread-noise-e=3\n"
    "dark-current-e-per-s=1000\nfull-well-e=1e6\nexposure-us=%g\n"
    "[illuminator]\nperiod-px=8\nirradiance=1\n%s\n%s", QE, K, EXPOSURE_US, illum ? illum : "", extra);
  g_autoptr (GError) error = NULL;
  DsScene *s = ds_scene_load_data (text, strlen (text), "renderer-test.scene", &error);
  g_assert_no_error (error);
  return s;
}

/* DN of the "on" level with no medium: photons x QE x K. */
static double
open_dn (void)
{
  return PX_PHOTONS_PER_MS * EXPOSURE_US / 1000 * QE * K;
}

static float
px (const DsImage *im, guint x, guint y)
{
  return ((const float *) ds_image_row (im, y))[x];
}

static void
truth (const DsRenderer *r, DsImage **t, DsImage **s)
{
  g_autoptr (GError) error = NULL;
  g_assert_true (ds_renderer_truth (r, EXPOSURE_US, 0, t, s, &error));
  g_assert_no_error (error);
}

static void
assert_uniform (const DsImage *im, double expect, double rel)
{
  for (guint y = 0; y < im->height; y++)
    for (guint x = 0; x < im->width; x++)
      if (fabs (px (im, x, y) - expect) > rel * fabs (expect) + 1e-6)
        g_error ("pixel (%u, %u) = %g, expected %g", x, y, px (im, x, y), expect);
}

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
square_lit (double x, guint k, guint n, double period, double duty)
{
  double u = x / period - (double) k / n;
  u -= floor (u + 0.5); /* [-1/2, 1/2) */
  double edge = fabs (fabs (u) - duty / 2) * period;
  if (edge < 0.6)
    return -1;
  return fabs (u) < duty / 2 ? 1 : 0;
}

static DsImage *
gaussian_kernel (guint radius, double sigma, double total)
{
  g_autoptr (GError) error = NULL;
  DsImage *k = ds_image_new (DS_SAMPLE_F32, 2 * radius + 1, 2 * radius + 1, &error);
  double sum = 0;
  for (guint y = 0; y < k->height; y++)
    for (guint x = 0; x < k->width; x++) {
      double dx = (double) x - radius, dy = (double) y - radius;
      sum += ((float *) ds_image_row (k, y))[x] = (float) exp (-(dx * dx + dy * dy) / (2 * sigma * sigma));
    }
  for (guint y = 0; y < k->height; y++)
    for (guint x = 0; x < k->width; x++)
      ((float *) ds_image_row (k, y))[x] *= (float) (total / sum);
  return k;
}

static void
test_truth_consistent (void)
{
  /* sigma_s = 1/mm over 1 mm; a kernel holding 30 % of the light, much wider than a period:
   * Lg is 0.3 of the open level, the direct light exp(-1.05) of it. */
  g_autoptr (DsScene) s = scene_from ("[medium]\nthickness-mm=1\nmua=0.05\nmus=1\n", "black-level=0.1\nduty=0.5\n");
  g_autoptr (DsImage) kernel = gaussian_kernel (20, 6, 0.3);
  g_autoptr (GError) error = NULL;
  g_autoptr (DsRenderer) r = ds_renderer_new_with_kernels (s, kernel, NULL, NULL, &error);
  g_assert_no_error (error);
  g_assert_true (ds_renderer_has_stage (r, DS_RENDER_STAGE_SCATTERING));
  g_autoptr (DsImage) t = NULL;
  g_autoptr (DsImage) sc = NULL;
  truth (r, &t, &sc);
  double ld = open_dn () * exp (-1.05), lg = open_dn () * 0.3;
  assert_uniform (t, ld, 1e-5);
  assert_uniform (sc, lg, 1e-3);
  /* Frames: b + (1 - b) pattern times Ld, plus Lg times the pattern's mean a + b (1 - a),
   * plus the dark signal K x dark electrons (1000 e-/s x 1 ms). */
  double b = 0.1, a = 0.5, dark_dn = K * 1.0;
  const guint n = 4;
  for (guint k = 0; k < n; k++) {
    DsRenderRequest req = { .phase = k, .n_phases = n, .illuminator_on = TRUE, .exposure_us = EXPOSURE_US };
    g_autoptr (DsImage) e = ds_renderer_render_expected (r, &req, &error);
    g_assert_no_error (error);
    guint checked = 0;
    for (guint y = 0; y < 48; y++)
      for (guint x = 0; x < 64; x++) {
        double lit = square_lit (x, k, n, 8, 0.5);
        if (lit < 0)
          continue;
        double expect = (b + (1 - b) * lit) * ld + lg * (a + b * (1 - a)) + dark_dn;
        if (fabs (px (e, x, y) - expect) > 2e-3 * expect)
          g_error ("phase %u (%u, %u): %g, expected %g", k, x, y, px (e, x, y), expect);
        checked++;
      }
    g_assert_cmpuint (checked, >, 48 * 32);
    /* Noisy frames average to the expectation (64 seeds, one row's mean per column). */
    g_autofree double *acc = g_new0 (double, 64);
    for (guint seed = 0; seed < 64; seed++) {
      req.seed = seed;
      g_autoptr (DsImage) f = ds_renderer_render (r, &req, &error);
      g_assert_no_error (error);
      for (guint y = 0; y < 48; y++)
        for (guint x = 0; x < 64; x++)
          acc[x] += ((const guint16 *) ds_image_row (f, y))[x];
    }
    for (guint x = 0; x < 64; x++) {
      double mean = acc[x] / (64 * 48), expect = 0;
      for (guint y = 0; y < 48; y++)
        expect += px (e, x, y) / 48;
      /* Shot + read noise per pixel ~ sqrt(K mean + K^2 9) < 12 DN; over 3072 samples < 0.25 DN. */
      g_assert_cmpfloat (fabs (mean - expect), <, 1.2);
    }
  }
}

static void
test_clear_object_changes_nothing (void)
{
  /* A fully clear object at the entry face takes the 2-D (DFT) convolution path; without it
   * the renderer convolves one row with the kernel's column sums. Same light either way. */
  g_autoptr (DsScene) s0 = scene_from ("[medium]\nthickness-mm=1\nmua=0.05\nmus=1\n", "edge-blur-px=0.7\n");
  g_autoptr (DsScene) s1 = scene_from ("[medium]\nthickness-mm=1\nmua=0.05\nmus=1\n"
                                       "[object.clear]\nshape=rect\nposition=-100;-100\nsize=300;300\n"
                                       "transmittance=1\ndepth-mm=0\n", "edge-blur-px=0.7\n");
  /* An asymmetric kernel: a flipped or transposed convolution would show. */
  g_autoptr (DsImage) kernel = gaussian_kernel (9, 2.5, 0.3);
  for (guint y = 0; y < kernel->height; y++)
    for (guint x = 0; x < kernel->width; x++)
      ((float *) ds_image_row (kernel, y))[x] *= (float) (1.0 + 0.08 * x + 0.01 * y);
  g_autoptr (GError) error = NULL;
  g_autoptr (DsRenderer) r0 = ds_renderer_new_with_kernels (s0, kernel, NULL, NULL, &error);
  g_autoptr (DsRenderer) r1 = ds_renderer_new_with_kernels (s1, kernel, NULL, NULL, &error);
  g_assert_no_error (error);
  DsRenderRequest req = { .phase = 2, .n_phases = 5, .illuminator_on = TRUE, .exposure_us = EXPOSURE_US };
  g_autoptr (DsImage) a = ds_renderer_render_expected (r0, &req, &error);
  g_autoptr (DsImage) b = ds_renderer_render_expected (r1, &req, &error);
  g_assert_no_error (error);
  for (guint y = 0; y < 48; y++)
    for (guint x = 0; x < 64; x++)
      if (fabs (px (a, x, y) - px (b, x, y)) > 1e-4 * px (b, x, y))
        g_error ("(%u, %u): %g (rows) vs %g (DFT)", x, y, px (a, x, y), px (b, x, y));
}

static void
test_sine_pattern (void)
{
  /* Sine stripes, b = 0.2, N = 3: frame - dark = (b + (1 - b) 0.5 (1 + cos 2 pi u)) Ld
   * + (b + (1 - b) / 2) Lg, with Lg uniform (a kernel much wider than the period). */
  g_autoptr (DsScene) s = scene_from ("[medium]\nthickness-mm=1\nmua=0.05\nmus=1\n",
                                      "pattern=sine\nblack-level=0.2\n");
  g_autoptr (DsImage) kernel = gaussian_kernel (20, 6, 0.3);
  g_autoptr (GError) error = NULL;
  g_autoptr (DsRenderer) r = ds_renderer_new_with_kernels (s, kernel, NULL, NULL, &error);
  g_assert_no_error (error);
  double ld = open_dn () * exp (-1.05), lg = open_dn () * 0.3, b = 0.2, dark_dn = K * 1.0;
  for (guint k = 0; k < 3; k++) {
    DsRenderRequest req = { .phase = k, .n_phases = 3, .illuminator_on = TRUE, .exposure_us = EXPOSURE_US };
    g_autoptr (DsImage) e = ds_renderer_render_expected (r, &req, &error);
    g_assert_no_error (error);
    for (guint y = 0; y < 48; y += 7)
      for (guint x = 0; x < 64; x++) {
        double p = 0.5 * (1 + cos (2 * G_PI * (x / 8.0 - k / 3.0)));
        double expect = (b + (1 - b) * p) * ld + (b + (1 - b) / 2) * lg + dark_dn;
        if (fabs (px (e, x, y) - expect) > 2e-3 * expect)
          g_error ("phase %u (%u, %u): %g, expected %g", k, x, y, px (e, x, y), expect);
      }
  }
}

/* The projector's Gaussian blur of the square stripes at point t (no pixel yet): a sum over the
 * lit intervals of Phi((t - l)/sigma) - Phi((t - h)/sigma), written with erf. */
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
test_monte_carlo_kernel (void)
{
  /* With the transport's own kernel, the scattered truth of a uniformly lit scene is the
   * scattered-in-cone fraction that the Monte Carlo totals give (a separate tally), less what
   * lands beyond the kernel: 1 mm slab, 0.1 mm pixels, kernel radius 20 px = 2 mm. */
  g_autoptr (DsScene) s = scene_from ("[medium]\nthickness-mm=1\nmua=0.1\nmus=2\ng=0.8\nn=1.4\nphotons=40000\nseed=3\n"
                                      "[camera]\nacceptance-half-angle-deg=20\n", NULL);
  g_autoptr (GError) error = NULL;
  g_autofree char *cache = g_dir_make_tmp ("ds-psf-XXXXXX", &error);
  g_autoptr (DsRenderer) r = ds_renderer_new (s, cache, &error);
  g_assert_no_error (error);
  g_autoptr (DsImage) t = NULL;
  g_autoptr (DsImage) sc = NULL;
  truth (r, &t, &sc);
  DsSlab slab = { .mua = 0.1, .mus = 2, .g = 0.8, .thickness_mm = 1, .n_medium = 1.4, .n_above = 1, .n_below = 1 };
  DsSlabTally tally;
  g_assert_true (ds_mc_slab_run_cone (&slab, 200000, 11, 20, &tally, &error));
  g_assert_no_error (error);
  double lg = px (sc, 32, 24) / open_dn ();
  g_test_message ("scattered in cone: renderer %.4f, Monte Carlo totals %.4f +- %.4f", lg, tally.scattered_in_cone,
                  tally.se_scattered_in_cone);
  g_assert_cmpfloat (lg, <=, tally.scattered_in_cone + 4 * tally.se_scattered_in_cone + 0.01);
  g_assert_cmpfloat (lg, >, 0.9 * tally.scattered_in_cone - 0.01);
  /* Ballistic: Fresnel both faces and Beer-Lambert. */
  assert_uniform (t, open_dn () * pow (1 - pow (0.4 / 2.4, 2), 2) * exp (-2.1), 1e-5);
  /* The cache has the kernel now: a second renderer reads the same one. */
  g_autoptr (DsRenderer) r2 = ds_renderer_new (s, cache, &error);
  g_assert_no_error (error);
  g_autoptr (DsImage) t2 = NULL;
  g_autoptr (DsImage) sc2 = NULL;
  truth (r2, &t2, &sc2);
  g_assert_cmpmem (sc->data, sc->stride * sc->height, sc2->data, sc2->stride * sc2->height);
  g_autoptr (GDir) d = g_dir_open (cache, 0, &error);
  g_assert_no_error (error);
  guint files = 0;
  for (const char *name; (name = g_dir_read_name (d)); files++) {
    g_autofree char *p = g_build_filename (cache, name, NULL);
    g_unlink (p);
  }
  g_assert_cmpuint (files, >=, 1);
  g_rmdir (cache);
}

static void
test_split_plane (void)
{
  /* Opaque object over the left half at mid-depth: deep in its shadow nothing arrives, in the
   * open half the documented composition of the two kernels. */
  g_autoptr (DsScene) s = scene_from ("[medium]\nthickness-mm=2\nmua=0\nmus=0.5\nn=1\n"
                                      "[camera]\nacceptance-half-angle-deg=30\n"
                                      "[object.o]\nshape=rect\nposition=-10;-10\nsize=42;100\ndepth-mm=1\n", NULL);
  g_autoptr (DsImage) k1 = gaussian_kernel (5, 1.5, 0.2);
  g_autoptr (DsImage) k2 = gaussian_kernel (5, 1.5, 0.1);
  g_autoptr (GError) error = NULL;
  g_autoptr (DsRenderer) r = ds_renderer_new_with_kernels (s, NULL, k1, k2, &error);
  g_assert_no_error (error);
  g_autoptr (DsImage) t = NULL;
  g_autoptr (DsImage) sc = NULL;
  truth (r, &t, &sc);
  double open = open_dn (), b = exp (-0.5), kappa = 0.25; /* sin^2 30 deg, n = 1 */
  g_assert_cmpfloat (fabs (px (t, 10, 20)), <, 1e-6);
  g_assert_cmpfloat (fabs (px (sc, 10, 20)), <, 1e-6);
  g_assert_cmpfloat (fabs (px (t, 55, 20) - open * exp (-1.0)), <, 1e-4 * open);
  /* s1 = 0.2 open; at the plane: open b + s1; after: 0.1 of that, plus s1 b kappa. */
  double expect = 0.1 * (open * b + 0.2 * open) + 0.2 * open * b * kappa;
  g_assert_cmpfloat (fabs (px (sc, 55, 20) - expect), <, 1e-3 * expect);
  /* Object at the exit face instead: scattered light is cut by it. */
  g_autoptr (DsScene) s2 = scene_from ("[medium]\nthickness-mm=2\nmua=0\nmus=0.5\n"
                                       "[object.o]\nshape=rect\nposition=-10;-10\nsize=42;100\ndepth-mm=2\n", NULL);
  g_autoptr (DsRenderer) r2 = ds_renderer_new_with_kernels (s2, k1, NULL, NULL, &error);
  g_assert_no_error (error);
  g_autoptr (DsImage) t2 = NULL;
  g_autoptr (DsImage) sc2 = NULL;
  truth (r2, &t2, &sc2);
  g_assert_cmpfloat (fabs (px (sc2, 10, 20)), <, 1e-6);
  g_assert_cmpfloat (fabs (px (sc2, 55, 20) - 0.2 * open), <, 1e-3 * open);
  /* Split scene without both kernels: refused. */
  g_autoptr (DsRenderer) r3 = ds_renderer_new_with_kernels (s, k1, NULL, NULL, &error);
  g_assert_null (r3);
  g_assert_error (error, DS_SIM_ERROR, DS_SIM_ERROR_INVALID);
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

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  g_test_add_func ("/sim/renderer/beer-lambert", test_beer_lambert);
  g_test_add_func ("/sim/renderer/fresnel-normal", test_fresnel);
  g_test_add_func ("/sim/renderer/object-shadow", test_object_shadow);
  g_test_add_func ("/sim/renderer/truth-consistent", test_truth_consistent);
  g_test_add_func ("/sim/renderer/sine-pattern", test_sine_pattern);
  g_test_add_func ("/sim/renderer/clear-object-changes-nothing", test_clear_object_changes_nothing);
  g_test_add_func ("/sim/renderer/edge-blur", test_edge_blur);
  g_test_add_func ("/sim/renderer/split-plane", test_split_plane);
  g_test_add_func ("/sim/renderer/monte-carlo-kernel", test_monte_carlo_kernel);
  g_test_add_func ("/sim/renderer/deterministic", test_deterministic);
  g_test_add_func ("/sim/renderer/concurrent", test_concurrent);
  g_test_add_func ("/sim/renderer/undeclared-stage", test_undeclared_stage);
  g_test_add_func ("/sim/renderer/ambient-level", test_ambient_level);
  g_test_add_func ("/sim/renderer/mask-object", test_mask_object);
  return g_test_run ();
}
