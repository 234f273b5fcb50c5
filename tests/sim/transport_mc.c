/* Monte Carlo slab transport against published tables and closed forms. Every comparison
 * allows 4 combined standard errors (a false alarm about once in 16000 per check) plus, where
 * the expectation is itself approximate, its stated error bound. */
#include <math.h>
#include <string.h>

#include "drivers/sim/henyey_greenstein.h"
#include "drivers/sim/sim_error.h"
#include "drivers/sim/transport.h"

static void
assert_within (const char *what, double got, double se, double expect, double extra)
{
  double tol = 4.0 * se + extra;
  if (!(fabs (got - expect) <= tol))
    g_error ("%s: got %.6f +- %.6f, expected %.6f (tolerance %.6f)", what, got, se, expect, tol);
}

static DsSlabTally
run (DsSlab s, guint64 photons, guint64 seed)
{
  g_autoptr (GError) error = NULL;
  DsSlabTally t;
  g_assert_true (ds_mc_slab_run (&s, photons, seed, &t, &error));
  g_assert_no_error (error);
  g_assert_cmpuint (t.photons, ==, photons);
  return t;
}

/* Wang, Jacques & Zheng (1995), MCML paper, validation against van de Hulst (1980):
 * slab n = 1 (matched), mu_a = 10/cm, mu_s = 90/cm, g = 0.75, d = 0.02 cm, normal incidence:
 * total diffuse reflectance Rd = 0.09734 (+- 0.00035, MCML) and total transmittance
 * Tt = 0.66096 (+- 0.00020). In our units: mu_a = 1/mm, mu_s = 9/mm, d = 0.2 mm. */
static void
test_mcml_benchmark (void)
{
  DsSlabTally t = run ((DsSlab) { 1.0, 9.0, 0.75, 0.2, 1.0, 1.0, 1.0 }, 300000, 11);
  assert_within ("Rd", t.reflectance, hypot (t.se_reflectance, 0.00035), 0.09734, 0);
  assert_within ("Tt", t.transmittance, hypot (t.se_transmittance, 0.00020), 0.66096, 0);
  g_assert_cmpfloat (t.specular, ==, 0.0);
}

/* specular + R + T + A = 1: weights only move between tallies, except that Russian roulette
 * changes a photon's weight (unbiased on average). */
static void
test_energy_balance (void)
{
  const DsSlab slabs[] = {
    { 1.0, 9.0, 0.75, 0.2, 1.0, 1.0, 1.0 },
    { 0.5, 10.0, 0.9, 2.0, 1.4, 1.0, 1.0 },
    { 2.0, 5.0, 0.0, 1.0, 1.5, 1.0, 1.33 },
    { 0.02, 3.0, -0.3, 1.0, 1.33, 1.5, 1.0 },
  };
  for (guint i = 0; i < G_N_ELEMENTS (slabs); i++) {
    DsSlabTally t = run (slabs[i], 40000, 20 + i);
    double se = sqrt (t.se_reflectance * t.se_reflectance + t.se_transmittance * t.se_transmittance +
                      t.se_absorbed * t.se_absorbed);
    assert_within ("R+T+A+specular", t.specular + t.reflectance + t.transmittance + t.absorbed, se, 1.0, 1e-9);
    g_assert_cmpfloat (t.ballistic, <=, t.transmittance);
    g_assert_cmpfloat_with_epsilon (t.specular, pow ((slabs[i].n_above - slabs[i].n_medium) /
                                                     (slabs[i].n_above + slabs[i].n_medium), 2), 1e-15);
  }
}

/* Unscattered light: exp(-mu_t d) with matched faces. With mismatched faces each pass loses
 * the normal-incidence Fresnel reflection R0 = ((n1-n2)/(n1+n2))^2 and unscattered light
 * bounces between the faces, so (geometric series, multiple internal reflections INCLUDED)
 * B = (1-Ra)(1-Rb) e^(-mu_t d) / (1 - Ra Rb e^(-2 mu_t d)). With n = 3 the series is 4 % of
 * B, far more than 4 standard errors: the single-pass form (1-Ra)(1-Rb)e^(-mu_t d) must fail. */
