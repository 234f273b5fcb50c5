/* The pieces of the automatic operating point against independent expectations: the stripe
 * pattern against brute-force integration, the harmonic fit against a known series, the probe
 * against synthetic frames of known Ld, Lg, noise and leak, the error model against the closed
 * forms of docs/estimators.md (order statistics, the sine estimator's variance) and against a
 * brute-force count of maxmin's precondition aN >= 1. */
#include <math.h>
#include <string.h>

#include "daemon/operating/error_model.h"
#include "daemon/operating/operating_point.h"
#include "daemon/operating/scene_probe.h"
#include "daemon/operating/stripe_model.h"

/* The blurred square stripe at pixel x, by brute force: the pixel's aperture w (1 when 0)
 * sampled at 2000 points, each the lit fraction of the Gaussian-blurred indicator computed with
 * erf. */
static double
brute_value (const DsStripeModel *g, double x, double shift)
{
  const int sub = 2000;
  double acc = 0, P = g->period_px, half = g->duty * P / 2, w = g->pixel_aperture > 0 ? g->pixel_aperture : 1;
  for (int i = 0; i < sub; i++) {
    double t = x - w / 2 + w * (i + 0.5) / sub, v = 0;
    for (int j = -3; j <= 3; j++) {
      double c = P * (floor (t / P - shift) + j + shift);
      if (g->blur_px > 0)
        v += 0.5 * (erf ((t - c + half) / (G_SQRT2 * g->blur_px)) - erf ((t - c - half) / (G_SQRT2 * g->blur_px)));
      else
        v += fabs (t - c) < half;
    }
    acc += v;
  }
  return g->black_level + (1 - g->black_level) * acc / sub;
}

static void
test_stripe_value (void)
{
  DsStripeModel g = { DS_PATTERN_SQUARE, 7.3, 0.35, 0.05, 0.0, 0 };
  for (int b = 0; b < 2; b++)
    for (int a = 0; a < 3; a++) {
      g.blur_px = b ? 0.8 : 0.0;
      g.pixel_aperture = a == 0 ? 0 : a == 1 ? 0.4 : DS_STRIPE_POINT_APERTURE;
      for (double x = 0; x < 15; x += 1)
        for (double s = 0; s < 1; s += 0.37)
          g_assert_cmpfloat_with_epsilon (ds_stripe_value (&g, x, s), brute_value (&g, x, s), 2e-3);
    }
  g.pixel_aperture = 0;
  /* The harmonic coefficient is the DFT of the pixel values over many columns of a period
   * that is not a divisor (every phase position is visited). */
  g.blur_px = 0.6;
  for (guint n = 1; n <= 3; n++) {
    double c = 0, s = 0;
    const guint cols = 7300;
    for (guint x = 0; x < cols; x++) {
      double v = ds_stripe_value (&g, x, 0);
      c += v * cos (2 * G_PI * n * x / g.period_px);
      s += v * sin (2 * G_PI * n * x / g.period_px);
    }
    g_assert_cmpfloat_with_epsilon (2 * hypot (c, s) / cols, fabs (ds_stripe_harmonic (&g, n)), 2e-3);
  }
  /* A pixel of half the pitch (closed form: sinc (w n / P)), and one sampling the centre. */
  for (guint n = 1; n <= 3; n++) {
    DsStripeModel whole = g, half = g, point = g;
    half.pixel_aperture = 0.5;
    point.pixel_aperture = DS_STRIPE_POINT_APERTURE;
    double f = n / g.period_px;
    g_assert_cmpfloat_with_epsilon (ds_stripe_harmonic (&half, n) / ds_stripe_harmonic (&whole, n),
                                    sin (G_PI * 0.5 * f) / (G_PI * 0.5 * f) / (sin (G_PI * f) / (G_PI * f)), 1e-9);
    g_assert_cmpfloat_with_epsilon (ds_stripe_harmonic (&point, n) / ds_stripe_harmonic (&whole, n),
                                    1 / (sin (G_PI * f) / (G_PI * f)), 1e-6);
  }
  /* The blur that gives a harmonic gain is the one that had it. */
  double h = ds_stripe_harmonic (&g, 1);
  g.blur_px = 0;
  g_assert_cmpfloat_with_epsilon (ds_stripe_blur_from_gain (&g, h), 0.6, 1e-6);

  /* A calibrated gain gives blur and aperture (ds_stripe_match_gain). Below the sharp whole
   * pixel's: that blur on the whole pixel. A sine as the simulator draws it, (1 - b)/2 sampled at
   * the pixel centre, is above it (by 1/sinc (1/P)): no blur and a point aperture, and the model's
   * first harmonic is the calibrated gain at every period (gen-14-04: the model integrated the
   * whole pixel, 1.9 % below it at 9.25 px). A pixel of half the pitch: aperture 0.5. */
  DsStripeModel m = g;
  m.pixel_aperture = 0.3;
  g_assert_true (ds_stripe_match_gain (&m, h));
  g_assert_cmpfloat_with_epsilon (m.blur_px, 0.6, 1e-6);
  g_assert_cmpfloat (m.pixel_aperture, ==, 0);
  DsStripeModel sine = { DS_PATTERN_SINE, 9.25, 0.5, 0.04, 0.3, 0 };
  g_assert_true (ds_stripe_match_gain (&sine, (1 - 0.04) / 2));
  g_assert_cmpfloat (sine.blur_px, ==, 0);
  g_assert_cmpfloat (sine.pixel_aperture, <=, DS_STRIPE_POINT_APERTURE);
  for (double q = 18.5; q > 4; q /= 2) {
    sine.period_px = q;
    g_assert_cmpfloat_with_epsilon (ds_stripe_harmonic (&sine, 1), (1 - 0.04) / 2, 1e-6);
  }
  sine.period_px = 9.25;
  double half_pixel = (1 - 0.04) / 2 * sin (G_PI * 0.5 / 9.25) / (G_PI * 0.5 / 9.25);
  g_assert_true (ds_stripe_match_gain (&sine, half_pixel));
  g_assert_cmpfloat (sine.blur_px, ==, 0);
  g_assert_cmpfloat_with_epsilon (sine.pixel_aperture, 0.5, 1e-6);
  g_assert_false (ds_stripe_match_gain (&sine, 0));
  g_assert_false (ds_stripe_match_gain (&sine, 1e-6));
  g_assert_cmpfloat (sine.blur_px, ==, 9.25 / 2);
}

