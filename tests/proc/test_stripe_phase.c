/* Stripe phase of synthetic frames built from the project's pattern convention (written out
 * here independently): frame k of N must measure k/N. */
#include <glib.h>
#include <math.h>

#include "proc/phase_order.h"
#include "proc/proc_error.h"
#include "proc/stripe_phase.h"
#include "tests/common/test_random.h"

typedef struct {
  double period, duty, black;
  gboolean sine;
  double direct;    /* Ld: pattern-following light */
  double global;    /* Lg: scattered, pattern-blind */
  double noise;     /* Gaussian sigma per pixel */
} Scene;

/* value = Lg * mean(pattern) + Ld * (b + (1 - b) * pattern(u)), u = frac(x/P - k/N) in [-1/2, 1/2),
 * integrated over the pixel [x - 1/2, x + 1/2) as a sensor does (16 sub-samples). */
static DsImage *
render (const Scene *s, DsSampleType type, guint w, guint h, guint k, guint n, GRand *rand)
{
  DsImage *img = ds_image_new (type, w, h, NULL);
  g_assert_nonnull (img);
  double pattern_mean = s->sine ? 0.5 : s->duty;
  double lit_mean = s->black + (1.0 - s->black) * pattern_mean;
  for (guint y = 0; y < h; y++)
    for (guint x = 0; x < w; x++) {
      double pat = 0;
      for (int j = 0; j < 16; j++) {
        double u = ((double) x + (j + 0.5) / 16.0 - 0.5) / s->period - (double) k / n;
        u -= floor (u + 0.5);
        pat += (s->sine ? 0.5 * (1.0 + cos (2.0 * G_PI * u)) : (fabs (u) < s->duty / 2 ? 1.0 : 0.0)) / 16.0;
      }
      double v = s->global * lit_mean + s->direct * (s->black + (1.0 - s->black) * pat);
      if (s->noise > 0)
        v += s->noise * test_normal (rand);
      if (type == DS_SAMPLE_F32) {
        ((float *) ds_image_row (img, y))[x] = (float) v;
      } else {
        double top = type == DS_SAMPLE_U8 ? 255.0 : 65535.0;
        v = CLAMP (round (v), 0.0, top);
        if (type == DS_SAMPLE_U8)
          ((guint8 *) ds_image_row (img, y))[x] = (guint8) v;
        else
          ((guint16 *) ds_image_row (img, y))[x] = (guint16) v;
      }
    }
  return img;
}

static void
expect_phase (const DsImage *img, double period, const DsRegion *region, double want, double tol,
              DsStripePhase *m)
{
  g_autoptr (GError) error = NULL;
  g_assert_true (ds_stripe_phase_measure (img, period, region, m, &error));
  g_assert_no_error (error);
  g_assert_cmpfloat (m->phase, >=, 0.0);
  g_assert_cmpfloat (m->phase, <, 1.0);
  double d = fabs (ds_stripe_phase_diff (m->phase, want));
  if (d > tol)
    g_error ("phase %.5f, expected %.5f (tolerance %.4f, snr %.1f)", m->phase, want, tol, m->snr);
  g_assert_true (m->reliable);
}

static void
test_all_phases (void)
{
  static const double periods[] = { 16.0, 7.3, 12.75, 31.0 };
  for (gsize p = 0; p < G_N_ELEMENTS (periods); p++)
    for (guint n = 2; n <= 16; n++)
      for (guint k = 0; k < n; k++)
        for (int sine = 0; sine < 2; sine++) {
          Scene s = { periods[p], 0.5, 0.0, sine, 1000.0, 500.0, 0.0 };
          g_autoptr (DsImage) img = render (&s, DS_SAMPLE_U16, 203, 4, k, n, NULL);
          DsStripePhase m;
          /* Integer rounding and sampling a square wave at pixel centres bend the phase a little. */
          expect_phase (img, s.period, NULL, (double) k / n, 0.01, &m);
        }
}

