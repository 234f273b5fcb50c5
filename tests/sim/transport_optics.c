/* Fresnel equations, the Henyey-Greenstein phase function and the random generator, each
 * against a closed form or a differently computed quantity. */
#include <math.h>

#include "drivers/sim/fresnel.h"
#include "drivers/sim/henyey_greenstein.h"
#include "drivers/sim/rng.h"

static double
deg (double d)
{
  return d * G_PI / 180.0;
}

static void
test_fresnel_normal_incidence (void)
{
  const double pairs[][2] = { { 1.0, 1.5 }, { 1.5, 1.0 }, { 1.0, 1.33 }, { 1.33, 1.5 }, { 1.4, 1.4 } };
  for (guint i = 0; i < G_N_ELEMENTS (pairs); i++) {
    double n1 = pairs[i][0], n2 = pairs[i][1];
    double expect = pow ((n1 - n2) / (n1 + n2), 2);
    g_assert_cmpfloat_with_epsilon (ds_fresnel_reflectance (n1, n2, 1.0), expect, 1e-14);
  }
  g_assert_cmpfloat_with_epsilon (ds_fresnel_reflectance (1.0, 1.5, 1.0), 0.04, 1e-14);
}

/* The s/p reflectances in the textbook angle form: rs = sin^2(ti-tt)/sin^2(ti+tt),
 * rp = tan^2(ti-tt)/tan^2(ti+tt), with tt from Snell's law. */
static void
test_fresnel_angle_form (void)
{
  const double pairs[][2] = { { 1.0, 1.5 }, { 1.5, 1.0 }, { 1.33, 1.0 }, { 1.0, 2.4 } };
  for (guint i = 0; i < G_N_ELEMENTS (pairs); i++)
    for (double a = 5; a < 89; a += 7) {
      double n1 = pairs[i][0], n2 = pairs[i][1], ti = deg (a);
      double st = n1 / n2 * sin (ti);
      if (st >= 1.0)
        continue;
      double tt = asin (st);
      double rs_e = pow (sin (ti - tt) / sin (ti + tt), 2);
      double rp_e = pow (tan (ti - tt) / tan (ti + tt), 2);
      double rs, rp;
      ds_fresnel_reflectance_sp (n1, n2, cos (ti), &rs, &rp);
      g_assert_cmpfloat_with_epsilon (rs, rs_e, 1e-12);
      g_assert_cmpfloat_with_epsilon (rp, rp_e, 1e-12);
      g_assert_cmpfloat_with_epsilon (ds_fresnel_reflectance (n1, n2, cos (ti)), 0.5 * (rs_e + rp_e), 1e-12);
      g_assert_cmpfloat_with_epsilon (ds_fresnel_cos_transmitted (n1, n2, cos (ti)), cos (tt), 1e-12);
    }
}

static void
test_fresnel_total_internal_reflection (void)
{
  double critical = asin (1.0 / 1.5) * 180.0 / G_PI; /* 41.81 degrees */
  g_assert_cmpfloat (ds_fresnel_reflectance (1.5, 1.0, cos (deg (critical - 0.5))), <, 1.0);
  g_assert_cmpfloat (ds_fresnel_reflectance (1.5, 1.0, cos (deg (critical + 0.01))), ==, 1.0);
  g_assert_cmpfloat (ds_fresnel_reflectance (1.5, 1.0, cos (deg (80))), ==, 1.0);
  g_assert_cmpfloat (ds_fresnel_cos_transmitted (1.5, 1.0, cos (deg (60))), ==, 0.0);
  /* From the optically thinner side there is no critical angle. */
  g_assert_cmpfloat (ds_fresnel_reflectance (1.0, 1.5, cos (deg (89))), <, 1.0);
  /* Grazing incidence reflects everything. */
  g_assert_cmpfloat_with_epsilon (ds_fresnel_reflectance (1.0, 1.5, 0.0), 1.0, 1e-12);
}

