/* The calibrator tells sine stripes from square ones (proc/calibration_pattern.h) on phase sets
 * written here in closed form, independently of the calibrator's models: a sinusoid, and a
 * square of duty a convolved with a Gaussian edge blur (a sum of erf steps), each with a black
 * level, integrated over the pixel's width by sub-sampling, with Gaussian noise. Sines are sine
 * and never "scatter"; squares the data can show harmonics of stay square; a square blurred
 * until it has no harmonic above the first is reported as sine, with the square said to fit. */
#include <glib.h>
#include <math.h>
#include <string.h>

#include "proc/calibration.h"
#include "proc/proc_error.h"
#include "tests/common/test_random.h"

#define W 240u
#define H 8u
#define N 8u
#define SUB 16u

typedef struct {
  DsPatternKind kind;
  double period, duty, black, blur, noise; /* noise: sigma relative to the lit level */
} Stripes;

/* Lit fraction at distance d (px) from a stripe centre. */
static double
lit (const Stripes *s, double d)
{
  if (s->kind == DS_PATTERN_SINE) /* a Gaussian blur scales a sine's amplitude, nothing else */
    return 0.5 + 0.5 * exp (-2 * G_PI * G_PI * s->blur * s->blur / (s->period * s->period)) *
                     cos (2 * G_PI * d / s->period);
  double half = s->duty * s->period / 2, v = 0;
  d = fmod (d, s->period);
  for (int j = -3; j <= 3; j++) {
    double c = d - j * s->period;
    if (s->blur > 0)
      v += 0.5 * (erf ((c + half) / (G_SQRT2 * s->blur)) - erf ((c - half) / (G_SQRT2 * s->blur)));
    else
      v += fabs (c) < half;
  }
  return v;
}

/* Adds one phase set of s to cal: each pixel's lit fraction integrated over its width, the left
 * half of the frame lit to level[0] and the right half to level[1] above offset, Gaussian noise of
 * noise_dn, samples of an integer type rounded and clipped at clip. */
static void
add_phase_set (DsCalibrator *cal, const Stripes *s, DsSampleType type, const double level[2], double offset,
               double noise_dn, double clip, guint32 seed)
{
  g_autoptr (GError) error = NULL;
  GRand *r = g_rand_new_with_seed (seed);
  for (guint k = 0; k < N; k++) {
    g_autoptr (DsImage) img = ds_image_new (type, W, H, NULL);
    for (guint y = 0; y < H; y++) {
      void *row = ds_image_row (img, y);
      for (guint x = 0; x < W; x++) {
        double v = 0;
        for (guint i = 0; i < SUB; i++) {
          double px = x - 0.5 + (i + 0.5) / SUB;
          v += lit (s, px - (0.3 + (double) k / N) * s->period) / SUB;
        }
        double dn = offset + level[x >= W / 2] * (s->black + (1 - s->black) * v) + noise_dn * test_normal (r);
        if (type == DS_SAMPLE_F32)
          ((float *) row)[x] = (float) dn;
        else if (type == DS_SAMPLE_U8)
          ((guint8 *) row)[x] = (guint8) CLAMP (round (dn), 0, clip);
        else
          ((guint16 *) row)[x] = (guint16) CLAMP (round (dn), 0, clip);
      }
    }
    g_assert_true (ds_calibrator_add (cal, k, img, &error));
    g_assert_no_error (error);
  }
  g_rand_free (r);
}

static void
calibrate (const Stripes *s, gboolean forced, DsCalibration *out)
{
  g_autoptr (GError) error = NULL;
  g_autoptr (DsCalibrator) cal = ds_calibrator_new (N, W, H, &error);
  g_assert_no_error (error);
  add_phase_set (cal, s, DS_SAMPLE_F32, (const double[2]) { 1000, 1000 }, 0, 1000 * s->noise, INFINITY, 7);
  DsCalibrationHints hints;
  ds_calibration_hints_init (&hints);
  if (forced) {
    hints.pattern = s->kind;
    hints.pattern_forced = TRUE;
  }
  g_assert_true (ds_calibrator_finish (cal, &hints, out, &error));
  g_assert_no_error (error);
  const DsPatternCheck *p = &out->pattern_check;
  g_test_message ("%s P %.2f a %.2f b %.2f blur %.2f noise %.3f: %s (sine %.4f %%, square %.4f %% at %.2f px, "
                  "noise %.4f %%)",
                  s->kind == DS_PATTERN_SINE ? "sine" : "square", s->period, s->duty, s->black, s->blur, s->noise,
                  out->pattern == DS_PATTERN_SINE ? "sine" : "square", 100 * p->sine_residual,
                  100 * p->square_residual, p->square_blur_px, 100 * p->noise);
}