static void
test_duty_black_types (void)
{
  GRand *rand = g_rand_new_with_seed (7);
  for (int t = 0; t < 3; t++) {
    DsSampleType type = t == 0 ? DS_SAMPLE_U8 : t == 1 ? DS_SAMPLE_U16 : DS_SAMPLE_F32;
    double scale = type == DS_SAMPLE_U8 ? 0.1 : 1.0;
    Scene s = { 10.4, 0.3, 0.1, FALSE, 1200.0 * scale, 600.0 * scale, 5.0 * scale };
    for (guint k = 0; k < 8; k++) {
      g_autoptr (DsImage) img = render (&s, type, 160, 12, k, 8, rand);
      DsStripePhase m;
      expect_phase (img, s.period, NULL, k / 8.0, 0.015, &m);
      /* Square wave, duty a, black b: first harmonic (2/pi) sin(pi a) (1 - b) Ld. The mean is
       * Lg * lit + Ld * lit. Sampling at pixel centres blurs the harmonic by a few percent. */
      double lit = s.black + (1 - s.black) * s.duty;
      double amp = 2.0 / G_PI * sin (G_PI * s.duty) * (1 - s.black) * s.direct;
      g_assert_cmpfloat_with_epsilon (m.amplitude, amp, 0.06 * amp);
      g_assert_cmpfloat_with_epsilon (m.mean, (s.global + s.direct) * lit, 0.02 * (s.global + s.direct) * lit);
    }
  }
  g_rand_free (rand);
}

static void
test_noise_and_heavy_scattering (void)
{
  GRand *rand = g_rand_new_with_seed (12345);
  /* Modulation 1 % of the mean: Ld = 404, Lg = 40000, sine pattern -> A = 202, M = 20202;
   * shot-like noise 140 DN per pixel. */
  Scene s = { 9.7, 0.5, 0.0, TRUE, 404.0, 40000.0, 140.0 };
  for (guint n = 3; n <= 12; n += 3)
    for (guint k = 0; k < n; k++) {
      g_autoptr (DsImage) img = render (&s, DS_SAMPLE_U16, 256, 64, k, n, rand);
      DsStripePhase m;
      expect_phase (img, s.period, NULL, (double) k / n, 0.01, &m);
      g_assert_cmpfloat_with_epsilon (m.modulation, 0.01, 0.002);
      /* Noise of the column means: 140/sqrt(64) = 17.5 DN; sigma_A ~ 17.5 sqrt(2/247) = 1.6 DN,
       * so snr should be near 202/1.6 = 130: generous bounds, but it must not be absurd. */
      g_assert_cmpfloat (m.snr, >, 60.0);
      g_assert_cmpfloat (m.snr, <, 300.0);
    }
  /* Square stripes at 1 % modulation with a u16 mean near full scale, non-integer period and a
   * region that is not a whole number of periods: the mean must not leak into the harmonic. */
  Scene sq = { 7.3, 0.5, 0.0, FALSE, 300.0, 59000.0, 60.0 };
  for (guint k = 0; k < 5; k++) {
    g_autoptr (DsImage) img = render (&sq, DS_SAMPLE_U16, 100, 32, k, 5, rand);
    DsStripePhase m;
    expect_phase (img, sq.period, NULL, k / 5.0, 0.02, &m);
    g_assert_cmpuint (m.periods_used, ==, 13);      /* floor(100 / 7.3) */
    g_assert_cmpuint (m.columns_used, ==, 95);      /* round(13 * 7.3) = round(94.9) */
  }
  g_rand_free (rand);
}

static void
test_pure_noise (void)
{
  /* No stripes at all: over many seeds, never "reliable"; the snr behaves like a Rayleigh
   * variable (mean sqrt(pi/2) = 1.25). */
  double snr_sum = 0;
  for (guint seed = 1; seed <= 40; seed++) {
    GRand *rand = g_rand_new_with_seed (seed);
    Scene s = { 11.0, 0.5, 0.0, TRUE, 0.0, 2000.0, 30.0 };
    g_autoptr (DsImage) img = render (&s, DS_SAMPLE_F32, 220, 16, 0, 1, rand);
    DsStripePhase m;
    g_autoptr (GError) error = NULL;
    g_assert_true (ds_stripe_phase_measure (img, s.period, NULL, &m, &error));
    g_assert_false (m.reliable);
    g_assert_cmpfloat (m.snr, <, DS_STRIPE_PHASE_MIN_SNR);
    snr_sum += m.snr;
    g_rand_free (rand);
  }
  g_assert_cmpfloat (snr_sum / 40, >, 0.8);
  g_assert_cmpfloat (snr_sum / 40, <, 1.8);
  /* A perfectly flat frame: amplitude 0, not reliable, no NaN. */
  Scene flat = { 11.0, 0.5, 0.0, TRUE, 0.0, 2000.0, 0.0 };
  g_autoptr (DsImage) img = render (&flat, DS_SAMPLE_U16, 64, 4, 0, 1, NULL);
  DsStripePhase m;
  g_assert_true (ds_stripe_phase_measure (img, 11.0, NULL, &m, NULL));
  g_assert_false (m.reliable);
  g_assert_true (isfinite (m.phase) && isfinite (m.snr) && isfinite (m.confidence));
}

