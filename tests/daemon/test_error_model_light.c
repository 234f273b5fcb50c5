/* The error model's light against independent expectations: the dark frame's own shot noise
 * (ambient light, dark current) scales with the exposure, the scattered stripes ride on the
 * scattered light (no light is negative), and a configuration with no pixel left to separate is
 * refused with the reason, never predicted as +inf or from a few noisy pixels. */
#include <math.h>
#include <string.h>

#include "daemon/operating/error_model.h"
#include "daemon/operating/scene_probe.h"

/* A frame of constant light `level` (DN) with Poisson-like noise of variance read^2 + gain level,
 * drawn with Box-Muller here (not the error model's generator). */
static DsImage *
flat_frame (double level, double read_dn, double gain, GRand *r)
{
  const guint w = 240, h = 120;
  DsImage *f = ds_image_new (DS_SAMPLE_F32, w, h, NULL);
  double sd = sqrt (read_dn * read_dn + gain * level);
  for (guint y = 0; y < h; y++) {
    float *row = ds_image_row (f, y);
    for (guint x = 0; x < w; x++) {
      double u1 = 1 - g_rand_double (r), u2 = g_rand_double (r);
      row[x] = (float) (level + sd * sqrt (-2 * log (u1)) * cos (2 * G_PI * u2));
    }
  }
  return f;
}

/* Sharp square stripes of period P, duty 1/2, phase `shift`, over an ambient level: Ld on the lit
 * half, Lg m everywhere, ambient everywhere (it is in the dark frame too). */
static DsImage *
stripe_frame (double P, double shift, double ld, double lg, double ambient, double read_dn, double gain, GRand *r)
{
  const guint w = 240, h = 120;
  DsImage *f = ds_image_new (DS_SAMPLE_F32, w, h, NULL);
  for (guint y = 0; y < h; y++) {
    float *row = ds_image_row (f, y);
    for (guint x = 0; x < w; x++) {
      double lit = 0;
      for (int i = 0; i < 100; i++) { /* pixel-integrated */
        double u = (x - 0.5 + (i + 0.5) / 100) / P - shift;
        u -= floor (u);
        lit += u < 0.5;
      }
      double v = ambient + ld * lit / 100 + lg * 0.5;
      double sd = sqrt (read_dn * read_dn + gain * v);
      double u1 = 1 - g_rand_double (r), u2 = g_rand_double (r);
      row[x] = (float) (v + sd * sqrt (-2 * log (u1)) * cos (2 * G_PI * u2));
    }
  }
  return f;
}

/* The probe tells the dark frame's shot noise (gain x its level) from the read noise: 300 DN of
 * ambient light at 0.25 DN^2/DN is 75 DN^2 of a dark frame's 76. */
static void
test_probe_dark_shot_noise (void)
{
  const double read_dn = 1.0, gain = 0.25, P = 12;
  for (int with_ambient = 0; with_ambient < 2; with_ambient++) {
    double ambient = with_ambient ? 300 : 0;
    g_autoptr (GRand) r = g_rand_new_with_seed (11);
    g_autoptr (DsImage) dark = flat_frame (ambient, read_dn, gain, r);
    g_autoptr (DsImage) l0 = stripe_frame (P, 0.1, 1000, 200, ambient, read_dn, gain, r);
    g_autoptr (DsImage) l1 = stripe_frame (P, 0.6, 1000, 200, ambient, read_dn, gain, r);
    DsProbeFrames fr = { .dark = dark, .lit = { l0, l1 }, .coarse_missing = "fixed by the test", .exposure_us = 1000,
                         .geometry = { DS_PATTERN_SQUARE, P, 0.5, 0, 0 }, .blur_known = TRUE };
    DsSceneProbe p;
    g_autoptr (GError) error = NULL;
    g_assert_true (ds_scene_probe_measure (&fr, &p, &error));
    g_assert_no_error (error);
    double shot = gain * ambient, var0 = read_dn * read_dn + shot;
    g_assert_cmpfloat_with_epsilon (p.noise.var0, var0, 0.1 * var0);
    g_assert_cmpfloat_with_epsilon (p.noise.gain, gain, 0.03);
    if (with_ambient)
      g_assert_cmpfloat_with_epsilon (p.noise.dark_shot, shot, 0.1 * shot);
    else
      g_assert_cmpfloat (p.noise.dark_shot, <, 0.5);
    g_assert_cmpfloat (p.noise.dark_shot, <=, p.noise.var0);
  }
}