static void
test_sine_is_sine (void)
{
  const Stripes cases[] = {
    { DS_PATTERN_SINE, 9.25, 0.5, 0, 0, 0 },
    { DS_PATTERN_SINE, 13, 0.5, 0.2, 0, 0.01 },
    { DS_PATTERN_SINE, 7.5, 0.5, 0.05, 0, 0.003 },
    { DS_PATTERN_SINE, 21, 0.5, 0.4, 0, 0.02 },
  };
  for (guint i = 0; i < G_N_ELEMENTS (cases); i++) {
    DsCalibration c;
    calibrate (&cases[i], FALSE, &c);
    g_assert_cmpint (c.pattern, ==, DS_PATTERN_SINE);
    g_assert_true (c.pattern_check.detected);
    g_assert_false (c.scatter.scattering);
    /* measured, then refined on the columns' phases (calibration_period.h) */
    g_assert_cmpfloat (fabs (c.period_px / cases[i].period - 1), <, 2e-4);
    g_autofree char *warning = ds_calibration_scatter_warning (&c);
    g_assert_null (warning);
    /* the default expectation is square: the notice names the remedy */
    g_autofree char *notice = ds_calibration_pattern_notice (&c);
    g_assert_nonnull (notice);
    g_assert_nonnull (strstr (notice, "pattern=sine"));
    /* one period cannot tell the black level: it is the hint's (0), said so, and the gain goes
     * with it: h = m c, the contrast c = k g measured (closed form: k (1 - b)/(1 + b), g the
     * pixel's sinc, no blur here) */
    g_assert_false (c.black_level_measured);
    g_assert_cmpfloat (c.black_level, ==, 0);
    g_autofree char *note = ds_calibration_black_level_note (&c);
    g_assert_nonnull (strstr (note, "assumed, not measured"));
    double k = (1 - cases[i].black) / (1 + cases[i].black), g = sin (G_PI / cases[i].period) / (G_PI / cases[i].period);
    g_assert_cmpfloat (fabs (c.contrast / (k * g) - 1), <, 0.01);
    g_assert_cmpfloat (fabs (c.harmonic_gain - 0.5 * c.contrast), <, 1e-9);
  }
}

/* Sine stripes of known black level b and blur sigma, integrated over the pixel, at a period and
 * at another: calibrate recovers b (within 0.01) and the harmonic gain the sine estimator needs
 * at the first period, h = (1 - b)/2 exp (-2 pi^2 sigma^2 / P^2) sinc (1/P) (within 1 %), and
 * the blur (within 0.1 px). The same with noise of 0.5 % of the lit level. */
static void
test_sine_levels (void)
{
  const struct {
    double period, second, black, blur, noise;
  } cases[] = {
    { 16, 32, 0.0222, 1.479, 0 },  /* the lab trial's gen-22-00 reference */
    { 9.25, 18.5, 0.1, 1.0, 0 },
    { 12, 24, 0.3, 0.5, 0.005 },
    { 8, 13, 0.05, 1.2, 0.005 },
    { 20, 40, 0, 0, 0.005 },
  };
  for (guint i = 0; i < G_N_ELEMENTS (cases); i++) {
    Stripes a = { DS_PATTERN_SINE, cases[i].period, 0.5, cases[i].black, cases[i].blur, cases[i].noise };
    Stripes b = a;
    b.period = cases[i].second;
    DsCalibration c, c2;
    calibrate (&a, FALSE, &c);
    calibrate (&b, TRUE, &c2);
    g_assert_cmpint (c.pattern, ==, DS_PATTERN_SINE);
    g_autoptr (GError) error = NULL;
    g_assert_true (ds_calibration_add_second_period (&c, &c2, 1.0, &error));
    g_assert_no_error (error);
    double P = cases[i].period, s2 = cases[i].blur * cases[i].blur;
    double h = (1 - cases[i].black) / 2 * exp (-2 * G_PI * G_PI * s2 / (P * P)) * sin (G_PI / P) / (G_PI / P);
    g_test_message ("P %.2f and %.2f, b %.4f, blur %.2f, noise %.3f: b %.4f, h %.4f (%.4f), blur %.2f",
                    P, cases[i].second, cases[i].black, cases[i].blur, cases[i].noise, c.black_level,
                    c.harmonic_gain, h, c.edge_blur_px);
    g_assert_true (c.black_level_measured);
    g_assert_cmpfloat (fabs (c.black_level - cases[i].black), <, 0.01);
    g_assert_cmpfloat (fabs (c.harmonic_gain / h - 1), <, 0.01);
    g_assert_cmpfloat (fabs (c.edge_blur_px - cases[i].blur), <, 0.1);
    g_autofree char *note = ds_calibration_black_level_note (&c);
    g_assert_null (note);
  }
  /* periods too close to tell, and square stripes, are refused naming why */
  Stripes a = { DS_PATTERN_SINE, 12, 0.5, 0.1, 1, 0 }, b = a;
  b.period = 13;
  DsCalibration c, c2;
  calibrate (&a, FALSE, &c);
  calibrate (&b, TRUE, &c2);
  g_autoptr (GError) error = NULL;
  g_assert_false (ds_calibration_add_second_period (&c, &c2, 1.0, &error));
  g_assert_error (error, DS_PROC_ERROR, DS_PROC_ERROR_INVALID_ARGUMENT);
  g_assert_nonnull (strstr (error->message, "1.25"));
  g_assert_false (c.black_level_measured);
}