static void
test_harmonics_fit (void)
{
  const guint w = 200;
  const double P = 9.5;
  double profile[200];
  for (guint x = 0; x < w; x++)
    profile[x] = 40 + 10 * cos (2 * G_PI * (x / P - 0.2)) + 3 * cos (2 * G_PI * 3 * (x / P - 0.1));
  DsStripeHarmonics h;
  g_autoptr (GError) error = NULL;
  g_assert_true (ds_stripe_harmonics_fit (profile, NULL, 0, w, P, 4, &h, &error));
  g_assert_cmpuint (h.n_harmonics, ==, 4);
  g_assert_cmpfloat_with_epsilon (h.mean, 40, 1e-9);
  g_assert_cmpfloat_with_epsilon (h.amplitude[1], 10, 1e-9);
  g_assert_cmpfloat_with_epsilon (h.phase[1], 0.2, 1e-9);
  g_assert_cmpfloat_with_epsilon (h.amplitude[2], 0, 1e-9);
  g_assert_cmpfloat_with_epsilon (h.amplitude[3], 3, 1e-9);
  g_assert_cmpfloat_with_epsilon (fmod (h.phase[3], 1.0 / 3), 0.1, 1e-9);
  /* Above Nyquist nothing is fitted; too few columns is an error naming them. */
  g_assert_true (ds_stripe_harmonics_fit (profile, NULL, 0, w, 5.0, 4, &h, &error));
  g_assert_cmpuint (h.n_harmonics, ==, 2);
  g_assert_false (ds_stripe_harmonics_fit (profile, NULL, 0, 4, P, 1, &h, &error));
  g_assert_nonnull (strstr (error->message, "columns"));
}

/* ---- synthetic pilot frames ---- */

typedef struct {
  DsStripeModel g;
  double ld, lg, dark;     /* DN */
  double read_dn, gain;    /* noise: read sigma, shot variance per DN */
  double leak_per_px;      /* the scattered light's transfer of a harmonic of period x: exp(a x) - 1 */
  double blocked;          /* fraction of the rows with Ld = 0 (an object) */
  double bright, ld_bright; /* fraction of the rows (the last ones) with Ld = ld_bright instead */
  double blocked_columns;  /* fraction of every 37 columns with Ld = 0 (bars spanning the rows) */
} Synth;

/* Frame of phase `shift` at `period`: the pattern's Fourier series (independent of
 * ds_stripe_value) with each harmonic's amplitude raised by the leak, plus noise. */
static DsImage *
synth_frame (const Synth *s, double period, double shift, gboolean on, GRand *r)
{
  const guint w = 240, h = 120;
  DsImage *f = ds_image_new (DS_SAMPLE_F32, w, h, NULL);
  DsStripeModel g = s->g;
  g.period_px = period;
  double m = g.duty + g.black_level * (1 - g.duty);
  double pattern[240];
  for (guint x = 0; x < w; x++) {
    double p = m;
    for (guint n = 1; n < 400; n++) {
      double c = (1 - g.black_level) * 2 / (n * G_PI) * sin (n * G_PI * g.duty) *
                 exp (-2 * G_PI * G_PI * g.blur_px * g.blur_px * n * n / (period * period)) *
                 sin (G_PI * n / period) / (G_PI * n / period);
      p += c * exp (s->leak_per_px * period / n) * cos (2 * G_PI * n * (x / period - shift));
    }
    pattern[x] = p;
  }
  for (guint y = 0; y < h; y++) {
    float *row = ds_image_row (f, y);
    double ld_row = y < s->blocked * h ? 0 : y >= (1 - s->bright) * h ? s->ld_bright : s->ld;
    for (guint x = 0; x < w; x++) {
      double ld = x % 37 < s->blocked_columns * 37 ? 0 : ld_row;
      /* The scattered light's own stripes are the leak above; its mean is Lg m. */
      double v = on ? ld * pattern[x] + s->lg * m : 0;
      double var = s->read_dn * s->read_dn + s->gain * v;
      double u1 = 1 - g_rand_double (r), u2 = g_rand_double (r);
      row[x] = (float) (s->dark + v + sqrt (var) * sqrt (-2 * log (u1)) * cos (2 * G_PI * u2));
    }
  }
  return f;
}

static void
probe_synth (const Synth *s, gboolean two_periods, double calibrated_gain, DsSceneProbe *p)
{
  g_autoptr (GRand) r = g_rand_new_with_seed (7);
  g_autoptr (DsImage) dark = synth_frame (s, s->g.period_px, 0, FALSE, r);
  g_autoptr (DsImage) l0 = synth_frame (s, s->g.period_px, 0.1, TRUE, r);
  g_autoptr (DsImage) l1 = synth_frame (s, s->g.period_px, 0.6, TRUE, r);
  g_autoptr (DsImage) c0 = two_periods ? synth_frame (s, 2 * s->g.period_px, 0.1, TRUE, r) : NULL;
  g_autoptr (DsImage) c1 = two_periods ? synth_frame (s, 2 * s->g.period_px, 0.6, TRUE, r) : NULL;
  DsStripeModel g = s->g;
  g.blur_px = 0;
  DsProbeFrames fr = { .dark = dark, .lit = { l0, l1 }, .coarse = { c0, c1 },
                       .coarse_missing = "fixed by the test", .exposure_us = 1000, .geometry = g,
                       .calibrated_gain = calibrated_gain };
  g_autoptr (GError) error = NULL;
  g_assert_true (ds_scene_probe_measure (&fr, p, &error));
  g_assert_no_error (error);
}

