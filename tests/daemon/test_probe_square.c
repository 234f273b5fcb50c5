/* Square stripes of a duty other than 1/2 over objects (issue 12: gen-16-07, gen-13-06): the
 * pilot pair's harmonics fitted on the scene's envelope once the stripes' even harmonics, which
 * such stripes' opposite phases share, are taken off it (daemon/operating/scene_probe_pairs.c).
 * Against independent expectations: frames in closed form, the stripes' Fourier series
 *     pattern(x) = a + sum_n (2 / (n pi)) sin (n pi a) exp (-2 pi^2 s^2 n^2 / Q^2) sinc (n / Q)
 *                      cos (2 pi n (x / Q - shift))
 * (a blurred square wave integrated over the whole pixel), times each column's light, plus
 * scattered light of a Gaussian kernel whose MTF multiplies every harmonic, so that the
 * difference of two opposite phases has the harmonic n (odd) of amplitude
 *     2 Ld c_n (1 + beta mtf_n)
 * on a scene whose light is the same in every column; and the simulator's own truth for
 * gen-16-07 rendered (no medium: no scattered light at all). */
#include <glib.h>
#include <math.h>
#include <string.h>

#include "daemon/operating/scene_probe.h"
#include "daemon/operating/scene_probe_pairs.h"
#include "daemon/operating/stripe_model.h"
#include "probe_rig.h"
#include "tests/test_random.h"

#define W 256
#define H 96

typedef struct {
  double period, duty, blur;   /* square stripes, black level 0 */
  double ld, dark;             /* DN */
  double beta, kernel_px;      /* scattered light of a Gaussian kernel: its light over Ld, its sigma */
  gboolean objects;            /* gen-16-07's three grids in front of the stripes */
} Scene;

/* The columns' transmission: gen-16-07's grids (pitch 58 with opaque 3 px lines, pitch 54 with
 * 11 px lines of 0.128, pitch 42 with 3 px lines of 0.662), or 1. */
static double
transmission (const Scene *s, guint x)
{
  if (!s->objects)
    return 1.0;
  double t = 1.0;
  t *= fmod (x + 5.0, 58) < 3 ? 0.0 : 1.0;
  t *= fmod (x + 17.0, 54) < 11 ? 0.128 : 1.0;
  t *= fmod (x + 2.0, 42) < 3 ? 0.662 : 1.0;
  return t;
}

static double
coefficient (const Scene *s, double period, guint n)
{
  double k = G_PI * n / period;
  return 2 / (n * G_PI) * sin (n * G_PI * s->duty) * exp (-2 * k * k * s->blur * s->blur) * sin (k) / k;
}

static double
kernel_mtf (const Scene *s, double period, guint n)
{
  double k = G_PI * n / period;
  return exp (-2 * k * k * s->kernel_px * s->kernel_px);
}

/* One lit frame at phase shift `shift` (cycles), with shot and read noise. */
static DsImage *
frame (const Scene *s, double period, double shift, GRand *r)
{
  DsImage *f = ds_image_new (DS_SAMPLE_F32, W, H, NULL);
  double profile[W];
  for (guint x = 0; x < W; x++) {
    double v = s->duty * (1 + s->beta);
    for (guint n = 1; n < 300; n++)
      v += coefficient (s, period, n) * (1 + s->beta * kernel_mtf (s, period, n)) *
           cos (2 * G_PI * n * (x / period - shift));
    profile[x] = s->ld * transmission (s, x) * v;
  }
  for (guint y = 0; y < H; y++) {
    float *row = ds_image_row (f, y);
    for (guint x = 0; x < W; x++)
      row[x] = (float) (s->dark + profile[x] + sqrt (4.0 + 0.25 * profile[x]) * test_normal (r));
  }
  return f;
}

static double
mean_transmission (const Scene *s)
{
  double t = 0;
  for (guint x = 0; x < W; x++)
    t += transmission (s, x);
  return t / W;
}