static void
test_square_is_square (void)
{
  const Stripes cases[] = {
    { DS_PATTERN_SQUARE, 12, 0.5, 0, 0, 0 },
    { DS_PATTERN_SQUARE, 9.5, 0.3, 0.1, 1.0, 0.005 },
    { DS_PATTERN_SQUARE, 14, 0.67, 0.14, 0.5, 0.01 },
    { DS_PATTERN_SQUARE, 13.5, 0.42, 0.12, 1.5, 0.002 },
    { DS_PATTERN_SQUARE, 8.5, 0.55, 0, 0.5, 0.01 },
  };
  for (guint i = 0; i < G_N_ELEMENTS (cases); i++) {
    DsCalibration c;
    calibrate (&cases[i], FALSE, &c);
    g_assert_cmpint (c.pattern, ==, DS_PATTERN_SQUARE);
    g_assert_false (c.scatter.scattering);
    g_assert_cmpfloat (fabs (c.period_px / cases[i].period - 1), <, 2e-4);
    g_assert_cmpfloat (fabs (c.duty - cases[i].duty), <, 0.02);
    g_assert_cmpfloat (fabs (c.black_level - cases[i].black), <, 0.02);
    g_autofree char *notice = ds_calibration_pattern_notice (&c);
    g_assert_null (notice);
  }
}

/* Blur sigma >= P / 4: the second harmonic is down by exp(-2 pi^2 4 sigma^2 / P^2) <= 3e-4 (at
 * 0.32 P), the third by 1.5e-5: none is left above the noise. */
static void
test_blurred_square_is_sine (void)
{
  const Stripes cases[] = {
    { DS_PATTERN_SQUARE, 8, 0.5, 0, 2.0, 0 },
    { DS_PATTERN_SQUARE, 10, 0.4, 0.1, 3.2, 0.003 },
  };
  for (guint i = 0; i < G_N_ELEMENTS (cases); i++) {
    DsCalibration c;
    calibrate (&cases[i], FALSE, &c);
    g_assert_cmpint (c.pattern, ==, DS_PATTERN_SINE);
    g_assert_true (c.pattern_check.square_fits);
    g_assert_false (c.scatter.scattering);
    g_autofree char *notice = ds_calibration_pattern_notice (&c);
    g_assert_nonnull (strstr (notice, "indistinguishable from a sine"));
  }
}

/* --pattern (pattern_forced): the given pattern is taken without looking, and no notice. */
static void
test_forced (void)
{
  const Stripes s = { DS_PATTERN_SQUARE, 12, 0.5, 0, 0, 0 };
  DsCalibration c;
  Stripes sine = s;
  sine.kind = DS_PATTERN_SINE;
  calibrate (&sine, FALSE, &c);
  g_assert_cmpint (c.pattern, ==, DS_PATTERN_SINE);
  calibrate (&s, TRUE, &c);
  g_assert_cmpint (c.pattern, ==, DS_PATTERN_SQUARE);
  g_assert_false (c.pattern_check.detected);
  g_autofree char *notice = ds_calibration_pattern_notice (&c);
  g_assert_null (notice);
}

