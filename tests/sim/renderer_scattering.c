/* The scattering stage against independent expectations: frames consistent with the truth for a
 * known kernel, the sine pattern, the 1-D and DFT paths agreeing, the chain through an object
 * plane against its closed form, the Monte Carlo kernel against the transport's totals, and the
 * modulated share of the scattered light against a Gaussian's MTF. */
#include <glib/gstdio.h>

#include "drivers/sim/transport.h"
#include "tests/sim/renderer_fixture.h"

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
static void
test_monte_carlo_kernel (void)
{
  /* With the transport's own kernel, the scattered truth of a uniformly lit scene is the
   * scattered-in-cone fraction that the Monte Carlo totals give (a separate tally), less what
   * lands beyond the kernel (sized to hold 99.5 %): 1 mm slab, 0.1 mm pixels. */
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
  /* Within both runs' Monte Carlo errors, less at most the 0.5 % the kernel leaves out. */
  DsRendererScattering info;
  g_assert_true (ds_renderer_scattering (r, &info));
  double se = hypot (tally.se_scattered_in_cone, info.se_scattered_in_cone);
  g_assert_cmpfloat (info.held, >=, 0.995);
  g_assert_cmpfloat (lg, <=, tally.scattered_in_cone + 4 * se);
  g_assert_cmpfloat (lg, >=, 0.995 * tally.scattered_in_cone - 4 * se);
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

/* Sum of a kernel's column x (its marginal along x). */
static double
column (const DsImage *k, guint x)
{
  double s = 0;
  for (guint y = 0; y < k->height; y++)
    s += ((const float *) ds_image_row (k, y))[x];
  return s;
}

static void
test_plane_chain (void)
{
  /* One plane at 1 mm of a 2 mm slab with hand-made kernels; transmittance 0.4 left of 31.5 px,
   * clear right of it. Per unit of incident light: 0.2 arrives unscattered at the plane, 0.3
   * scattered (sigma 2 px); of the scattered, 0.3 crosses back and forth once more and last
   * crosses 3 px to the right (meeting O^2 there), 0.7 crosses once; then 0.5 (sigma 3 px) of the
   * unscattered and 0.8 (sigma 4 px) of the scattered light leave in the cone. Uniform light:
   *   out(x) = sum_y [0.5 g3(x - y) O(y) 0.2 + 0.8 g4(x - y) (0.7 O(y) 0.3 + 0.3 O(y - 3) 0.3 O(y)^2)]
   * computed here as a direct sum over the kernels' marginals. */
  g_autoptr (DsScene) s = scene_from ("[medium]\nthickness-mm=2\nmua=0\nmus=0.5\n"
                                      "[object.o]\nshape=rect\nposition=-1000;-1000\nsize=1031.5;3000\n"
                                      "depth-mm=1\ntransmittance=0.4\n", NULL);
  const guint R = 12;
  g_autoptr (DsSlabKernels) k = g_new0 (DsSlabKernels, 1);
  k->radius_px = R;
  k->planes.n_planes = 1;
  k->planes.depth_mm[0] = 1;
  k->full = gaussian_kernel (R, 3, 0.2 * 0.5 + 0.3 * 0.8);
  k->segments[0].from_ballistic = gaussian_kernel (R, 2, 0.3);
  k->segments[0].stays_ballistic = 0.2;
  k->segments[1].from_ballistic = gaussian_kernel (R, 3, 0.5);
  k->segments[1].from_scattered = gaussian_kernel (R, 4, 0.8);
  DsSlabPlaneCrossing *c = &k->crossings[0];
  c->once_ballistic = 1;
  c->once_scattered = 0.7;
  c->recross_ballistic = gaussian_kernel (R, 1, 0);
  c->recross_scattered = gaussian_kernel (R, 1, 0);
  ((float *) ds_image_row (c->recross_scattered, R))[R + 3] = 0.3f; /* last crossing 3 px right of the first */
  c->recross_times[0] = 1;
  k->held = 1;
  g_autoptr (GError) error = NULL;
  g_autoptr (DsRenderer) r = ds_renderer_new_with_slab_kernels (s, k, &error);
  g_assert_no_error (error);
  g_autoptr (DsImage) t = NULL;
  g_autoptr (DsImage) sc = NULL;
  truth (r, &t, &sc);
  double g3[2 * 12 + 1], g4[2 * 12 + 1];
  for (guint i = 0; i <= 2 * R; i++) {
    g3[i] = column (k->segments[1].from_ballistic, i) / 0.5;
    g4[i] = column (k->segments[1].from_scattered, i) / 0.8;
  }
  for (guint x = 0; x < 64; x++) {
    double expect = 0;
    for (int d = -(int) R; d <= (int) R; d++) {
      int y = (int) x - d;
      double o = y <= 31 ? 0.4 : 1.0, o3 = y - 3 <= 31 ? 0.4 : 1.0;
      expect += 0.5 * g3[d + R] * o * 0.2 + 0.8 * g4[d + R] * (0.7 * o * 0.3 + 0.3 * o3 * 0.3 * o * o);
    }
    expect *= open_dn ();
    for (guint y = 0; y < 48; y += 11)
      if (fabs (px (sc, x, y) - expect) > 1e-4 * open_dn ())
        g_error ("(%u, %u): %g, expected %g", x, y, px (sc, x, y), expect);
    /* The direct light passes the plane once. */
    g_assert_cmpfloat (fabs (px (t, x, 20) - open_dn () * exp (-1.0) * (x <= 31 ? 0.4 : 1.0)), <, 1e-4 * open_dn ());
  }
  /* Objects at the exit face instead: the scattered light is cut by them, no chain. */
  g_autoptr (DsScene) s2 = scene_from ("[medium]\nthickness-mm=2\nmua=0\nmus=0.5\n"
                                       "[object.o]\nshape=rect\nposition=-10;-10\nsize=42;100\ndepth-mm=2\n", NULL);
  g_autoptr (DsImage) k1 = gaussian_kernel (5, 1.5, 0.2);
  g_autoptr (DsRenderer) r2 = ds_renderer_new_with_kernels (s2, k1, NULL, NULL, &error);
  g_assert_no_error (error);
  g_autoptr (DsImage) t2 = NULL;
  g_autoptr (DsImage) sc2 = NULL;
  truth (r2, &t2, &sc2);
  g_assert_cmpfloat (fabs (px (sc2, 10, 20)), <, 1e-6);
  g_assert_cmpfloat (fabs (px (sc2, 55, 20) - 0.2 * open_dn ()), <, 1e-3 * open_dn ());
  /* A scene with an object inside the medium needs the chain: one kernel is refused, and so are
   * kernels made for another depth. */
  g_autoptr (DsRenderer) r3 = ds_renderer_new_with_kernels (s, k1, NULL, NULL, &error);
  g_assert_null (r3);
  g_assert_error (error, DS_SIM_ERROR, DS_SIM_ERROR_INVALID);
  g_clear_error (&error);
  k->planes.depth_mm[0] = 1.5;
  g_autoptr (DsRenderer) r4 = ds_renderer_new_with_slab_kernels (s, k, &error);
  g_assert_null (r4);
  g_assert_error (error, DS_SIM_ERROR, DS_SIM_ERROR_INVALID);
}

/* First harmonic at period P of row y of an image (columns 0 .. whole periods), relative to the row's mean. */
static double
harmonic (const DsImage *im, guint y, double period)
{
  guint n = (guint) (floor (im->width / period) * period);
  double re = 0, imag = 0, mean = 0;
  for (guint x = 0; x < n; x++) {
    double v = px (im, x, y);
    re += v * cos (2 * G_PI * x / period);
    imag += v * sin (2 * G_PI * x / period);
    mean += v;
  }
  return 2 * hypot (re, imag) / mean;
}

static void
test_modulated_fraction (void)
{
  /* The share of scattered light that keeps the stripes is the kernel's MTF at 1/period: for a
   * Gaussian of sigma 3 px at P = 8, exp(-2 pi^2 sigma^2 / P^2) = 0.0623. The renderer reports
   * it, and the frames show it: the scattered light's first harmonic over its mean is that times
   * the incident light's. */
  g_autoptr (DsScene) s = scene_from ("[medium]\nthickness-mm=1\nmua=0.05\nmus=1\n", NULL);
  g_autoptr (DsImage) kernel = gaussian_kernel (20, 3, 0.3);
  g_autoptr (DsImage) none = gaussian_kernel (20, 3, 0);
  g_autoptr (GError) error = NULL;
  g_autoptr (DsRenderer) r = ds_renderer_new_with_kernels (s, kernel, NULL, NULL, &error);
  g_autoptr (DsRenderer) r0 = ds_renderer_new_with_kernels (s, none, NULL, NULL, &error);
  g_assert_no_error (error);
  DsRendererScattering info;
  g_assert_true (ds_renderer_scattering (r, &info));
  double mtf = exp (-2 * G_PI * G_PI * 9.0 / 64.0);
  g_assert_cmpfloat (fabs (info.modulated - mtf), <, 1e-3);
  g_assert_cmpfloat (info.modulated_noise, ==, 0); /* a given kernel, no Monte Carlo */
  g_assert_cmpuint (info.kernel_radius_px, ==, 20);
  g_assert_cmpfloat (fabs (info.ballistic - exp (-1.05)), <, 1e-9);
  DsRenderRequest req = { .phase = 1, .n_phases = 4, .illuminator_on = TRUE, .exposure_us = EXPOSURE_US };
  g_autoptr (DsImage) with = ds_renderer_render_photons (r, &req, &error);
  g_autoptr (DsImage) direct = ds_renderer_render_photons (r0, &req, &error);
  g_assert_no_error (error);
  for (guint y = 0; y < with->height; y++)
    for (guint x = 0; x < with->width; x++)
      ((float *) ds_image_row (with, y))[x] -= px (direct, x, y);
  double got = harmonic (with, 7, 8) / harmonic (direct, 7, 8);
  g_test_message ("modulated share of the scattered light: frames %.4f, renderer %.4f, closed form %.4f", got,
                  info.modulated, mtf);
  g_assert_cmpfloat (fabs (got - mtf), <, 2e-3);
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  g_test_add_func ("/sim/renderer/truth-consistent", test_truth_consistent);
  g_test_add_func ("/sim/renderer/sine-pattern", test_sine_pattern);
  g_test_add_func ("/sim/renderer/clear-object-changes-nothing", test_clear_object_changes_nothing);
  g_test_add_func ("/sim/renderer/plane-chain", test_plane_chain);
  g_test_add_func ("/sim/renderer/monte-carlo-kernel", test_monte_carlo_kernel);
  g_test_add_func ("/sim/renderer/modulated-fraction", test_modulated_fraction);
  return g_test_run ();
}