static void
test_ballistic (void)
{
  DsSlab m = { 0.5, 1.5, 0.8, 1.0, 1.0, 1.0, 1.0 };
  DsSlabTally t = run (m, 100000, 31);
  assert_within ("ballistic matched", t.ballistic, t.se_ballistic, exp (-2.0), 0);

  const DsSlab mismatched[] = { { 0.1, 0.1, 0.5, 1.0, 3.0, 1.0, 1.0 }, { 0.3, 0.4, 0.0, 1.5, 1.5, 1.0, 1.33 } };
  for (guint i = 0; i < G_N_ELEMENTS (mismatched); i++) {
    const DsSlab *s = &mismatched[i];
    double ra = pow ((s->n_above - s->n_medium) / (s->n_above + s->n_medium), 2);
    double rb = pow ((s->n_below - s->n_medium) / (s->n_below + s->n_medium), 2);
    double e = exp (-(s->mua + s->mus) * s->thickness_mm);
    double multiple = (1 - ra) * (1 - rb) * e / (1 - ra * rb * e * e);
    t = run (*s, 200000, 32 + i);
    assert_within ("ballistic mismatched", t.ballistic, t.se_ballistic, multiple, 0);
    if (i == 0)
      g_assert_cmpfloat (fabs (t.ballistic - (1 - ra) * (1 - rb) * e), >, 10 * t.se_ballistic);
  }
}

/* mu_s = 0: nothing scatters. Transmitted light is all ballistic, none reaches the cone as
 * scattered light, and the absorbed fraction is 1 - exp(-mu_a d) (matched faces). */
static void
test_no_scattering (void)
{
  DsSlab s = { 0.7, 0.0, 0.5, 1.3, 1.0, 1.0, 1.0 };
  DsSlabTally t = run (s, 100000, 41);
  g_assert_cmpfloat (t.transmittance, ==, t.ballistic);
  g_assert_cmpfloat (t.scattered_in_cone, ==, 0.0);
  g_assert_cmpfloat (t.reflectance, ==, 0.0);
  assert_within ("T", t.transmittance, t.se_transmittance, exp (-0.91), 0);
  assert_within ("A", t.absorbed, t.se_absorbed, 1 - exp (-0.91), 0);
  /* Mismatched (R0 = 0.04 at both faces, e = exp(-mu_a d)): light bounces but never
   * scatters. Summing the bounces: T = (1-R0)^2 e / (1 - R0^2 e^2) and the light that leaves
   * again through the entry face R = (1-R0)^2 R0 e^2 / (1 - R0^2 e^2). */
  s.n_medium = 1.5;
  t = run (s, 400000, 42);
  g_assert_cmpfloat (t.transmittance, ==, t.ballistic);
  g_assert_cmpfloat (t.scattered_in_cone, ==, 0.0);
  double r0 = 0.04, e = exp (-0.91);
  assert_within ("T mismatched", t.transmittance, t.se_transmittance, pow (1 - r0, 2) * e / (1 - r0 * r0 * e * e), 0);
  assert_within ("R mismatched", t.reflectance, t.se_reflectance,
                 pow (1 - r0, 2) * r0 * e * e / (1 - r0 * r0 * e * e), 0);
  /* A perfectly clear slab passes everything (mu_t = 0: infinite free path). */
  s = (DsSlab) { 0.0, 0.0, 0.0, 2.0, 1.0, 1.0, 1.0 };
  t = run (s, 1000, 43);
  g_assert_cmpfloat (t.transmittance, ==, 1.0);
}

/* Thin slab, matched, no absorption, tau = mu_s d << 1. To first order in tau a photon
 * scatters once (probability tau) and then leaves forwards with probability
 * F = P(mu > 0) = (1+g)/(2g) - (1-g^2)/(2g sqrt(1+g^2)), so T_scattered = tau F and
 * R = tau (1 - F). Neglected: a second interaction, of order tau ln(1/tau) relative (grazing
 * paths are long); that bound is added to the tolerance. */