/* Ld, Lg, the noise model and the spread of Ld from two phases; without scattered stripes. */
static void
test_probe_plain (void)
{
  Synth s = { { DS_PATTERN_SQUARE, 10, 0.5, 0, 0.4, 0 }, 800, 1200, 50, 3.0, 0.25, 0, 0.25, 0, 0, 0 };
  DsSceneProbe p;
  probe_synth (&s, TRUE, 0, &p);
  double ld_mean = s.ld * (1 - s.blocked);
  g_assert_cmpfloat_with_epsilon (p.light.ld_mean, ld_mean, 0.02 * ld_mean);
  g_assert_cmpfloat_with_epsilon (p.light.lg_mean, s.lg, 0.02 * s.lg);
  g_assert_cmpfloat_with_epsilon (p.noise.var0, 9.0, 0.9);
  g_assert_cmpfloat_with_epsilon (p.noise.gain, 0.25, 0.03);
  /* mean(Ld^2) / mean(Ld)^2 of a quarter blocked: 1 / 0.75 */
  g_assert_cmpfloat_with_epsilon (p.light.ld_spread, 1 / 0.75, 0.05);
  g_assert_cmpfloat_with_epsilon (p.phase_offset, 0.1, 0.01);
  g_assert_true (p.leak.measured);
  g_assert_cmpfloat (ds_scene_probe_leak (&p, 10, 1), <, 0.02);
  /* The blur, measured from the harmonics at two periods. */
  g_assert_cmpint (p.blur.source, ==, DS_BLUR_MEASURED);
  g_assert_cmpfloat_with_epsilon (p.geometry.blur_px, 0.4, 0.1);
}

/* Scattered light that keeps the stripes: the probe's extrapolation over the period recovers
 * Ld, and the leak at the period, from two periods; with one it says it cannot. */
static void
test_probe_leak (void)
{
  Synth s = { { DS_PATTERN_SQUARE, 12, 0.5, 0, 0.0, 0 }, 500, 3000, 20, 2.0, 0.25, 0.04, 0, 0, 0, 0 };
  DsSceneProbe p;
  DsStripeModel sharp = s.g;
  probe_synth (&s, TRUE, ds_stripe_harmonic (&sharp, 1), &p);
  g_assert_cmpint (p.blur.source, ==, DS_BLUR_CALIBRATED);
  g_assert_cmpfloat_with_epsilon (p.light.ld_mean, s.ld, 0.05 * s.ld);
  g_assert_cmpfloat_with_epsilon (ds_scene_probe_leak (&p, 12, 1), expm1 (0.04 * 12), 0.1 * expm1 (0.04 * 12));
  g_assert_true (p.leak.measured);
  probe_synth (&s, FALSE, ds_stripe_harmonic (&sharp, 1), &p);
  g_assert_false (p.leak.measured);
  g_assert_nonnull (strstr (p.leak.note, "fixed by the test"));
  g_assert_cmpfloat (ds_scene_probe_leak (&p, 12, 1), ==, 0);
}

/* No scattered light, blurred stripes and a calibrated blur 0.05 px short of the frames' (within
 * DS_PROBE_BLUR_UNCERTAINTY_PX): the higher harmonics, which the blur has nearly erased, then
 * arrive 4-20 % weaker than modelled, and a transfer fitted through them rises with x as
 * scattered stripes would (26 % at the period when the blur's error is not a parameter of the
 * fit). The truth is no scattered stripes at all: what is left is the noise of the harmonics the
 * blur has nearly erased (1-2 % of their amplitude), extrapolated. */
static void
test_probe_blurred_harmonics (void)
{
  Synth s = { { DS_PATTERN_SQUARE, 12, 0.4, 0, 1.2, 0 }, 2000, 300, 20, 2.0, 0.25, 0, 0, 0, 0, 0 };
  g_autoptr (GRand) r = g_rand_new_with_seed (11);
  g_autoptr (DsImage) dark = synth_frame (&s, 12, 0, FALSE, r);
  g_autoptr (DsImage) l0 = synth_frame (&s, 12, 0.1, TRUE, r);
  g_autoptr (DsImage) l1 = synth_frame (&s, 12, 0.6, TRUE, r);
  g_autoptr (DsImage) c0 = synth_frame (&s, 24, 0.1, TRUE, r);
  g_autoptr (DsImage) c1 = synth_frame (&s, 24, 0.6, TRUE, r);
  DsStripeModel g = s.g;
  g.blur_px = 0;
  DsProbeFrames fr = { .dark = dark, .lit = { l0, l1 }, .coarse = { c0, c1 }, .exposure_us = 1000,
                       .geometry = g, .blur_known = TRUE, .calibrated_blur_px = 1.15 };
  g_autoptr (GError) error = NULL;
  DsSceneProbe p;
  g_assert_true (ds_scene_probe_measure (&fr, &p, &error));
  g_assert_no_error (error);
  g_assert_true (p.leak.measured);
  g_assert_cmpfloat (ds_scene_probe_leak (&p, 12, 1), <, 0.04);
  /* Ld is the same line's intercept: off by as much, the other way. */
  g_assert_cmpfloat_with_epsilon (p.light.ld_mean, s.ld, 0.04 * s.ld);
}