/* A probe of a 256 x 192 scene under sharp square stripes of duty 1/2 and period P, the blur
 * calibrated, at 1000 µs, Ld uniform and the scattered stripes measured; each test sets the rest. */
static DsSceneProbe
square_probe (double period, double ld)
{
  DsSceneProbe p = { 0 };
  p.geometry = (DsStripeModel){ DS_PATTERN_SQUARE, period, 0.5, 0, 0, 0 };
  p.blur.source = DS_BLUR_CALIBRATED;
  p.exposure_us = 1000;
  p.light.ld_mean = ld;
  p.light.ld_spread = 1;
  p.leak.measured = TRUE;
  p.width = 256;
  p.height = 192;
  return p;
}

/* The separation's parameters for those stripes (N = 4; predict () takes its own N). */
static DsSeparationParams
square_params (void)
{
  DsSeparationParams sp;
  ds_separation_params_init (&sp, 4);
  sp.pattern = DS_PATTERN_SQUARE;
  sp.duty = 0.5;
  return sp;
}

/* The error model at a quarter of the pilot's exposure: sine's noise on sharp square stripes is
 * sqrt (2 var / (M N h^2)) / Ld (docs/estimators.md) with var = read^2 + S f, the dark frame's
 * shot noise S scaled by the exposure factor f and the read noise not; sine's Ld does not see
 * the dark frame (a constant). Counted as read noise, S would stay whole: here 100 DN^2 against
 * 25.75, twice the noise. */
static void
test_error_model_dark_shot_noise (void)
{
  const double ld = 500, read_var = 1, S = 99, f = 0.25;
  DsSceneProbe p = square_probe (16, ld);
  p.light.lg_mean = 1000;
  p.noise.var0 = read_var + S;
  p.noise.dark_shot = S;
  p.noise.gain = 0;
  DsSeparationParams sp = square_params ();
  g_autoptr (DsErrorModel) m = ds_error_model_new (&p, &sp);
  DsErrorParts parts;
  g_autoptr (GError) error = NULL;
  const guint N = 16, M = 4;
  double h = 2 / G_PI * sin (G_PI / N) / (G_PI / N);
  for (int i = 0; i < 2; i++) {
    double factor = i ? f : 1;
    g_assert_true (ds_error_model_predict (m, DS_ESTIMATOR_SINE, N, M, factor, 0, &parts, &error));
    double var = read_var + S * factor;
    double expect = sqrt (2 * var / (M * N * h * h)) / (factor * ld);
    g_test_message ("factor %g: noise %.5f, closed form %.5f", factor, parts.noise, expect);
    g_assert_cmpfloat_with_epsilon (parts.noise, expect, 0.1 * expect);
  }
}

/* A leak read on a scene whose mean shows no scattered light (Lg 0, as gen-3-01's 1.9 % at P):
 * the scattered stripes' troughs would be negative light, below the dark frame at every lit
 * pixel, and the noise-free error was +inf. With the stripes riding on the scattered light they
 * need, every part is finite, and maxmin's systematic error (N = P: every pixel sees its lit and
 * its dark phase) is max - min of the pattern with its leak against 1, computed here by brute
 * force from the square wave's Fourier series, not with the model's table. */