/* The pairs at `periods` fitted as the probe fits them: plainly, then (with_pattern) refitted on
 * the envelope with the calibrated pattern, the light per harmonic read off all their first
 * harmonics (ds_probe_pairs_refit_pattern ()). */
static void
fit_pairs (const Scene *s, const double *periods, guint n, gboolean with_pattern, DsStripeHarmonics *out)
{
  g_autoptr (GRand) r = g_rand_new_with_seed (7);
  DsProbePairFit fits[4];
  DsProbePairFit *pairs[4];
  g_assert_cmpuint (n, <=, 4);
  memset (fits, 0, sizeof fits);
  for (guint i = 0; i < n; i++) {
    g_autoptr (DsImage) a = frame (s, periods[i], 0.1, r);
    g_autoptr (DsImage) b = frame (s, periods[i], 0.6, r);
    g_autoptr (GError) error = NULL;
    gboolean ok = ds_probe_pair_fit (a, b, a, b, INFINITY, periods[i], -1, &fits[i], &error);
    g_assert_no_error (error);
    g_assert_true (ok);
    pairs[i] = &fits[i];
  }
  DsStripeModel pattern = { DS_PATTERN_SQUARE, s->period, s->duty, 0, s->blur, 0 };
  if (with_pattern)
    ds_probe_pairs_refit_pattern (pairs, periods, n, s->dark, &pattern);
  for (guint i = 0; i < n; i++) {
    out[i] = fits[i].fit;
    ds_column_stats_clear (&fits[i].stats);
  }
}

/* The share by which harmonic n of the fit misses the closed form's. */
static double
harmonic_error (const Scene *s, const DsStripeHarmonics *h, double period, guint n)
{
  double want = 2 * s->ld * mean_transmission (s) * coefficient (s, period, n) * (1 + s->beta * kernel_mtf (s, period, n));
  return h->amplitude[n] / fabs (want) - 1;
}

/* gen-16-07 in closed form: duty 0.466 at 8.25 px, blur 0.36 px, three grids, no scattered light.
 * The grids' pitch harmonics next to the stripes' even ones beat with them in the column profile;
 * the pair's sum holds the stripes' even harmonics (its second 11 % of its mean). On the envelope
 * every odd harmonic at P, 2P and P/2 is the closed form's within the 2 % the probe's transfer fit
 * allows each harmonic (what is left: the objects' variation times the stripes' even harmonics in
 * the envelope: 1.3 % on the third at P, under 0.7 % on the others); the plain fit misses one of
 * them by more than 5 % (asserted, so that the case shows what it is about). */
static void
test_objects_closed_form (void)
{
  Scene s = { .period = 8.25, .duty = 0.466, .blur = 0.36, .ld = 3500, .dark = 50, .objects = TRUE };
  const double periods[] = { 8.25, 16.5, 4.125 };
  double worst_plain = 0;
  DsStripeHarmonics env[3], plain[3];
  fit_pairs (&s, periods, 3, TRUE, env);
  fit_pairs (&s, periods, 3, FALSE, plain);
  for (guint i = 0; i < G_N_ELEMENTS (periods); i++) {
    for (guint n = 1; n <= env[i].n_harmonics && periods[i] / n >= 2.5; n += 2) {
      double e = harmonic_error (&s, &env[i], periods[i], n), p = harmonic_error (&s, &plain[i], periods[i], n);
      g_test_message ("period %.3f harmonic %u: on the envelope %+.4f, plain %+.4f", periods[i], n, e, p);
      g_assert_cmpfloat (fabs (e), <, 0.02);
      worst_plain = MAX (worst_plain, fabs (p));
    }
  }
  g_assert_cmpfloat (worst_plain, >, 0.05);
}