/* The clip level: a full well below the pixel format's top shows as a pile-up in the pilot frames
 * (then known, but not flagged by the sets, which know the format's top); a configured one is
 * known and flagged; without either no exposure above the pilot's is allowed. A calibrated edge
 * blur is taken as it is. */
static void
test_probe_clip_level (void)
{
  Synth s = { { DS_PATTERN_SQUARE, 10, 0.5, 0, 0.0, 0 }, 800, 300, 50, 3.0, 0.25, 0, 0.25, 0, 0, 0 };
  g_autoptr (GRand) r = g_rand_new_with_seed (11);
  DsImage *raw[3] = { synth_frame (&s, 10, 0, FALSE, r), synth_frame (&s, 10, 0.1, TRUE, r),
                      synth_frame (&s, 10, 0.6, TRUE, r) };
  for (int clipped = 0; clipped < 2; clipped++) {
    /* 12-bit frames; clipped: a full well at 1010 DN, within the lit stripes' noise (1000 +- 16
     * DN): a third of their samples pile up there. */
    DsImage *f[3];
    for (int i = 0; i < 3; i++) {
      f[i] = ds_image_convert_f32_clamped (raw[i], DS_SAMPLE_U16, clipped ? 1010 : 4095, NULL);
      f[i]->bit_depth = 12;
    }
    DsProbeFrames fr = { .dark = f[0], .lit = { f[1], f[2] }, .coarse_missing = "fixed by the test",
                         .exposure_us = 1000, .saturation_dn = 4095, .geometry = s.g,
                         .blur_known = TRUE, .calibrated_blur_px = 0.7 };
    DsSceneProbe p;
    g_autoptr (GError) error = NULL;
    gboolean measured = ds_scene_probe_measure (&fr, &p, &error);
    g_assert_no_error (error);
    g_assert_true (measured);
    g_assert_cmpint (p.blur.source, ==, DS_BLUR_CALIBRATED);
    g_assert_cmpfloat (p.geometry.blur_px, ==, 0.7);
    if (clipped) {
      g_assert_cmpfloat (p.clip.saturation_dn, ==, 1010);
      g_assert_true (p.clip.known);
      g_assert_false (p.clip.flagged);
    } else {
      g_assert_cmpfloat (p.clip.saturation_dn, ==, 4095);
      g_assert_false (p.clip.known);
      /* Unknown full well: the pilot's exposure is the longest allowed, though 4095 DN is far. */
      g_assert_cmpfloat (ds_scene_probe_max_exposure (&p), ==, 1000);
      /* Configured: known and flagged; 90 % of it over the brightest pixels. */
      fr.saturation_dn = 3000;
      fr.saturation_known = TRUE;
      g_assert_true (ds_scene_probe_measure (&fr, &p, &error));
      g_assert_true (p.clip.known && p.clip.flagged);
      g_assert_cmpfloat_with_epsilon (ds_scene_probe_max_exposure (&p), 1000 * (0.9 * 3000 - p.noise.dark_dn) / p.clip.bright_dn,
                                      1e-9);
      g_assert_cmpfloat (ds_scene_probe_max_exposure (&p), >, 2000);
    }
    for (int i = 0; i < 3; i++)
      ds_image_free (f[i]);
  }
  for (int i = 0; i < 3; i++)
    ds_image_free (raw[i]);
}

/* A sensor with little read noise (0.2 DN: the dark frame alone cannot tell noise from a flat
 * field) that clips at a full well of 1030 DN (2 sigma above the lit stripes): the lit frames' shot noise shows the pile-up,
 * and the shot noise is then measured on the unclipped pixels (gain 0.25 DN^2/DN, not the
 * fraction left when the clipped pixels' zero differences count). A noise-free frame's flat
 * top is no clip. */
static void
test_probe_clip_quiet_sensor (void)
{
  for (int noisy = 0; noisy < 2; noisy++) {
    Synth s = { { DS_PATTERN_SQUARE, 10, 0.5, 0, 0.0, 0 }, 800, 300, 50, noisy ? 0.2 : 0.0, noisy ? 0.25 : 0.0, 0, 0.25, 0, 0, 0 };
    g_autoptr (GRand) r = g_rand_new_with_seed (13);
    DsImage *f[3];
    for (int i = 0; i < 3; i++) {
      g_autoptr (DsImage) raw = synth_frame (&s, 10, i == 2 ? 0.6 : 0.1, i > 0, r);
      f[i] = ds_image_convert_f32_clamped (raw, DS_SAMPLE_U16, noisy ? 1030 : 1100, NULL);
      f[i]->bit_depth = 12;
    }
    DsProbeFrames fr = { .dark = f[0], .lit = { f[1], f[2] }, .coarse_missing = "fixed by the test",
                         .exposure_us = 1000, .saturation_dn = 4095, .geometry = s.g };
    DsSceneProbe p;
    g_autoptr (GError) error = NULL;
    g_assert_true (ds_scene_probe_measure (&fr, &p, &error));
    g_assert_no_error (error);
    g_assert_cmpfloat (p.noise.var0, <, 0.25);
    if (noisy) {
      g_assert_cmpfloat (p.clip.saturation_dn, ==, 1030);
      g_assert_true (p.clip.known);
      g_assert_cmpfloat_with_epsilon (p.noise.gain, 0.25, 0.05);
    } else {
      g_assert_cmpfloat (p.clip.saturation_dn, ==, 4095);
      g_assert_false (p.clip.known);
    }
    for (int i = 0; i < 3; i++)
      ds_image_free (f[i]);
  }
}

