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

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  g_test_add_func ("/stripe-period/known-periods", test_known_periods);
  g_test_add_func ("/stripe-period/no-stripes", test_no_stripes);
  g_test_add_func ("/stripe-period/bad-range", test_bad_range);
  return g_test_run ();
}