static void
test_thin_slab_single_scattering (void)
{
  const double gs[] = { 0.75, -0.5 };
  for (guint i = 0; i < G_N_ELEMENTS (gs); i++) {
    double g = gs[i], tau = 0.001;
    double f = (1 + g) / (2 * g) - (1 - g * g) / (2 * g * sqrt (1 + g * g));
    DsSlabTally t = run ((DsSlab) { 0.0, 1.0, g, tau, 1.0, 1.0, 1.0 }, 3000000, 51 + i);
    double bound = 2 * tau * log (1 / tau);
    assert_within ("T scattered", t.scattered_in_cone, t.se_scattered_in_cone, tau * f, bound * tau * f);
    assert_within ("R", t.reflectance, t.se_reflectance, tau * (1 - f), bound * tau * (1 - f));
    /* The closed form for F is checked here too, against the phase function's CDF. */
    g_assert_cmpfloat_with_epsilon (f, ds_hg_forward_fraction (g), 1e-12);
  }
}

static double
image_sum (const DsImage *im)
{
  double s = 0;
  for (guint y = 0; y < im->height; y++) {
    const float *row = ds_image_row (im, y);
    for (guint x = 0; x < im->width; x++)
      s += row[x];
  }
  return s;
}

/* The PSF holds the scattered transmitted light within the cone: its sum matches the tally of
 * an independent run (another seed) for a kernel wide enough to hold all of it; it is
 * symmetric under x -> -x within noise. */
static void
test_psf_sum_matches_tally (void)
{
  DsSlab s = { 0.05, 5.0, 0.8, 1.0, 1.4, 1.0, 1.0 };
  const double angles[] = { 90.0, 20.0 };
  for (guint i = 0; i < G_N_ELEMENTS (angles); i++) {
    DsPsfGrid grid = { 0.1, 60, angles[i] };
    g_autoptr (GError) error = NULL;
    const guint64 n = 60000;
    g_autoptr (DsImage) psf = ds_slab_psf_monte_carlo (&s, &grid, n, 61, &error);
    g_assert_no_error (error);
    g_assert_cmpuint (psf->width, ==, 121);
    g_assert_cmpuint (psf->type, ==, DS_SAMPLE_F32);
    DsSlabTally t;
    g_assert_true (ds_mc_slab_run_cone (&s, n, 62, angles[i], &t, &error));
    /* Both estimates carry the same standard error. */
    assert_within ("psf sum", image_sum (psf), M_SQRT2 * t.se_scattered_in_cone, t.scattered_in_cone, 0);
    double left = 0, right = 0;
    for (guint y = 0; y < psf->height; y++) {
      const float *row = ds_image_row (psf, y);
      for (guint x = 0; x < 60; x++) {
        left += row[x];
        right += row[120 - x];
      }
    }
    assert_within ("left/right", left, 2 * t.se_scattered_in_cone, right, 0);
  }
  /* Same seed: the kernel holds the tallied in-cone light that lands inside it, and neither
   * depends on the number of worker threads. */
  {
    DsPsfGrid g1 = { 0.1, 60, 30.0 };
    g_autoptr (DsImage) one = ds_slab_psf_monte_carlo_threads (&s, &g1, 5000, 63, 1, NULL);
    g_autoptr (DsImage) two = ds_slab_psf_monte_carlo_threads (&s, &g1, 5000, 63, 2, NULL);
    g_autoptr (DsImage) three = ds_slab_psf_monte_carlo_threads (&s, &g1, 5000, 63, 3, NULL);
    g_assert_cmpmem (one->data, one->stride * one->height, two->data, two->stride * two->height);
    g_assert_cmpmem (one->data, one->stride * one->height, three->data, three->stride * three->height);
    DsSlabTally t1, t3;
    g_assert_true (ds_mc_slab_run_threads (&s, 5000, 63, 30.0, 1, &t1, NULL));
    g_assert_true (ds_mc_slab_run_threads (&s, 5000, 63, 30.0, 3, &t3, NULL));
    g_assert_cmpmem (&t1, sizeof t1, &t3, sizeof t3);
    /* Only light beyond the kernel's 6 mm half-width is missing from it. */
    double in_kernel = image_sum (one);
    g_assert_cmpfloat (in_kernel, <=, t1.scattered_in_cone * (1 + 1e-6));
    g_assert_cmpfloat (in_kernel, >, 0.99 * t1.scattered_in_cone);
  }
  /* Same seed, same kernel: bit-identical (reproducible per seed). */
  DsPsfGrid grid = { 0.2, 10, 45 };
  g_autoptr (DsImage) a = ds_slab_psf_monte_carlo (&s, &grid, 2000, 5, NULL);
  g_autoptr (DsImage) b = ds_slab_psf_monte_carlo (&s, &grid, 2000, 5, NULL);
  g_autoptr (DsImage) c = ds_slab_psf_monte_carlo (&s, &grid, 2000, 6, NULL);
  g_assert_cmpmem (a->data, a->stride * a->height, b->data, b->stride * b->height);
  g_assert_true (memcmp (a->data, c->data, a->stride * a->height) != 0);
}

