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
  if (s->kind == DS_PATTERN_SINE)
    return 0.5 + 0.5 * cos (2 * G_PI * d / s->period);
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

static double
gauss (GRand *r)
{
  double u = g_rand_double_range (r, 1e-12, 1), v = g_rand_double (r);
  return sqrt (-2 * log (u)) * cos (2 * G_PI * v);
}

static void
calibrate (const Stripes *s, gboolean forced, DsCalibration *out)
{
  g_autoptr (GError) error = NULL;
  g_autoptr (DsCalibrator) cal = ds_calibrator_new (N, W, H, &error);
  g_assert_no_error (error);
  GRand *r = g_rand_new_with_seed (7);
  for (guint k = 0; k < N; k++) {
    g_autoptr (DsImage) img = ds_image_new (DS_SAMPLE_F32, W, H, NULL);
    for (guint y = 0; y < H; y++) {
      float *row = ds_image_row (img, y);
      for (guint x = 0; x < W; x++) {
        double v = 0;
        for (guint i = 0; i < SUB; i++) {
          double px = x - 0.5 + (i + 0.5) / SUB;
          v += lit (s, px - (0.3 + (double) k / N) * s->period) / SUB;
        }
        row[x] = (float) (1000 * (s->black + (1 - s->black) * v + s->noise * gauss (r)));
      }
    }
    g_assert_true (ds_calibrator_add (cal, k, img, &error));
    g_assert_no_error (error);
  }
  g_rand_free (r);
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
    /* the sine's fit takes the pixel's width into account: its black level is the scene's */
    g_assert_cmpfloat (fabs (c.black_level - cases[i].black), <, 0.02);
  }
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

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  g_test_add_func ("/calibration-pattern/sine-is-sine", test_sine_is_sine);
  g_test_add_func ("/calibration-pattern/square-is-square", test_square_is_square);
  g_test_add_func ("/calibration-pattern/blurred-square-is-sine", test_blurred_square_is_sine);
  g_test_add_func ("/calibration-pattern/forced", test_forced);
  return g_test_run ();
}