/* One phase set of square stripes (duty 0.5, blur 0.5 px) as a 12-bit sensor delivers it in a
 * 16-bit format: the left half of the frame lit to left_dn, the right half to right_dn, with 5 DN
 * of noise, each sample clipped at 4095. */
static DsCalibrator *
clipped_set (double left_dn, double right_dn)
{
  const Stripes s = { DS_PATTERN_SQUARE, 12.0, 0.5, 0.0, 0.5, 0.0 };
  g_autoptr (GError) error = NULL;
  DsCalibrator *cal = ds_calibrator_new (N, W, H, &error);
  g_assert_no_error (error);
  add_phase_set (cal, &s, DS_SAMPLE_U16, (const double[2]) { left_dn, right_dn }, 100, 5, 4095, 11);
  g_autoptr (DsImage) dark = ds_image_new (DS_SAMPLE_U16, W, H, NULL);
  for (guint y = 0; y < H; y++)
    for (guint x = 0; x < W; x++)
      ((guint16 *) ds_image_row (dark, y))[x] = 100;
  g_assert_true (ds_calibrator_set_dark (cal, dark, &error));
  return cal;
}

/* A sensor that clips below its format's top piles samples at its clip level (clip_level.h): the
 * calibrator leaves those pixels out as it does pixels at the format's top. The lit level is then
 * the unclipped half's; counting the clipped half would pull it towards 4095 less the dark. With
 * every pixel clipped the error names the level. */
static void
test_clip_below_format_top (void)
{
  g_autoptr (DsCalibrator) cal = clipped_set (3000, 6000);
  DsCalibrationHints hints;
  ds_calibration_hints_init (&hints);
  DsCalibration out;
  g_autoptr (GError) error = NULL;
  g_assert_true (ds_calibrator_finish (cal, &hints, &out, &error));
  g_assert_no_error (error);
  g_test_message ("lit level %.1f DN over %" G_GUINT64_FORMAT " pixels (unclipped half: 3000)", out.lit_level_dn,
                  out.pixels_used);
  g_assert_cmpfloat (fabs (out.lit_level_dn - 3000), <=, 0.01 * 3000);
  g_assert_cmpuint (out.pixels_used, <=, W / 2 * H);

  g_autoptr (DsCalibrator) all = clipped_set (6000, 6000);
  g_assert_false (ds_calibrator_finish (all, &hints, &out, &error));
  g_assert_nonnull (strstr (error->message, "clips (at 4095 DN)"));
}

/* An 8-bit camera's reference far below its clip level: fine stripes (3 px, duty 0.23) lit to 150
 * DN with 2 DN of noise. Each frame's top value is a noise tail's last code, which in a frame of
 * 1920 pixels holds the 0.02 % a probe pair's pile asks for: it is no clip, and the set is
 * measured (the lit level within 2 %). */
static void
test_noise_top_is_no_clip (void)
{
  const Stripes s = { DS_PATTERN_SQUARE, 3.0, 0.23, 0.0, 0.22, 0.0 };
  g_autoptr (GError) error = NULL;
  g_autoptr (DsCalibrator) cal = ds_calibrator_new (N, W, H, &error);
  g_assert_no_error (error);
  add_phase_set (cal, &s, DS_SAMPLE_U8, (const double[2]) { 150, 150 }, 0, 2, 255, 13);
  DsCalibrationHints hints;
  ds_calibration_hints_init (&hints);
  hints.period_px = 3.0;
  DsCalibration out;
  g_assert_true (ds_calibrator_finish (cal, &hints, &out, &error));
  g_assert_no_error (error);
  g_test_message ("lit level %.1f DN over %" G_GUINT64_FORMAT " pixels (150)", out.lit_level_dn, out.pixels_used);
  g_assert_cmpfloat (fabs (out.lit_level_dn - 150), <=, 0.02 * 150);
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  g_test_add_func ("/calibration-pattern/sine-is-sine", test_sine_is_sine);
  g_test_add_func ("/calibration-pattern/sine-levels", test_sine_levels);
  g_test_add_func ("/calibration-pattern/square-is-square", test_square_is_square);
  g_test_add_func ("/calibration-pattern/blurred-square-is-sine", test_blurred_square_is_sine);
  g_test_add_func ("/calibration-pattern/forced", test_forced);
  g_test_add_func ("/calibration-pattern/clip-below-format-top", test_clip_below_format_top);
  g_test_add_func ("/calibration-pattern/noise-top-is-no-clip", test_noise_top_is_no_clip);
  return g_test_run ();
}