/* Places whose stripes' peaks pass the clip level (a full well the pilot reaches) on a third of
 * the scene, a quarter blocked, the rest dim. Leaving out only the clipped samples keeps the
 * bright places between the stripes' peaks and the dim ones at them: the difference profile's
 * first harmonic then reads Ld at a fraction, and the brightest places, which weigh most in a
 * relative error, are missing from Ld, its spread and Lg. The scene's own figures are the
 * expectation; the bright places' Ld can only be known to be at least what reaches the clip
 * level (the frames do not say by how much their peaks pass it: here by 4 %). */
static void
test_probe_clipped_places (void)
{
  for (int two = 0; two < 2; two++) {
    Synth s = { { DS_PATTERN_SQUARE, 10, 0.5, 0.1, 0.0, 0 }, 500, 200, 50, 3.0, 0.25, 0, 0.25, 0.35, 1300, 0 };
    const double m = 0.5 + 0.1 * 0.5, clip = 1400;
    g_assert_cmpfloat (s.dark + s.ld_bright + m * s.lg, >, clip);
    g_autoptr (GRand) r = g_rand_new_with_seed (17);
    DsImage *f[5] = { NULL };
    const double period[5] = { 10, 10, 10, 20, 20 }, shift[5] = { 0, 0.1, 0.6, 0.1, 0.6 };
    for (int i = 0; i < (two ? 5 : 3); i++) {
      g_autoptr (DsImage) raw = synth_frame (&s, period[i], shift[i], i > 0, r);
      f[i] = ds_image_convert_f32_clamped (raw, DS_SAMPLE_U16, clip, NULL);
      f[i]->bit_depth = 12;
    }
    DsProbeFrames fr = { .dark = f[0], .lit = { f[1], f[2] }, .coarse = { f[3], f[4] },
                         .coarse_missing = "fixed by the test", .exposure_us = 1000, .saturation_dn = clip,
                         .saturation_known = TRUE, .geometry = s.g, .blur_known = TRUE };
    DsSceneProbe p;
    g_autoptr (GError) error = NULL;
    g_assert_true (ds_scene_probe_measure (&fr, &p, &error));
    g_assert_no_error (error);
    double dim = 1 - s.blocked - s.bright;
    double ld_mean = dim * s.ld + s.bright * s.ld_bright;
    double spread = (dim * s.ld * s.ld + s.bright * s.ld_bright * s.ld_bright) / (ld_mean * ld_mean);
    g_test_message ("%s: Ld %.1f (scene %.1f), Lg %.1f (%.1f), spread %.3f (%.3f), scattered stripes %.4f",
                    two ? "two periods" : "one period", p.light.ld_mean, ld_mean, p.light.lg_mean, s.lg, p.light.ld_spread,
                    spread, ds_scene_probe_leak (&p, 10, 1));
    /* Every pixel of the bright rows clips in one of the two phases (duty 0.5). */
    g_assert_cmpfloat_with_epsilon (p.clip.saturated_fraction, s.bright, 0.03);
    g_assert_cmpfloat (p.light.ld_mean, <, 1.01 * ld_mean);
    g_assert_cmpfloat (p.light.ld_mean, >, 0.95 * ld_mean);
    g_assert_cmpfloat_with_epsilon (p.light.lg_mean, s.lg, 0.15 * s.lg);
    g_assert_cmpfloat_with_epsilon (p.light.ld_spread, spread, 0.08 * spread);
    g_assert_cmpfloat_with_epsilon (p.noise.gain, 0.25, 0.05);
    /* One population at both periods: no scattered stripes read into the difference. */
    g_assert_cmpfloat (ds_scene_probe_leak (&p, 10, 1), <, 0.02);
    for (int i = 0; i < 5; i++)
      g_clear_pointer (&f[i], ds_image_free);
  }
}

/* The spread of Ld over the scene, mean (Ld^2) / mean (Ld)^2, when objects block rows (within
 * a column) and bars block columns (across them, which a column's statistics cannot see): the
 * scene's own figure, 1 / (the lit fraction) for Ld either 0 or one level. */
static void
test_probe_spread (void)
{
  /* Rows blocked, columns blocked, both. */
  for (guint i = 0; i < 3; i++) {
    Synth s = { { DS_PATTERN_SQUARE, 10, 0.5, 0, 0.4, 0 }, 800, 600, 50, 3.0, 0.25, 0, i == 1 ? 0 : 0.25, 0, 0,
                i == 0 ? 0 : 0.3 };
    DsSceneProbe p;
    probe_synth (&s, TRUE, 0, &p);
    guint lit_cols = 0;
    for (guint x = 0; x < 240; x++)
      lit_cols += !(x % 37 < s.blocked_columns * 37);
    double lit = (1 - s.blocked) * lit_cols / 240.0;
    g_test_message ("rows blocked %.2f, columns %.2f: spread %.3f, the scene's %.3f, Ld %.1f (%.1f)", s.blocked,
                    s.blocked_columns, p.light.ld_spread, 1 / lit, p.light.ld_mean, s.ld * lit);
    g_assert_cmpfloat_with_epsilon (p.light.ld_spread, 1 / lit, 0.05 / lit);
    g_assert_cmpfloat_with_epsilon (p.light.ld_mean, s.ld * lit, 0.03 * s.ld * lit);
  }
}

/* A probe written by hand: the error model's inputs. */
static DsSceneProbe
hand_probe (double period, double duty, double ld, double lg, double var0, double gain)
{
  DsSceneProbe p = { 0 };
  p.geometry = (DsStripeModel){ DS_PATTERN_SQUARE, period, duty, 0, 0, 0 };
  p.blur.source = DS_BLUR_CALIBRATED;
  p.exposure_us = 1000;
  p.light.ld_mean = ld;
  p.light.ld_spread = 1;
  p.light.lg_mean = lg;
  p.leak.measured = TRUE;
  p.noise.var0 = var0;
  p.noise.gain = gain;
  p.width = 256;
  p.height = 192;
  return p;
}

