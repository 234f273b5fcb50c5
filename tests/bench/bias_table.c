/* ds-bias-table: noise bias and spread of the estimators vs N, measured through the real
 * phase-set API on synthetic f32 frames (the table in docs/estimators.md).
 *
 * Square stripes, a = 1/2, b = 0, period 7.31 px (so pixels sample every stripe position),
 * Gaussian noise of sigma = 1 per frame. For each N and estimator:
 *   modulated pixels (Ld = 50, Lg = 100): bias = mean(Ld_noisy - Ld_noise_free) and its
 *   standard deviation, so that the estimator's deterministic error (e.g. the sine
 *   estimator's aliasing on square stripes) is not counted as noise bias; same for Lg;
 *   unmodulated pixels (Ld = 0, Lg = 100): mean Ld, the bias a blank region shows.
 * All numbers in units of sigma.
 *
 *   ds-bias-table [--quick] [--pixels WxH] [--seed S]
 * Prints a Markdown table. --quick: fewer N and pixels (the ctest smoke run). */
#include <glib.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "proc/separation.h"

static double
gauss (GRand *r)
{
  double u1 = g_rand_double_range (r, 1e-300, 1.0), u2 = g_rand_double (r);
  return sqrt (-2 * log (u1)) * cos (2 * G_PI * u2);
}

static double
square (double x, double period, guint k, guint n)
{
  double u = x / period - (double) k / n;
  u -= floor (u + 0.5);
  return fabs (u) < 0.25 ? 1.0 : 0.0;
}

/* Separates one synthetic set; returns the result or exits on error. */
static DsSeparation *
run (DsEstimator est, guint n, guint w, guint h, double ld, double lg, double sigma, GRand *r)
{
  DsSeparationParams p;
  ds_separation_params_init (&p, n);
  p.estimator = est;
  g_autoptr (GError) error = NULL;
  g_autoptr (DsPhaseSet) set = ds_phase_set_new (&p, w, h, &error);
  if (!set) {
    fprintf (stderr, "ds-bias-table: %s\n", error->message);
    exit (1);
  }
  g_autoptr (DsImage) f = ds_image_new (DS_SAMPLE_F32, w, h, NULL);
  for (guint k = 0; k < n; k++) {
    for (guint y = 0; y < h; y++) {
      float *row = ds_image_row (f, y);
      for (guint x = 0; x < w; x++)
        row[x] = (float) (ld * square (x + 0.37 * y, 7.31, k, n) + lg * 0.5 +
                          (sigma > 0 ? sigma * gauss (r) : 0));
    }
    if (!ds_phase_set_accumulate (set, k, f, &error)) {
      fprintf (stderr, "ds-bias-table: %s\n", error->message);
      exit (1);
    }
  }
  DsSeparation *sep = ds_phase_set_finalize (set, &error);
  if (!sep) {
    fprintf (stderr, "ds-bias-table: %s\n", error->message);
    exit (1);
  }
  return sep;
}

typedef struct {
  double ld_bias, ld_sd, lg_bias, zero_bias;
} Stats;

static Stats
measure (DsEstimator est, guint n, guint w, guint h, GRand *r)
{
  Stats s = { 0 };
  g_autoptr (DsSeparation) clean = run (est, n, w, h, 50, 100, 0, r);
  g_autoptr (DsSeparation) noisy = run (est, n, w, h, 50, 100, 1.0, r);
  g_autoptr (DsSeparation) blank = run (est, n, w, h, 0, 100, 1.0, r);
  double s1 = 0, s2 = 0, g1 = 0, z1 = 0;
  for (guint y = 0; y < h; y++) {
    const float *t0 = ds_image_row (clean->transmissive, y), *t1 = ds_image_row (noisy->transmissive, y);
    const float *g0 = ds_image_row (clean->scattered, y), *gg = ds_image_row (noisy->scattered, y);
    const float *tz = ds_image_row (blank->transmissive, y);
    for (guint x = 0; x < w; x++) {
      double d = (double) t1[x] - t0[x];
      s1 += d;
      s2 += d * d;
      g1 += (double) gg[x] - g0[x];
      z1 += tz[x];
    }
  }
  double cnt = (double) w * h;
  s.ld_bias = s1 / cnt;
  s.ld_sd = sqrt (MAX (0.0, s2 / cnt - s.ld_bias * s.ld_bias));
  s.lg_bias = g1 / cnt;
  s.zero_bias = z1 / cnt;
  return s;
}

int
main (int argc, char **argv)
{
  guint w = 512, h = 256, seed = 1;
  gboolean quick = FALSE;
  for (int i = 1; i < argc; i++) {
    if (strcmp (argv[i], "--quick") == 0) {
      quick = TRUE;
      w = 64;
      h = 32;
    } else if (strcmp (argv[i], "--pixels") == 0 && i + 1 < argc &&
               sscanf (argv[i + 1], "%ux%u", &w, &h) == 2 && w > 0 && h > 0) {
      i++;
    } else if (strcmp (argv[i], "--seed") == 0 && i + 1 < argc) {
      seed = (guint) atoi (argv[++i]);
    } else {
      fprintf (stderr, "usage: %s [--quick] [--pixels WxH] [--seed S]\n", argv[0]);
      return 2;
    }
  }
  const guint full[] = { 2, 3, 4, 6, 8, 12, 16, 32, 64 };
  const guint small[] = { 2, 3, 8 };
  const guint *ns = quick ? small : full;
  guint n_ns = quick ? G_N_ELEMENTS (small) : G_N_ELEMENTS (full);
  GRand *r = g_rand_new_with_seed (seed);

  printf ("Noise bias and spread in units of the per-frame noise sigma; square stripes a = 1/2,\n"
          "b = 0; modulated: Ld = 50, Lg = 100 sigma; blank: Ld = 0. %ux%u pixels per cell.\n\n",
          w, h);
  printf ("| N | maxmin Ld bias | maxmin Ld sd | maxmin Lg bias | robust Ld bias | robust Ld sd | "
          "robust Lg bias | sine Ld bias | sine Ld sd | sine Lg bias | blank Ld: maxmin | robust | sine |\n");
  printf ("|---|---|---|---|---|---|---|---|---|---|---|---|---|\n");
  for (guint i = 0; i < n_ns; i++) {
    guint n = ns[i];
    Stats mm = measure (DS_ESTIMATOR_MAXMIN, n, w, h, r);
    Stats rb = measure (DS_ESTIMATOR_ROBUST, n, w, h, r);
    Stats sn = { NAN, NAN, NAN, NAN };
    if (n >= 3)
      sn = measure (DS_ESTIMATOR_SINE, n, w, h, r);
    printf ("| %u | %+.2f | %.2f | %+.2f | %+.2f | %.2f | %+.2f | %+.2f | %.2f | %+.2f | %+.2f | %+.2f | %+.2f |\n", n,
            mm.ld_bias, mm.ld_sd, mm.lg_bias, rb.ld_bias, rb.ld_sd, rb.lg_bias, sn.ld_bias, sn.ld_sd,
            sn.lg_bias, mm.zero_bias, rb.zero_bias, sn.zero_bias);
  }
  g_rand_free (r);
  return 0;
}