static void
test_fresnel_brewster (void)
{
  const double pairs[][2] = { { 1.0, 1.5 }, { 1.5, 1.0 }, { 1.0, 1.33 } };
  for (guint i = 0; i < G_N_ELEMENTS (pairs); i++) {
    double tb = atan (pairs[i][1] / pairs[i][0]);
    double rs, rp;
    ds_fresnel_reflectance_sp (pairs[i][0], pairs[i][1], cos (tb), &rs, &rp);
    g_assert_cmpfloat (rp, <, 1e-20);
    g_assert_cmpfloat (rs, >, 0.01);
  }
}

/* Hemispherical reflectances inside and outside obey r_in = 1 - (1 - r_out)/n^2 (etendue);
 * for n = 1.4 the Egan & Hilgeman fit -1.440/n^2 + 0.710/n + 0.668 + 0.0636 n gives 0.529. */
static void
test_fresnel_diffuse (void)
{
  g_assert_cmpfloat (ds_fresnel_diffuse_reflectance (1.3, 1.3), ==, 0.0);
  for (double n = 1.1; n < 2.0; n += 0.2) {
    double r_in = ds_fresnel_diffuse_reflectance (n, 1.0), r_out = ds_fresnel_diffuse_reflectance (1.0, n);
    g_assert_cmpfloat_with_epsilon (r_in, 1.0 - (1.0 - r_out) / (n * n), 2e-4);
  }
  double fit = -1.440 / (1.4 * 1.4) + 0.710 / 1.4 + 0.668 + 0.0636 * 1.4;
  g_assert_cmpfloat_with_epsilon (ds_fresnel_diffuse_reflectance (1.4, 1.0), fit, 0.01);
}

/* Simpson integral of f over [a, b]. */
static double
simpson (double (*f) (double, double), double g, double a, double b, int n)
{
  double h = (b - a) / n, s = f (g, a) + f (g, b);
  for (int i = 1; i < n; i++)
    s += (i % 2 ? 4 : 2) * f (g, a + i * h);
  return s * h / 3.0;
}

static double
hg_mu_pdf (double g, double mu)
{
  return mu * ds_hg_pdf (g, mu);
}

static void
test_hg_cdf_numeric (void)
{
  const double gs[] = { -0.7, -0.2, 0.0, 0.3, 0.75, 0.9 };
  for (guint i = 0; i < G_N_ELEMENTS (gs); i++) {
    double g = gs[i];
    g_assert_cmpfloat_with_epsilon (simpson (ds_hg_pdf, g, -1, 1, 20000), 1.0, 1e-6);
    g_assert_cmpfloat_with_epsilon (simpson (hg_mu_pdf, g, -1, 1, 20000), g, 1e-6);
    for (double mu = -0.95; mu < 1.0; mu += 0.15)
      g_assert_cmpfloat_with_epsilon (ds_hg_cdf (g, mu), simpson (ds_hg_pdf, g, -1, mu, 20000), 1e-6);
    /* Forward fraction derived by hand: (1+g)/(2g) - (1-g^2)/(2g sqrt(1+g^2)), 1/2 at g = 0. */
    double f = fabs (g) < 1e-9 ? 0.5 : (1 + g) / (2 * g) - (1 - g * g) / (2 * g * sqrt (1 + g * g));
    g_assert_cmpfloat_with_epsilon (ds_hg_forward_fraction (g), f, 1e-12);
  }
}

/* Sampled mean cosine = g within 4 standard errors; the sample distribution matches the CDF
 * (Kolmogorov-Smirnov distance below the 0.1 % critical value 1.95/sqrt(N)). */