static void
test_region_and_nonfinite (void)
{
  Scene s = { 13.0, 0.5, 0.0, FALSE, 800.0, 200.0, 0.0 };
  g_autoptr (DsImage) img = render (&s, DS_SAMPLE_F32, 300, 40, 3, 7, NULL);
  /* An opaque object in the left half must not matter to a region on the right. */
  for (guint y = 0; y < 40; y++)
    for (guint x = 0; x < 120; x++)
      ((float *) ds_image_row (img, y))[x] = (x * 7919u + y * 104729u) % 97u;
  /* NaN in a few pixels and one whole column of the region. */
  for (guint y = 0; y < 40; y++)
    ((float *) ds_image_row (img, y))[200] = NAN;
  ((float *) ds_image_row (img, 5))[150] = INFINITY;
  DsRegion r = { 133, 10, 150, 20 };
  DsStripePhase m;
  expect_phase (img, s.period, &r, 3.0 / 7, 0.01, &m);
  g_assert_cmpuint (m.periods_used, ==, 11);      /* floor(150 / 13) */
  g_assert_cmpuint (m.columns_used, ==, 143 - 1); /* one column is NaN throughout */
}

/* The column sums against sums taken one sample at a time in long double, each sample read
 * by its own type: exact for integer frames (the tallest frame, nearly all at the largest
 * sample, takes a column's sum past 2^31), the finite samples alone for F32, in a region away
 * from the frame's origin. */
static void
test_column_sums (void)
{
  const DsSampleType types[] = { DS_SAMPLE_U8, DS_SAMPLE_U16, DS_SAMPLE_F32 };
  for (guint t = 0; t < G_N_ELEMENTS (types); t++) {
    guint w = 37, h = types[t] == DS_SAMPLE_F32 ? 300 : DS_IMAGE_MAX_SIDE;
    g_autoptr (DsImage) img = ds_image_new (types[t], w, h, NULL);
    for (guint y = 0; y < h; y++)
      for (guint x = 0; x < w; x++) {
        guint v = (x * 7919u + y * 104729u) % 65536u;
        void *row = ds_image_row (img, y);
        if (types[t] == DS_SAMPLE_U8)
          ((guint8 *) row)[x] = (guint8) (y % 50 ? 255 : v);
        else if (types[t] == DS_SAMPLE_U16)
          ((guint16 *) row)[x] = (guint16) (y % 50 ? 65535 : v);
        else
          ((float *) row)[x] = (x == 20 || (x + y) % 11 == 0) ? NAN : (float) v / 7.0f;
      }
    const guint x0 = 3, y0 = 2, cols = 30, rows = h - 5;
    double sum[30];
    guint32 count[30];
    ds_stripe_phase_column_sums (img, x0, y0, cols, rows, sum, count);
    for (guint i = 0; i < cols; i++) {
      long double ref = 0;
      guint32 n = 0;
      for (guint y = y0; y < y0 + rows; y++) {
        const void *row = ds_image_row (img, y);
        long double v = types[t] == DS_SAMPLE_U8    ? ((const guint8 *) row)[x0 + i]
                        : types[t] == DS_SAMPLE_U16 ? ((const guint16 *) row)[x0 + i]
                                                    : ((const float *) row)[x0 + i];
        if (isfinite (v)) {
          ref += v;
          n++;
        }
      }
      g_assert_cmpuint (count[i], ==, n);
      if (types[t] == DS_SAMPLE_F32)
        g_assert_cmpfloat (fabsl (sum[i] - ref), <=, 1e-12L * fabsl (ref) + 1e-9L);
      else
        g_assert_cmpfloat (sum[i], ==, (double) ref);
    }
  }
}

static void
test_errors (void)
{
  g_autoptr (DsImage) img = ds_image_new (DS_SAMPLE_U16, 50, 4, NULL);
  DsStripePhase m;
  struct { double period; DsRegion r; } bad[] = {
    { 2.0, { 0, 0, 0, 0 } },   /* Nyquist */
    { 51.0, { 0, 0, 0, 0 } },  /* longer than the frame */
    { NAN, { 0, 0, 0, 0 } },
    { 10.0, { 50, 0, 0, 0 } }, /* origin outside */
    { 10.0, { 45, 0, 10, 0 } },/* extends outside */
    { 10.0, { 0, 0, 9, 0 } },  /* narrower than a period */
  };
  for (gsize i = 0; i < G_N_ELEMENTS (bad); i++) {
    g_autoptr (GError) error = NULL;
    g_assert_false (ds_stripe_phase_measure (img, bad[i].period, &bad[i].r, &m, &error));
    g_assert_error (error, DS_PROC_ERROR, DS_PROC_ERROR_INVALID_ARGUMENT);
  }
  g_assert_cmpfloat_with_epsilon (ds_stripe_phase_diff (0.95, 0.05), -0.1, 1e-12);
  g_assert_cmpfloat_with_epsilon (ds_stripe_phase_diff (0.05, 0.95), 0.1, 1e-12);
}