static void
expect_invalid (DsSlab s, const char *name)
{
  g_autoptr (GError) error = NULL;
  DsSlabTally t;
  g_assert_false (ds_mc_slab_run (&s, 100, 1, &t, &error));
  g_assert_error (error, DS_SIM_ERROR, DS_SIM_ERROR_INVALID);
  g_autofree char *want = g_strdup_printf ("slab: %s =", name);
  if (!g_str_has_prefix (error->message, want))
    g_error ("message '%s' does not name %s", error->message, name);
}

static void
test_validation (void)
{
  const DsSlab ok = { 0.1, 1.0, 0.5, 1.0, 1.33, 1.0, 1.0 };
  DsSlab s = ok;
  s.g = 1.0;
  expect_invalid (s, "g");
  s = ok;
  s.g = -1.0;
  expect_invalid (s, "g");
  s = ok;
  s.mua = -0.1;
  expect_invalid (s, "mua");
  s = ok;
  s.mus = NAN;
  expect_invalid (s, "mus");
  s = ok;
  s.thickness_mm = 0;
  expect_invalid (s, "thickness");
  s = ok;
  s.n_medium = 0.9;
  expect_invalid (s, "n_medium");
  s = ok;
  s.n_below = 0.5;
  expect_invalid (s, "n_below");
  g_autoptr (GError) error = NULL;
  DsSlabTally t;
  g_assert_false (ds_mc_slab_run (&ok, 1, 1, &t, &error));
  g_assert_error (error, DS_SIM_ERROR, DS_SIM_ERROR_INVALID);
  g_clear_error (&error);
  const DsPsfGrid bad[] = { { 0.0, 5, 30 }, { 0.1, 5, 0 }, { 0.1, 5, 91 }, { NAN, 5, 30 }, { 0.1, 2049, 30 } };
  for (guint i = 0; i < G_N_ELEMENTS (bad); i++) {
    g_assert_null (ds_slab_psf_monte_carlo (&ok, &bad[i], 100, 1, &error));
    g_assert_error (error, DS_SIM_ERROR, DS_SIM_ERROR_INVALID);
    g_assert_nonnull (strstr (error->message, "psf grid:"));
    g_clear_error (&error);
  }
}

/* Kernels with object planes: tracking the planes draws no random numbers, so the MCML slab's
 * kernel with two clear planes is the kernel without them, bit for bit, and its tally is the
 * published one; the chain's bookkeeping adds up to that kernel (every photon is in exactly one
 * kernel of each segment); the radius holds the asked energy. */
