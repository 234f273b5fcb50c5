/* The lower end of the direct light where scattered light keeps the stripes (issue 12, gen-19-07):
 * ds_probe_direct_interval () on first harmonics in closed form. Sine stripes of black level 0, no
 * blur and point-sampling pixels at periods that divide the frame's width, so a harmonic's gain is
 * 1 (the difference of two opposite phases is cos of amplitude 1 per DN) and its amplitude at a
 * period Q is Ld + S T(Q), S the scattered light and T its kernel's MTF, written here from the
 * kernels' definitions: the family the interval assumes, (1 + 2 k^2)^-1/2 with k = 2 pi w / Q (the
 * Fourier transform of a kernel with a 1/k tail), and a Gaussian, exp (-2 pi^2 s^2 / Q^2), whose
 * MTF falls faster, so the family's kernel hides more light below the finest period than it does.
 * The coarse period loses 30 % of S, within three times the harmonics' noise: gen-19-07's case,
 * where the probe read "Ld not bounded below" though the loss's ratio lies inside what the family
 * allows. */
#include <math.h>

#include "daemon/operating/scene_probe_transfer.h"

#define WIDTH 256
#define LD 5000.0
#define S 600.0
#define NOISE 30.0 /* DN, each harmonic's one sigma: 3 x the drop's noise exceeds the loss at 32 px */

static const double periods[] = { 8, 16, 32 };

static DsStripeModel
sine_geometry (void)
{
  return (DsStripeModel){ .kind = DS_PATTERN_SINE, .period_px = 16, .duty = 0.5, .black_level = 0,
                          .blur_px = 0, .pixel_aperture = DS_STRIPE_POINT_APERTURE };
}

static double
family_mtf (double w, double q)
{
  double k = 2 * G_PI * w / q;
  return 1 / sqrt (1 + 2 * k * k);
}

static double
gaussian_mtf (double s, double q)
{
  return exp (-2 * G_PI * G_PI * s * s / (q * q));
}

static void
interval_of (const double *t, DsProbeDirectInterval *out)
{
  DsStripeModel g = sine_geometry ();
  DsProbeEquation eq[G_N_ELEMENTS (periods)];
  for (guint i = 0; i < G_N_ELEMENTS (periods); i++) {
    /* The gain the interval divides by must be 1 here: the closed form above rests on it. */
    g_assert_cmpfloat_with_epsilon (ds_probe_model_gain (&g, periods[i], 0, 0, WIDTH, 1), 1.0, 1e-6);
    eq[i] = (DsProbeEquation){ .period = periods[i], .n = 1, .amplitude = LD + S * t[i], .sigma = NOISE, .offset = 0 };
  }
  /* The probe's fit reads Ld at P, where the kernel still keeps part of the stripes. */
  ds_probe_direct_interval (eq, G_N_ELEMENTS (eq), &g, 0, WIDTH, LD + S * t[1], LD + S, out);
}

/* One kernel of the family that keeps 70 % of its stripes at 32 px: the loss there (180 DN) is
 * under three times the noise of the drop (3 x 66 DN), its ratio to the loss at 8 px (0.39) is
 * far above the steepest the family allows, (8/32)^2 = 0.0625. The interval's lower end is Ld
 * itself: the family's own kernel is what the bound assumes. */
static void
test_family_kernel_within_noise (void)
{
  double w = 32 * sqrt ((1 / (0.7 * 0.7) - 1) / 2) / (2 * G_PI), t[G_N_ELEMENTS (periods)];
  for (guint i = 0; i < G_N_ELEMENTS (periods); i++)
    t[i] = family_mtf (w, periods[i]);
  g_assert_cmpfloat_with_epsilon (t[2], 0.7, 1e-9);
  DsProbeDirectInterval in;
  interval_of (t, &in);
  g_test_message ("family kernel w %.2f px: %s", w, in.note);
  g_assert_true (in.computed);
  g_assert_false (in.unbounded);
  double lower = in.ratio * (LD + S * t[1]);
  g_assert_cmpfloat_with_epsilon (lower, LD, 1e-3 * LD);
  g_assert_cmpfloat_with_epsilon (in.kernel_px, w, 1e-3 * w);
}

/* A Gaussian kernel keeping 70 % at 32 px and 0.3 % at 8 px: the truth lies inside the interval,
 * between the family's lower end and the fit's Ld, and the lower end is under the truth by what
 * the family's slower tail hides (4735 DN: S / (1 - T) from the 1/k form at the measured ratio). */
static void
test_gaussian_kernel_within_noise (void)
{
  double s = 32 * sqrt (-log (0.7) / 2) / G_PI, t[G_N_ELEMENTS (periods)];
  for (guint i = 0; i < G_N_ELEMENTS (periods); i++)
    t[i] = gaussian_mtf (s, periods[i]);
  DsProbeDirectInterval in;
  interval_of (t, &in);
  g_test_message ("Gaussian kernel s %.2f px: %s", s, in.note);
  g_assert_true (in.computed);
  g_assert_false (in.unbounded);
  double fit = LD + S * t[1], lower = in.ratio * fit;
  g_assert_cmpfloat (lower, <=, LD);
  g_assert_cmpfloat (lower, >, LD - S);
  g_assert_cmpfloat (fit, >=, LD);
}

/* A drop steeper than any kernel of the family: the coarse period keeps all the light the mean
 * holds (T = 1 at 32 px) while 8 px has lost 45 % of it. No lower end. */
static void
test_steeper_than_the_family (void)
{
  double t[G_N_ELEMENTS (periods)] = { 0.55, 0.9, 1.0 };
  DsProbeDirectInterval in;
  interval_of (t, &in);
  g_assert_true (in.computed);
  g_assert_true (in.unbounded);
  /* and a loss at 32 px that is there but under (8/32)^2 of the one at 8 px: r = 0.05 */
  t[2] = 1 - 0.05 * (1 - t[0]);
  interval_of (t, &in);
  g_assert_true (in.unbounded);
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  g_test_add_func ("/probe-interval/family-kernel-within-noise", test_family_kernel_within_noise);
  g_test_add_func ("/probe-interval/gaussian-kernel-within-noise", test_gaussian_kernel_within_noise);
  g_test_add_func ("/probe-interval/steeper-than-the-family", test_steeper_than_the_family);
  return g_test_run ();
}