/* The rig's separation parameters for a hand-made probe. */
static DsSeparationParams
params_of (const DsSceneProbe *p)
{
  DsSeparationParams s;
  ds_separation_params_init (&s, 4);
  s.pattern = p->geometry.kind;
  s.duty = p->geometry.duty;
  s.black_level = p->geometry.black_level;
  return s;
}

/* maxmin's precondition: a pixel fully lit in some phase and fully dark in another. With duty
 * 0.3 at N = 3, aN = 0.9 < 1: refused when the period is unknown (proc's check, passed on), and
 * with the period known the sampling part is the rms over pixels of max - min - 1 of the
 * pixel-integrated lit fraction, computed here by brute force. */
static void
test_error_model_precondition (void)
{
  const double P = 10, a = 0.3;
  DsSceneProbe p = hand_probe (P, a, 1000, 500, 0, 0);
  DsSeparationParams sp = params_of (&p);
  DsErrorParts parts;
  g_autoptr (GError) error = NULL;
  {
    g_autoptr (DsErrorModel) blind = ds_error_model_new (&p, &sp);
    g_assert_false (ds_error_model_predict (blind, DS_ESTIMATOR_MAXMIN, 3, 1, 1, 0, &parts, &error));
    g_clear_error (&error);
  }
  sp.geometry.period_px = P;
  sp.geometry.pixel_aperture = 1;
  g_autoptr (DsErrorModel) m = ds_error_model_new (&p, &sp);
  g_assert_true (ds_error_model_predict (m, DS_ESTIMATOR_MAXMIN, 3, 1, 1, 0, &parts, &error));
  double se = 0;
  guint n = 0;
  for (guint x = 0; x < 256; x++) {
    double hi = 0, lo = 1;
    for (guint k = 0; k < 3; k++) {
      double lit = 0;
      for (int i = 0; i < 1000; i++) {
        double u = (x - 0.5 + (i + 0.5) / 1000.0) / P - k / 3.0;
        u -= floor (u + 0.5);
        lit += fabs (u) < a / 2;
      }
      lit /= 1000;
      hi = MAX (hi, lit);
      lo = MIN (lo, lit);
    }
    se += (hi - lo - 1) * (hi - lo - 1);
    n++;
  }
  double expect = sqrt (se / n);
  g_assert_cmpfloat (expect, >, 0.1); /* a 24-58 % error in places: not small */
  g_assert_cmpfloat_with_epsilon (parts.sampling, expect, 0.01);
  g_assert_cmpfloat_with_epsilon (parts.total, expect, 0.01);
  /* With aN >= 1 (N = 4, and wide enough that pixel edges do not matter) maxmin is exact. */
  g_assert_true (ds_error_model_predict (m, DS_ESTIMATOR_MAXMIN, 8, 1, 1, 0, &parts, &error));
  g_assert_cmpfloat (parts.sampling, <, 1e-6);
}

/* robust's (and maxmin's) sampling part where the unlit run is too short for the phase step: a
 * 1-px pixel is fully dark while its aperture lies in the dark run, L0 = (1 - a)P - 1 pixels of
 * positions; phases shift it by s = P/N. Between two dark positions a gap g = s - L0 is left: a
 * pixel there (a fraction g/s) has its darkest sample at a distance d = min(u, g - u) outside the
 * run (u uniform over the gap), where it is lit d pixels' worth (the edge is sharp, the aperture
 * 1 px): Ld = 1 - d. The rms error over pixels is sqrt((g/s) E[d^2]) = sqrt(g^3 / (12 s)). The
 * lit run is long enough for robust's lit window. The model must see this, not zero; and with no
 * fully dark position at all, robust is refused with proc's reason. */
static void
test_error_model_robust_sampling (void)
{
  const double P = 14.5, a = 0.75;
  const guint n = 4;
  DsSceneProbe p = hand_probe (P, a, 1000, 300, 0, 0);
  p.phase_offset = 0.013; /* no synthetic pixel exactly on an edge */
  DsSeparationParams sp = params_of (&p);
  sp.geometry.period_px = P;
  sp.geometry.pixel_aperture = 1;
  sp.geometry.edge_blur_known = TRUE; /* sharp, as the probe says */
  double s = P / n, g = s - ((1 - a) * P - 1);
  double expect = sqrt (g * g * g / (12 * s));
  g_assert_cmpfloat (expect, >, 0.1);
  g_autoptr (DsErrorModel) m = ds_error_model_new (&p, &sp);
  DsErrorParts parts;
  g_autoptr (GError) error = NULL;
  for (int e = 0; e < 2; e++) {
    DsEstimator est = e ? DS_ESTIMATOR_ROBUST : DS_ESTIMATOR_MAXMIN;
    g_assert_true (ds_error_model_predict (m, est, n, 1, 1, 0, &parts, &error));
    g_assert_no_error (error);
    g_test_message ("%s N = %u: sampling %.4f, closed form %.4f", ds_estimator_name (est), n, parts.sampling,
                    expect);
    g_assert_cmpfloat_with_epsilon (parts.sampling, expect, 0.05 * expect);
    g_assert_cmpfloat_with_epsilon (parts.total, expect, 0.05 * expect);
  }
  /* Twice the phases: s = 1.81 px < L0, every pixel has a fully dark phase: exact. */
  g_assert_true (ds_error_model_predict (m, DS_ESTIMATOR_ROBUST, 2 * n, 1, 1, 0, &parts, &error));
  g_assert_cmpfloat (parts.sampling, <, 1e-4);
  /* (1 - a)P = 0.725 px, narrower than a pixel: never fully dark anywhere. */
  DsSceneProbe q = hand_probe (P, 0.95, 1000, 300, 0, 0);
  sp.duty = 0.95;
  g_autoptr (DsErrorModel) never = ds_error_model_new (&q, &sp);
  g_assert_false (ds_error_model_predict (never, DS_ESTIMATOR_ROBUST, 8, 1, 1, 0, &parts, &error));
  g_assert_nonnull (strstr (error->message, "no pixel is fully lit in one phase and fully dark in another"));
}