/* gen-16-09 without its objects, in closed form: duty 0.564 at 13.75 px, sharp stripes, scattered
 * light of 0.56 Ld in a Gaussian kernel keeping 72 % of it modulated at P and 27 % at P/2. The
 * sum's even harmonics (a fifth of its mean) carry the kernel's transfer at their own Q/k, which
 * the pairs' odd harmonics give to a few % only where the transfer is steep: taken off the
 * envelope, what is left of them beats with the first harmonic onto the others (the fifth 13 %
 * off at P, 19 % at 2P). Without objects the envelope has nothing to gain, so the plain fit must
 * stay and every odd harmonic at P and 2P be the closed form's to 1 %. (The plain fit before this
 * change was that already: this case guards the envelope's rule, not a miss it cured.) */
static void
test_scattered_even_harmonics (void)
{
  Scene s = { .period = 13.75, .duty = 0.564, .blur = 0, .ld = 4200, .dark = 50, .beta = 0.56 };
  s.kernel_px = sqrt (-log (0.72) / 2) * s.period / G_PI;
  const double periods[] = { 13.75, 27.5, 6.875 };
  DsStripeHarmonics env[3];
  fit_pairs (&s, periods, 3, TRUE, env);
  for (guint i = 0; i < 2; i++) {
    for (guint n = 1; n <= 5; n += 2) {
      double e = harmonic_error (&s, &env[i], periods[i], n);
      g_test_message ("period %.2f harmonic %u (kernel MTF %.3f): on the envelope %+.4f", periods[i], n,
                      kernel_mtf (&s, periods[i], n), e);
      g_assert_cmpfloat (fabs (e), <, 0.01);
    }
  }
}

/* Generated scene 16-7 rendered: no medium, three grids (one opaque), square stripes of duty
 * 0.466 at 8.25 px. The probe read Lg 100 DN against 0 and 3.0 % of scattered stripes at P, and
 * two requests were predicted x2.5 their achieved error. The leak at P and Lg must stay under
 * 1 % of Ld, Ld within 1 % of the renderer's. */
static void
test_gen_16_07 (void)
{
  static const char text[] =
    "[scene]\nname=generated 16-7\n\n"
    "[sensor]\nwidth=256\nheight=192\nbit-depth=14\npixel-pitch-um=5.31027\nquantum-efficiency=0.573532\n"
    "system-gain=0.429875\nread-noise-e=4.16334\ndark-current-e-per-s=11.1142\nfull-well-e=27496.8\n"
    "exposure-us=4832\n\n"
    "[illuminator]\npattern=square\nperiod-px=8.25\nduty=0.466065\nedge-blur-px=0.359198\nirradiance=1\n\n"
    "[camera]\nmagnification=0.0754951\nacceptance-half-angle-deg=16.0949\n\n"
    "[object.o0]\nshape=grid\npitch=58\nline-width=3\ntransmittance=0\n\n"
    "[object.o1]\nshape=grid\npitch=54\nline-width=11\ntransmittance=0.128333\n\n"
    "[object.o2]\nshape=grid\npitch=42\nline-width=3\ntransmittance=0.662292\n";
  DsValidateScene vs;
  double truth;
  probe_rig_probe_scene (text, "gen-16-07", &vs, &truth, NULL);
  double leak = ds_scene_probe_leak (&vs.probe, vs.probe.geometry.period_px, 1);
  g_test_message ("gen-16-07: scattered stripes at P %.4f (truth %.4f), Ld %.1f (truth %.1f), Lg %.1f", leak, truth,
                  vs.probe.ld_mean, vs.truth_ld_mean, vs.probe.lg_mean);
  g_assert_cmpfloat (truth, ==, 0);
  g_assert_cmpfloat (leak, <, 0.01);
  g_assert_cmpfloat (vs.probe.lg_mean, <, 0.01 * vs.truth_ld_mean);
  g_assert_cmpfloat (fabs (vs.probe.ld_mean / vs.truth_ld_mean - 1), <, 0.01);
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  g_test_add_func ("/probe-square/objects-closed-form", test_objects_closed_form);
  g_test_add_func ("/probe-square/scattered-even-harmonics", test_scattered_even_harmonics);
  g_test_add_func ("/probe-square/gen-16-07", test_gen_16_07);
  return g_test_run ();
}