static void
test_error_model_leak_on_no_scattered_light (void)
{
  const double P = 12, ld = 1000, alpha = log (1.03) / P; /* 3 % of the first harmonic at P */
  DsSceneProbe p = square_probe (P, ld);
  p.light.lg_mean = 0;
  p.leak.per_px = alpha;
  DsSeparationParams sp = square_params ();
  sp.geometry.period_px = P;
  sp.geometry.pixel_aperture = 1;
  g_autoptr (DsErrorModel) m = ds_error_model_new (&p, &sp);
  DsErrorParts parts;
  g_autoptr (GError) error = NULL;
  g_assert_true (ds_error_model_predict (m, DS_ESTIMATOR_MAXMIN, 12, 1, 1, 0, &parts, &error));
  g_assert_no_error (error);
  g_assert_true (isfinite (parts.total) && isfinite (parts.systematic) && isfinite (parts.sampling) &&
                 isfinite (parts.scattered_stripes));
  /* Brute force: per pixel x, the pixel-integrated sharp pattern plus the leak's odd harmonics
   * (exp (alpha P / n) - 1 times the pattern's own), max - min over the 12 phases against 1. */
  double se = 0;
  for (guint x = 0; x < 256; x++) {
    double hi = -INFINITY, lo = INFINITY;
    for (guint k = 0; k < 12; k++) {
      double v = 0.5;
      for (guint n = 1; n < 200; n += 2) {
        double c = 2 / (n * G_PI) * sin (n * G_PI / 2) * sin (G_PI * n / P) / (G_PI * n / P);
        double l = n <= 15 ? exp (alpha * P / n) : 1; /* the model carries 15 harmonics of the leak */
        v += c * l * cos (2 * G_PI * n * (x / P - k / 12.0 - p.phase_offset));
      }
      hi = MAX (hi, v);
      lo = MIN (lo, v);
    }
    se += (hi - lo - 1) * (hi - lo - 1);
  }
  double expect = sqrt (se / 256);
  g_test_message ("maxmin N = 12 with a 3 %% leak and Lg 0: systematic %.5f, brute force %.5f", parts.systematic, expect);
  g_assert_cmpfloat (expect, >, 0.01);
  g_assert_cmpfloat_with_epsilon (parts.systematic, expect, 0.1 * expect);
}

/* Every lit pixel clipped at an exposure, with the sets flagging the clip level: no pixel is left,
 * and the configuration is refused with a reason naming the clip, not predicted. */
static void
test_error_model_nothing_left (void)
{
  DsSceneProbe p = square_probe (12, 1000);
  p.noise.var0 = 4;
  p.noise.gain = 0.25;
  p.clip.saturation_dn = 1500;
  p.clip.bright_dn = 1000;
  p.clip.flagged = TRUE;
  DsSeparationParams sp = square_params ();
  g_autoptr (DsErrorModel) m = ds_error_model_new (&p, &sp);
  DsErrorParts parts;
  g_autoptr (GError) error = NULL;
  for (guint n = 3; n <= 12; n += 9) {
    g_assert_false (ds_error_model_predict (m, DS_ESTIMATOR_ROBUST, n, 1, 2, 0, &parts, &error));
    g_assert_nonnull (error);
    g_test_message ("%s", error->message);
    g_assert_nonnull (strstr (error->message, "clip"));
    g_clear_error (&error);
  }
  /* At the pilot's exposure nothing clips: a finite prediction. */
  g_assert_true (ds_error_model_predict (m, DS_ESTIMATOR_ROBUST, 12, 1, 1, 0, &parts, &error));
  g_assert_true (isfinite (parts.total));
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  g_test_add_func ("/error-model-light/probe-dark-shot-noise", test_probe_dark_shot_noise);
  g_test_add_func ("/error-model-light/dark-shot-noise", test_error_model_dark_shot_noise);
  g_test_add_func ("/error-model-light/leak-on-no-scattered-light", test_error_model_leak_on_no_scattered_light);
  g_test_add_func ("/error-model-light/nothing-left", test_error_model_nothing_left);
  return g_test_run ();
}