static void
test_hg_sampling (void)
{
  const double gs[] = { -0.5, 0.0, 0.3, 0.75, 0.9, 0.99 };
  const int n = 400000;
  for (guint i = 0; i < G_N_ELEMENTS (gs); i++) {
    double g = gs[i];
    DsRng rng;
    ds_rng_seed (&rng, 1000 + i);
    double s = 0, s2 = 0;
    for (int k = 0; k < n; k++) {
      double mu = ds_hg_sample_cos (g, ds_rng_uniform (&rng));
      g_assert_cmpfloat (mu, >=, -1.0);
      g_assert_cmpfloat (mu, <=, 1.0);
      s += mu;
      s2 += mu * mu;
    }
    double mean = s / n, se = sqrt ((s2 / n - mean * mean) / n);
    g_assert_cmpfloat (fabs (mean - g), <, 4 * se);
    /* KS on a grid of mu: the empirical CDF from the sorted-free count. */
    const int bins = 200;
    int *count = g_new0 (int, bins + 1);
    ds_rng_seed (&rng, 2000 + i);
    for (int k = 0; k < n; k++) {
      double mu = ds_hg_sample_cos (g, ds_rng_uniform (&rng));
      count[(int) floor ((mu + 1.0) / 2.0 * bins)]++;
    }
    double cum = 0, ks = 0;
    for (int b = 0; b < bins; b++) {
      cum += count[b];
      ks = MAX (ks, fabs (cum / n - ds_hg_cdf (g, -1.0 + 2.0 * (b + 1) / bins)));
    }
    g_free (count);
    g_assert_cmpfloat (ks, <, 1.95 / sqrt (n));
  }
}

static void
test_rng_reproducible_streams (void)
{
  DsRng a, b, c, d;
  ds_rng_seed (&a, 42);
  ds_rng_seed (&b, 42);
  ds_rng_seed (&c, 43);
  ds_rng_seed_stream (&d, 42, 1);
  gboolean differ_seed = FALSE, differ_stream = FALSE;
  for (int i = 0; i < 100; i++) {
    guint64 x = ds_rng_next (&a), y = ds_rng_next (&b);
    g_assert_cmpuint (x, ==, y);
    differ_seed |= ds_rng_next (&c) != x;
    differ_stream |= ds_rng_next (&d) != x;
  }
  g_assert_true (differ_seed);
  g_assert_true (differ_stream);
  ds_rng_seed_stream (&a, 42, 0);
  ds_rng_seed (&b, 42);
  g_assert_cmpuint (ds_rng_next (&a), ==, ds_rng_next (&b));
  /* Uniform: mean 1/2 and variance 1/12 within 4 standard errors; open interval honoured. */
  const int n = 200000;
  double s = 0, s2 = 0;
  for (int i = 0; i < n; i++) {
    double u = ds_rng_uniform (&a), v = ds_rng_uniform_open0 (&a);
    g_assert_cmpfloat (u, >=, 0.0);
    g_assert_cmpfloat (u, <, 1.0);
    g_assert_cmpfloat (v, >, 0.0);
    g_assert_cmpfloat (v, <=, 1.0);
    s += u;
    s2 += u * u;
  }
  g_assert_cmpfloat (fabs (s / n - 0.5), <, 4 * sqrt (1.0 / 12 / n));
  g_assert_cmpfloat (fabs (s2 / n - 1.0 / 3), <, 4 * sqrt ((1.0 / 5 - 1.0 / 9) / n));
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  g_test_add_func ("/sim/transport/fresnel/normal-incidence", test_fresnel_normal_incidence);
  g_test_add_func ("/sim/transport/fresnel/angle-form", test_fresnel_angle_form);
  g_test_add_func ("/sim/transport/fresnel/total-internal-reflection", test_fresnel_total_internal_reflection);
  g_test_add_func ("/sim/transport/fresnel/brewster", test_fresnel_brewster);
  g_test_add_func ("/sim/transport/fresnel/diffuse", test_fresnel_diffuse);
  g_test_add_func ("/sim/transport/hg/cdf-numeric", test_hg_cdf_numeric);
  g_test_add_func ("/sim/transport/hg/sampling", test_hg_sampling);
  g_test_add_func ("/sim/transport/rng/reproducible-streams", test_rng_reproducible_streams);
  return g_test_run ();
}