/* Noise parts against closed forms (docs/estimators.md): maxmin's bias and spread at N = 8 are
 * 2.06 and 0.99 sigma (order statistics of 4 normals); sine's variance is 2 v / (N h^2) for a
 * pixel of per-frame variance v (here v is the same in every phase: no shot noise). */
static void
test_error_model_noise (void)
{
  const double sigma = 10, ld = 500;
  DsSceneProbe p = hand_probe (16, 0.5, ld, 1000, sigma * sigma, 0);
  DsSeparationParams sp = params_of (&p);
  g_autoptr (DsErrorModel) m = ds_error_model_new (&p, &sp);
  DsErrorParts parts;
  g_autoptr (GError) error = NULL;
  g_assert_true (ds_error_model_predict (m, DS_ESTIMATOR_MAXMIN, 8, 1, 1, 0, &parts, &error));
  double expect = sqrt (2.06 * 2.06 + 0.99 * 0.99) * sigma / ld;
  g_assert_cmpfloat_with_epsilon (parts.noise, expect, 0.08 * expect);
  /* sine, N = 16, M = 4: its gain on sharp square stripes sampled by pixels. */
  g_assert_true (ds_error_model_predict (m, DS_ESTIMATOR_SINE, 16, 4, 1, 0, &parts, &error));
  double h = 2 / G_PI * sin (G_PI / 16) / (G_PI / 16);
  expect = sqrt (2 * sigma * sigma / 4 / (16 * h * h)) / ld;
  g_assert_cmpfloat_with_epsilon (parts.noise, expect, 0.1 * expect);
  /* Twice the exposure: the signal doubles, read noise stays. */
  g_assert_true (ds_error_model_predict (m, DS_ESTIMATOR_SINE, 16, 4, 2, 0, &parts, &error));
  g_assert_cmpfloat_with_epsilon (parts.noise, expect / 2, 0.1 * expect / 2);
}

/* Clipping counts in the prediction: maxmin on sharp stripes is exact (N = P), so at an exposure
 * whose lit level 2 Ld passes the clip level c the whole error is the clip's, 1 - c / (2 Ld),
 * when the sets do not flag it; when they do, every lit pixel is flagged and nothing is left. */
static void
test_error_model_clipping (void)
{
  DsSceneProbe p = hand_probe (12, 0.5, 1000, 0, 0, 0);
  p.clip.saturation_dn = 1500;
  p.noise.dark_dn = 0;
  p.clip.bright_dn = 1000; /* the lit stripes: the synthetic pixels are the scene's brightest */
  DsSeparationParams sp = params_of (&p);
  DsErrorParts parts;
  g_autoptr (GError) error = NULL;
  {
    g_autoptr (DsErrorModel) m = ds_error_model_new (&p, &sp);
    g_assert_true (ds_error_model_predict (m, DS_ESTIMATOR_MAXMIN, 12, 1, 1, 0, &parts, &error));
    g_assert_cmpfloat (parts.total, <, 1e-4);
    g_assert_true (ds_error_model_predict (m, DS_ESTIMATOR_MAXMIN, 12, 1, 2, 0, &parts, &error));
    g_assert_cmpfloat_with_epsilon (parts.total, 1 - 1500.0 / 2000, 1e-3);
  }
  p.clip.flagged = TRUE;
  g_autoptr (DsErrorModel) m = ds_error_model_new (&p, &sp);
  g_assert_false (ds_error_model_predict (m, DS_ESTIMATOR_MAXMIN, 12, 1, 2, 0, &parts, &error));
}

/* A leak that cancels part of the sampling error: sine on a pixel-integrating sensor reads
 * (1 + L) sinc(1/P) - 1 (test_error_model_leak), below the sampling error 1 - sinc(1/P) for
 * 0 < L < 2 (1/sinc - 1). The prediction is the measured leak's, its upper end the worse end of
 * leaks from none to 2L, max(1 - sinc, (1 + 2L) sinc - 1): with L at the exact cancellation, the
 * sampling error; with L at 3/4 of the way to the overshoot, the doubled leak's. */
static void
test_error_model_cancellation (void)
{
  const double P = 12, s = sin (G_PI / P) / (G_PI / P);
  const double cases[] = { 1 / s - 1, 1.5 * (1 / s - 1) };
  for (guint i = 0; i < G_N_ELEMENTS (cases); i++) {
    double L = cases[i];
    DsSceneProbe p = hand_probe (P, 0.5, 500, 3000, 0, 0);
    p.leak.per_px = log1p (L) / P;
    DsSeparationParams sp = params_of (&p);
    g_autoptr (DsErrorModel) m = ds_error_model_new (&p, &sp);
    DsErrorParts parts;
    g_autoptr (GError) error = NULL;
    g_assert_true (ds_error_model_predict (m, DS_ESTIMATOR_SINE, 32, 1, 1, 0, &parts, &error));
    double sys = fabs ((1 + L) * s - 1), worst = MAX (1 - s, (1 + 2 * L) * s - 1);
    g_test_message ("leak %.4f: systematic %.5f (closed form %.5f), total %.5f (worst end %.5f)", L,
                    parts.systematic, sys, parts.total_upper, worst);
    /* Within the per-pixel ripple the closed form leaves out (higher harmonics aliased at N = 32). */
    g_assert_cmpfloat_with_epsilon (parts.systematic, sys, 0.15 * (1 - s));
    g_assert_cmpfloat_with_epsilon (parts.sampling, 1 - s, 0.05 * (1 - s));
    g_assert_cmpfloat (parts.scattered_stripes, <, 0);
    g_assert_cmpfloat_with_epsilon (parts.total_upper, worst, 0.05 * worst);
    g_assert_cmpfloat_with_epsilon (parts.total, parts.systematic, 0.05 * worst); /* noise-free probe */
    g_assert_cmpfloat_with_epsilon (parts.cancellation, parts.total_upper - parts.systematic, 0.05 * worst);
  }
}