static void
test_kernels_with_planes (void)
{
  DsSlab mcml = { 1.0, 9.0, 0.75, 0.2, 1.0, 1.0, 1.0 };
  DsSlabKernelSpec spec = { DS_TRANSPORT_MONTE_CARLO, 0.01, 90.0, 0.995, 300000, 11, { 0 } };
  g_autoptr (GError) error = NULL;
  g_autoptr (DsSlabKernels) plain = ds_slab_kernels_compute (&mcml, &spec, 0, &error);
  g_assert_no_error (error);
  spec.planes = (DsSlabPlanes) { 2, { 0.05, 0.12 } };
  g_autoptr (DsSlabKernels) k = ds_slab_kernels_compute (&mcml, &spec, 2, &error);
  g_assert_no_error (error);
  g_assert_cmpuint (k->radius_px, ==, plain->radius_px);
  g_assert_cmpfloat (k->scattered_in_cone, ==, plain->scattered_in_cone);
  for (guint y = 0; y < k->full->height; y++)
    g_assert_cmpmem (ds_image_row (k->full, y), k->full->width * 4, ds_image_row (plain->full, y), k->full->width * 4);
  /* Published Tt = 0.66096 (+- 0.00020), ballistic e^-2: the scattered part, in any direction. */
  assert_within ("Tt - ballistic", k->scattered_in_cone, hypot (k->se_scattered_in_cone, 0.00020), 0.66096 - exp (-2.0),
                 0.0005);
  g_assert_cmpfloat (k->held, >=, 0.995);
  g_assert_cmpfloat (k->held, <, 0.9999);
  /* One pixel less and the kernel would hold less than 99.5 %. */
  double inner = 0;
  guint r = k->radius_px;
  for (guint y = 1; y + 1 < k->full->height; y++)
    for (guint x = 1; x + 1 < k->full->width; x++)
      inner += ((const float *) ds_image_row (k->full, y))[x];
  g_assert_cmpfloat (inner, <, 0.995 * k->scattered_in_cone);
  g_assert_cmpuint (r, >=, 4);
  /* The chain with every plane clear carries exactly the full kernel's light. */
  double b = 1, d = 0;
  for (guint j = 0; j <= 2; j++) {
    const DsSlabSegment *g = &k->segments[j];
    if (j > 0) {
      const DsSlabPlaneCrossing *c = &k->crossings[j - 1];
      double rb = image_sum (c->recross_ballistic), rs = image_sum (c->recross_scattered);
      /* Light crossing once, or again: all of it goes on (but for what lands beyond the radius). */
      g_assert_cmpfloat (fabs (c->once_ballistic + rb - 1), <, 5e-3);
      g_assert_cmpfloat (fabs (c->once_scattered + rs - 1), <, 5e-3);
      g_assert_cmpfloat (fabs (c->recross_times[0] + c->recross_times[1] + c->recross_times[2] - 1), <, 1e-9);
      d = d + b * (1 - c->once_ballistic);
      b = b * c->once_ballistic;
    }
    double nd = d * (g->from_scattered ? image_sum (g->from_scattered) : 0) + b * image_sum (g->from_ballistic);
    b *= g->stays_ballistic;
    d = nd;
  }
  g_assert_cmpfloat (b, ==, 0); /* the last segment keeps nothing unscattered */
  g_assert_cmpfloat (fabs (d - image_sum (k->full)), <, 5e-3 * d);
  /* Planes must lie inside the slab, deeper one after another. */
  spec.planes = (DsSlabPlanes) { 2, { 0.12, 0.05 } };
  g_assert_null (ds_slab_kernels_compute (&mcml, &spec, 0, &error));
  g_assert_error (error, DS_SIM_ERROR, DS_SIM_ERROR_INVALID);
  g_clear_error (&error);
  spec.planes = (DsSlabPlanes) { 1, { 0.2 } };
  g_assert_null (ds_slab_kernels_compute (&mcml, &spec, 0, &error));
  g_assert_error (error, DS_SIM_ERROR, DS_SIM_ERROR_INVALID);
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  g_test_add_func ("/sim/transport/mc/mcml-benchmark", test_mcml_benchmark);
  g_test_add_func ("/sim/transport/mc/energy-balance", test_energy_balance);
  g_test_add_func ("/sim/transport/mc/ballistic", test_ballistic);
  g_test_add_func ("/sim/transport/mc/no-scattering", test_no_scattering);
  g_test_add_func ("/sim/transport/mc/thin-slab-single-scattering", test_thin_slab_single_scattering);
  g_test_add_func ("/sim/transport/mc/psf-sum-matches-tally", test_psf_sum_matches_tally);
  g_test_add_func ("/sim/transport/mc/validation", test_validation);
  g_test_add_func ("/sim/transport/mc/kernels-with-planes", test_kernels_with_planes);
  return g_test_run ();
}
