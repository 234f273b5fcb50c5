/* proc/stripe_period: synthetic stripes of known, non-integer periods (square of several duties,
 * sine), with a scattered background and noise, measured within a small fraction of a pixel;
 * no stripes is "cannot tell", not a number. */
#include <glib.h>
#include <math.h>

#include "proc/proc_error.h"
#include "proc/stripe_period.h"

static DsImage *
stripes (guint w, guint h, double period, double duty, gboolean sine, double amplitude, double noise, guint seed)
{
  DsImage *img = ds_image_new (DS_SAMPLE_U16, w, h, NULL);
  GRand *rand = g_rand_new_with_seed (seed);
  for (guint y = 0; y < h; y++)
    for (guint x = 0; x < w; x++) {
      double u = x / period + 0.3;
      u -= floor (u);
      double lit = sine ? 0.5 + 0.5 * cos (2 * G_PI * u) : (u < duty ? 1.0 : 0.0);
      /* Box-Muller normal noise. */
      double n = sqrt (-2 * log (1 - g_rand_double (rand))) * cos (2 * G_PI * g_rand_double (rand));
      double v = 800 + 2.0 * x + amplitude * lit + noise * n;
      ((guint16 *) ds_image_row (img, y))[x] = (guint16) CLAMP (v + 0.5, 0, 65535);
    }
  g_rand_free (rand);
  return img;
}

static void
test_known_periods (void)
{
  const struct {
    double period, duty;
    gboolean sine;
  } cases[] = { { 16.0, 0.5, FALSE }, { 13.7, 0.5, FALSE }, { 7.3, 0.3, FALSE }, { 31.25, 0.5, TRUE }, { 5.5, 0.5, TRUE } };
  for (guint i = 0; i < G_N_ELEMENTS (cases); i++) {
    g_autoptr (DsImage) img = stripes (640, 48, cases[i].period, cases[i].duty, cases[i].sine, 300, 30, i + 1);
    DsStripePeriod sp;
    g_autoptr (GError) error = NULL;
    g_assert_true (ds_stripe_period_measure (img, cases[i].period / 2, MIN (cases[i].period * 2, 320), &sp, &error));
    g_assert_no_error (error);
    g_test_message ("period %.3f: measured %.4f (peak/median %.0f)", cases[i].period, sp.period_px, sp.peak_ratio);
    g_assert_true (sp.reliable);
    /* A 640-px frame holds 20..120 periods: 0.2 % is a small fraction of one DFT bin. */
    g_assert_cmpfloat (fabs (sp.period_px - cases[i].period) / cases[i].period, <, 0.002);
  }
}

static void
test_no_stripes (void)
{
  g_autoptr (DsImage) img = stripes (640, 48, 16, 0.5, FALSE, 0, 30, 9);
  DsStripePeriod sp;
  g_assert_true (ds_stripe_period_measure (img, 8, 32, &sp, NULL));
  g_assert_false (sp.reliable);
  g_assert_true (isnan (sp.period_px));
}

static void
test_bad_range (void)
{
  g_autoptr (DsImage) img = stripes (64, 4, 16, 0.5, FALSE, 300, 0, 1);
  DsStripePeriod sp;
  g_autoptr (GError) error = NULL;
  g_assert_false (ds_stripe_period_measure (img, 8, 40, &sp, &error));
  g_assert_error (error, DS_PROC_ERROR, DS_PROC_ERROR_INVALID_ARGUMENT);
  g_assert_nonnull (g_strstr_len (error->message, -1, "half the width"));
}

/* ds_stripe_period_detect: square stripes (pixel-integrated, several duties, a black level) and
 * sine stripes over a scene that varies along x, with scattered light and noise, from one frame
 * or from two about half a period apart: within 0.1 %; a frame without stripes gives none. */
static DsImage *
phase_frame (guint w, guint h, double period, double duty, double black, gboolean sine, double k_cycles,
             double direct, double global, double noise, GRand *rand)
{
  DsImage *img = ds_image_new (DS_SAMPLE_U16, w, h, NULL);
  for (guint y = 0; y < h; y++)
    for (guint x = 0; x < w; x++) {
      double pat = 0;
      for (int j = 0; j < 16; j++) {
        double u = (x + (j + 0.5) / 16.0 - 0.5) / period - k_cycles;
        u -= floor (u + 0.5);
        pat += (sine ? 0.5 * (1 + cos (2 * G_PI * u)) : (fabs (u) < duty / 2 ? 1.0 : 0.0)) / 16;
      }
      double scene = 1 + 0.3 * sin (x * 0.013) + 0.2 * ((x * 7919) % 13) / 13.0; /* texture along x */
      double n = sqrt (-2 * log (1 - g_rand_double (rand))) * cos (2 * G_PI * g_rand_double (rand));
      double v = scene * (global + direct * (black + (1 - black) * pat)) + noise * n;
      ((guint16 *) ds_image_row (img, y))[x] = (guint16) CLAMP (v + 0.5, 0, 65535);
    }
  return img;
}

static void
test_detect (void)
{
  const struct {
    double period, duty, black;
    gboolean sine, pair;
  } cases[] = {
    { 12, 0.5, 0, FALSE, FALSE }, { 5.5, 0.5, 0, FALSE, TRUE }, { 37.3, 0.25, 0, FALSE, TRUE },
    { 80, 0.3, 0.1, FALSE, TRUE }, { 9.7, 0.5, 0, TRUE, TRUE },
  };
  const guint w = 640, h = 8;
  GRand *r = g_rand_new_with_seed (99);
  for (guint i = 0; i < G_N_ELEMENTS (cases); i++) {
    g_autoptr (DsImage) a = phase_frame (w, h, cases[i].period, cases[i].duty, cases[i].black, cases[i].sine, 0,
                                         1000, 2000, 5, r);
    g_autoptr (DsImage) b = cases[i].pair ? phase_frame (w, h, cases[i].period, cases[i].duty, cases[i].black,
                                                         cases[i].sine, 0.5, 1000, 2000, 5, r)
                                          : NULL;
    double period, snr;
    g_autoptr (GError) error = NULL;
    g_assert_true (ds_stripe_period_detect (a, b, &period, &snr, &error));
    g_assert_no_error (error);
    g_test_message ("case %u: period %.4f (true %g), snr %.0f", i, period, cases[i].period, snr);
    g_assert_cmpfloat (fabs (period / cases[i].period - 1), <, 1e-3);
  }
  /* no direct light: two frames differ by noise only (the scene's texture, periodic itself at
   * 13 px, cancels in the difference) */
  g_autoptr (DsImage) flat0 = phase_frame (w, h, 12, 0.5, 0, FALSE, 0, 0, 1000, 5, r);
  g_autoptr (DsImage) flat1 = phase_frame (w, h, 12, 0.5, 0, FALSE, 0.5, 0, 1000, 5, r);
  double period, snr;
  g_assert_false (ds_stripe_period_detect (flat0, flat1, &period, &snr, NULL));
  g_assert_true (isnan (period));
  g_assert_cmpfloat (snr, <, 8);
  g_rand_free (r);
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  g_test_add_func ("/stripe-period/known-periods", test_known_periods);
  g_test_add_func ("/stripe-period/no-stripes", test_no_stripes);
  g_test_add_func ("/stripe-period/bad-range", test_bad_range);
  g_test_add_func ("/stripe-period/detect", test_detect);
  return g_test_run ();
}