/* The order of phases from measured phases: the offset found by the majority, one swap
 * reordered, a duplicate or an in-between frame broken, unmeasured frames taken as given. */
static void
test_phase_order_check (void)
{
  const guint n = 8;
  const double off = 0.37, tol = 0.25 / n;
  DsPhaseOrderFrame fr[8];
  double offset;
  /* all right, offset unknown: found as the common offset */
  for (guint k = 0; k < n; k++)
    fr[k] = (DsPhaseOrderFrame) { .given = k, .measured = TRUE, .phase = fmod (k / 8.0 + off + 0.003 * (k % 3), 1) };
  g_assert_cmpint (ds_phase_order_check (fr, n, n, tol, FALSE, &offset), ==, DS_PHASE_ORDER_OK);
  g_assert_cmpfloat (fabs (offset - off - 0.003), <, 0.003);
  /* frames 0 and 5 swapped: reordered, whichever frame is first */
  fr[0].phase = fmod (5 / 8.0 + off, 1);
  fr[5].phase = fmod (0 / 8.0 + off, 1);
  g_assert_cmpint (ds_phase_order_check (fr, n, n, tol, FALSE, &offset), ==, DS_PHASE_ORDER_REORDERED);
  g_assert_cmpint (fr[0].found, ==, 5);
  g_assert_cmpint (fr[5].found, ==, 0);
  g_assert_cmpint (fr[3].found, ==, 3);
  /* frame 5 shows phase 4 too: phase 5 has none */
  fr[0].phase = off;
  fr[5].phase = fmod (4 / 8.0 + off, 1);
  g_assert_cmpint (ds_phase_order_check (fr, n, n, tol, FALSE, &offset), ==, DS_PHASE_ORDER_BROKEN);
  g_assert_cmpint (fr[5].found, ==, 4);
  /* ... unless it cannot be measured: taken as given */
  fr[5].measured = FALSE;
  g_assert_cmpint (ds_phase_order_check (fr, n, n, tol, FALSE, &offset), ==, DS_PHASE_ORDER_OK);
  g_assert_cmpint (fr[5].found, ==, -1);
  /* half a step off: between phases */
  fr[5].measured = TRUE;
  fr[5].phase = fmod (5.5 / 8.0 + off, 1);
  g_assert_cmpint (ds_phase_order_check (fr, n, n, tol, FALSE, &offset), ==, DS_PHASE_ORDER_BROKEN);
  g_assert_cmpint (fr[5].found, ==, -1);
  g_assert_cmpfloat (fabs (fabs (fr[5].residual) - 0.5 / 8), <, 0.005); /* the offset is the frames' mean */
  /* a known offset is used as given: every frame off by a whole phase */
  for (guint k = 0; k < n; k++)
    fr[k] = (DsPhaseOrderFrame) { .given = k, .measured = TRUE, .phase = fmod ((k + 1) / 8.0 + off, 1) };
  offset = off;
  g_assert_cmpint (ds_phase_order_check (fr, n, n, tol, TRUE, &offset), ==, DS_PHASE_ORDER_REORDERED);
  g_assert_cmpfloat (offset, ==, off);
  g_assert_cmpint (fr[7].found, ==, 0);
  /* nothing measured */
  for (guint k = 0; k < n; k++)
    fr[k].measured = FALSE;
  g_assert_cmpint (ds_phase_order_check (fr, n, n, tol, FALSE, &offset), ==, DS_PHASE_ORDER_UNKNOWN);
  g_assert_true (isnan (offset));
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  g_test_add_func ("/stripe-phase/all-phases", test_all_phases);
  g_test_add_func ("/stripe-phase/duty-black-types", test_duty_black_types);
  g_test_add_func ("/stripe-phase/noise-heavy-scattering", test_noise_and_heavy_scattering);
  g_test_add_func ("/stripe-phase/pure-noise", test_pure_noise);
  g_test_add_func ("/stripe-phase/region-nonfinite", test_region_and_nonfinite);
  g_test_add_func ("/stripe-phase/errors", test_errors);
  g_test_add_func ("/stripe-phase/column-sums", test_column_sums);
  g_test_add_func ("/phase-order/check", test_phase_order_check);
  return g_test_run ();
}
