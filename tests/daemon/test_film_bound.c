/* The upper end of a thin film's bias (daemon/operating/film_bound.h), against expectations
 * written independently of it: the Henyey-Greenstein phase function integrated numerically over
 * the cone, its isotropic and delta limits, and a singly scattering film built forward from its
 * optical depth (direct light e^-τ, scattered 1 - e^-τ of which F stays in the cone, narrowed
 * inside the film by refraction). */
#include <glib.h>
#include <math.h>

#include "daemon/operating/film_bound.h"
#include "daemon/operating/scene_probe_loss.h"

/* ∫0^θc p(θ) 2π sin θ dθ, p(θ) = (1 - g²) / (4π (1 + g² - 2g cos θ)^3/2), by Simpson's rule in
 * u = 1 - cos θ (the integrand is smooth there for g < 1). */
static double
hg_cone_integral (double g, double theta)
{
  const int n = 200000;
  double umax = 1 - cos (theta), h = umax / n, sum = 0;
  for (int i = 0; i <= n; i++) {
    double u = i * h;
    double p = (1 - g * g) / (2 * pow (1 + g * g - 2 * g * (1 - u), 1.5));
    sum += p * (i == 0 || i == n ? 1 : i % 2 ? 4 : 2);
  }
  return sum * h / 3;
}

static void
test_against_integral (void)
{
  const double gs[] = { 0.1, 0.5, 0.85, 0.927, 0.95, 0.98 };
  const double degs[] = { 1, 7.65, 30, 90, 180 };
  for (guint i = 0; i < G_N_ELEMENTS (gs); i++)
    for (guint j = 0; j < G_N_ELEMENTS (degs); j++) {
      double th = degs[j] * G_PI / 180;
      double f = ds_film_cone_fraction (gs[i], th), ref = hg_cone_integral (gs[i], th);
      g_assert_cmpfloat_with_epsilon (f, ref, 1e-6);
    }
  /* the whole sphere holds all of it */
  g_assert_cmpfloat_with_epsilon (ds_film_cone_fraction (0.9, G_PI), 1.0, 1e-12);
}

static void
test_limits (void)
{
  const double degs[] = { 2, 10, 45, 120 };
  for (guint j = 0; j < G_N_ELEMENTS (degs); j++) {
    double th = degs[j] * G_PI / 180, iso = (1 - cos (th)) / 2;
    /* isotropic: the cone's share of the sphere's solid angle */
    g_assert_cmpfloat_with_epsilon (ds_film_cone_fraction (0, th), iso, 1e-15);
    g_assert_cmpfloat_with_epsilon (ds_film_cone_fraction (1e-9, th), iso, 1e-8);
    g_assert_cmpfloat_with_epsilon (ds_film_cone_fraction (1e-3, th), iso, 1e-3);
    /* a delta forward: everything in any cone */
    g_assert_cmpfloat_with_epsilon (ds_film_cone_fraction (1 - 1e-7, th), 1.0, 1e-4);
    /* more forward-peaked, more in the cone: the bound's g is its worst */
    double last = 0;
    for (double g = 0.05; g < 0.99; g += 0.05) {
      double f = ds_film_cone_fraction (g, th);
      g_assert_cmpfloat (f, >, last);
      last = f;
    }
  }
}

/* A film that only scatters, once, with g = DS_FILM_MAX_G and faces of DS_FILM_MIN_INDEX: the
 * bound is exact for it; absorbing or less forward-peaked films lie below it. */
static void
test_bias_bound (void)
{
  /* Snell's law at the exit face: sin θair = n sin θfilm */
  double th_deg = 7.65, th = asin (sin (th_deg * G_PI / 180) / DS_FILM_MIN_INDEX);
  double r = (DS_FILM_MIN_INDEX - 1) / (DS_FILM_MIN_INDEX + 1);
  double faces = (1 - r * r) / (1 + r * r);
  const double taus[] = { 0.02, 0.1, 0.3, 0.5 };
  for (guint i = 0; i < G_N_ELEMENTS (taus); i++) {
    double direct = exp (-taus[i]), scattered = 1 - direct;
    double f = ds_film_cone_fraction (DS_FILM_MAX_G, th);
    double t = faces * (direct + f * scattered);
    g_assert_cmpfloat_with_epsilon (ds_film_bias_upper (t, th_deg), f * scattered / direct, 1e-9);
    /* g = 0.85: less in the cone, and less passing for direct */
    double f85 = ds_film_cone_fraction (0.85, th);
    double t85 = faces * (direct + f85 * scattered);
    g_assert_cmpfloat (f85 * scattered / direct, <, ds_film_bias_upper (t85, th_deg));
    /* absorption on top (albedo 0.8): the loss grows, the bias falls */
    double s_abs = 0.8 * scattered, t_abs = faces * (direct + f * s_abs);
    g_assert_cmpfloat (f * s_abs / direct, <, ds_film_bias_upper (t_abs, th_deg));
  }
  /* a loss the cone's share cannot leave any direct light beside */
  g_assert_true (isinf (ds_film_bias_upper (0.2, 7.65)));
  /* no loss beyond the faces: no bias */
  g_assert_cmpfloat_with_epsilon (ds_film_bias_upper (faces, th_deg), 0.0, 1e-12);
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  g_test_add_func ("/film-bound/cone-fraction-integral", test_against_integral);
  g_test_add_func ("/film-bound/cone-fraction-limits", test_limits);
  g_test_add_func ("/film-bound/bias-bound", test_bias_bound);
  return g_test_run ();
}