/* The blur unknown: sine stripes on a pixel-integrating sensor (the estimator's theory gain,
 * sinc (1/P) lost to the pixel) read Ld low by 1 - sinc (1/P) when sharp, and by
 * 1 - sinc (1/P) exp (-2 pi^2 s^2 / P^2) under the assumed blur s = min (0.75, P/8). The
 * prediction is the sharp pattern's, the upper end the blurred one's: an interval, not the worse
 * of the two as the prediction (at P = 5: 0.065 and 0.313). */
static void
test_error_model_blur_unknown (void)
{
  const double P = 5, s = sin (G_PI / P) / (G_PI / P), sigma = MIN (DS_ERROR_MODEL_UNKNOWN_BLUR_PX, P / 8);
  DsSceneProbe p = hand_probe (P, 0.5, 1000, 0, 0, 0);
  p.geometry.kind = DS_PATTERN_SINE;
  p.blur.source = DS_BLUR_ASSUMED_SHARP;
  DsSeparationParams sp = params_of (&p);
  g_autoptr (DsErrorModel) m = ds_error_model_new (&p, &sp);
  DsErrorParts parts;
  g_autoptr (GError) error = NULL;
  g_assert_true (ds_error_model_predict (m, DS_ESTIMATOR_SINE, 8, 1, 1, 0, &parts, &error));
  double sharp = 1 - s, blurred = 1 - s * exp (-2 * G_PI * G_PI * sigma * sigma / (P * P));
  g_test_message ("sine at %g px, blur unknown: %.4f to %.4f (closed form %.4f to %.4f)", P, parts.total,
                  parts.total_upper, sharp, blurred);
  g_assert_true (parts.blur_assumed);
  g_assert_cmpfloat_with_epsilon (parts.total, sharp, 0.05 * sharp);
  g_assert_cmpfloat_with_epsilon (parts.total_upper, blurred, 0.05 * blurred);
}

/* The scattered stripes: sine sees the first harmonic raised by the leak L and lowered by the
 * pixel's aperture sinc(1/P) against its theoretical gain, so its relative error is
 * (1 + L) sinc(1/P) - 1 (N large enough to ignore aliasing). */
static void
test_error_model_leak (void)
{
  DsSceneProbe p = hand_probe (12, 0.5, 500, 3000, 0, 0);
  p.leak.per_px = 0.02;
  DsSeparationParams sp = params_of (&p);
  g_autoptr (DsErrorModel) m = ds_error_model_new (&p, &sp);
  DsErrorParts parts;
  g_autoptr (GError) error = NULL;
  g_assert_true (ds_error_model_predict (m, DS_ESTIMATOR_SINE, 32, 1, 1, 0, &parts, &error));
  double leak = expm1 (0.02 * 12), aperture = sin (G_PI / 12) / (G_PI / 12);
  g_assert_cmpfloat_with_epsilon (parts.systematic, (1 + leak) * aperture - 1, 0.01 * leak);
  g_assert_cmpfloat (parts.scattered_stripes, >, 0.9 * leak);
  /* It adds to the sampling error: the prediction rests on no cancellation. */
  g_assert_cmpfloat (parts.cancellation, ==, 0);
  g_assert_cmpfloat_with_epsilon (parts.total, parts.systematic, 1e-9);
  /* At half the period the leak shrinks as the model says. */
  g_assert_true (ds_error_model_predict (m, DS_ESTIMATOR_SINE, 32, 1, 1, 6, &parts, &error));
  g_assert_cmpfloat (parts.scattered_stripes, <, 0.6 * leak);
  /* An estimator's own refusal comes through with its message. */
  g_assert_false (ds_error_model_predict (m, DS_ESTIMATOR_SINE, 2, 1, 1, 0, &parts, &error));
  g_assert_nonnull (strstr (error->message, "sine"));
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  g_test_add_func ("/error-model/stripe-value", test_stripe_value);
  g_test_add_func ("/error-model/harmonics-fit", test_harmonics_fit);
  g_test_add_func ("/error-model/probe-plain", test_probe_plain);
  g_test_add_func ("/error-model/probe-leak", test_probe_leak);
  g_test_add_func ("/error-model/probe-blurred-harmonics", test_probe_blurred_harmonics);
  g_test_add_func ("/error-model/precondition", test_error_model_precondition);
  g_test_add_func ("/error-model/robust-sampling", test_error_model_robust_sampling);
  g_test_add_func ("/error-model/noise", test_error_model_noise);
  g_test_add_func ("/error-model/probe-clip-level", test_probe_clip_level);
  g_test_add_func ("/error-model/probe-clip-quiet-sensor", test_probe_clip_quiet_sensor);
  g_test_add_func ("/error-model/clipping", test_error_model_clipping);
  g_test_add_func ("/error-model/leak", test_error_model_leak);
  g_test_add_func ("/error-model/cancellation", test_error_model_cancellation);
  g_test_add_func ("/error-model/blur-unknown", test_error_model_blur_unknown);
  g_test_add_func ("/error-model/probe-clipped-places", test_probe_clipped_places);
  g_test_add_func ("/error-model/probe-spread", test_probe_spread);
  return g_test_run ();
}
