/* Monte Carlo slab transport speed on one core (docs/benchmarks.md, issue 13).
 * For three slabs: photons per second on one thread against an MCML-style loop run in the same
 * process on the same generator (the baseline: the ratio is what issue 13 asks >= 1.0 of), the
 * speed-up on all processors, and the time of a kernel by Monte Carlo and by diffusion. The
 * two loops must agree on R, T and A within 5 standard errors: the benchmark checks its results.
 *   bench_monte_carlo [--quick] */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "drivers/sim/fresnel.h"
#include "drivers/sim/rng.h"
#include "drivers/sim/transport.h"

static double
now (void)
{
  return g_get_monotonic_time () / 1e6;
}

/* ---- MCML-style loop: Wang, Jacques & Zheng (1995), as a reader of the MCML paper writes it for
 * one layer between two ambient media: StepSize with the unfinished step carried over a boundary
 * (sleft), Hop, Drop, Spin with the azimuth from cos(psi), RFresnel with MCML's sine/cosine
 * formula, CrossOrNot, Roulette. The generator is the project's (the loops differ only in how
 * they transport). Tallies: R, T, A with their sums of squares. ------------------------------ */

#define MCML_WEIGHT 1e-4
#define MCML_CHANCE 0.1
#define MCML_COSZERO (1.0 - 1.0e-12)
#define MCML_COS90D 1.0e-6

static double
mcml_rfresnel (double n1, double n2, double ca1, double *ca2_out)
{
  double r;
  if (n1 == n2) {
    *ca2_out = ca1;
    r = 0.0;
  } else if (ca1 > MCML_COSZERO) {
    *ca2_out = ca1;
    r = (n2 - n1) / (n2 + n1);
    r *= r;
  } else if (ca1 < MCML_COS90D) {
    *ca2_out = 0.0;
    r = 1.0;
  } else {
    double sa1 = sqrt (1 - ca1 * ca1), sa2 = n1 * sa1 / n2;
    if (sa2 >= 1.0) {
      *ca2_out = 0.0;
      r = 1.0;
    } else {
      double ca2 = sqrt (1 - sa2 * sa2);
      double cap = ca1 * ca2 - sa1 * sa2, cam = ca1 * ca2 + sa1 * sa2;
      double sap = sa1 * ca2 + ca1 * sa2, sam = sa1 * ca2 - ca1 * sa2;
      r = 0.5 * sam * sam * (cam * cam + cap * cap) / (sap * sap * cam * cam);
      *ca2_out = ca2;
    }
  }
  return r;
}

typedef struct {
  double sum[3], sum2[3]; /* R, T, A */
} McmlTally;

static void
mcml_run (const DsSlab *s, guint64 photons, guint64 seed, McmlTally *t)
{
  DsRng rng;
  ds_rng_seed (&rng, seed);
  double mut = s->mua + s->mus, d = s->thickness_mm, g = s->g;
  double rsp = (s->n_above - s->n_medium) / (s->n_above + s->n_medium);
  memset (t, 0, sizeof *t);
  for (guint64 i = 0; i < photons; i++) {
    double w = 1.0 - rsp * rsp, x = 0, y = 0, z = 0, ux = 0, uy = 0, uz = 1, sleft = 0;
    double q[3] = { 0, 0, 0 };
    gboolean dead = FALSE;
    while (!dead) {
      /* StepSizeInTissue */
      double step;
      if (sleft == 0.0) {
        double rnd;
        do
          rnd = ds_rng_uniform (&rng);
        while (rnd <= 0.0);
        step = -log (rnd) / mut;
      } else {
        step = sleft / mut;
        sleft = 0.0;
      }
      /* HitBoundary */
      double db = uz > 0.0 ? (d - z) / uz : uz < 0.0 ? -z / uz : G_MAXDOUBLE;
      gboolean hit = step > db;
      if (hit) {
        sleft = (step - db) * mut;
        step = db;
      }
      /* Hop */
      x += step * ux;
      y += step * uy;
      z += step * uz;
      if (hit) {
        /* CrossUpOrNot / CrossDnOrNot */
        double uz1, nt = uz > 0 ? s->n_below : s->n_above;
        double r = mcml_rfresnel (s->n_medium, nt, fabs (uz), &uz1);
        if (ds_rng_uniform (&rng) > r) {
          q[uz > 0 ? 1 : 0] += w;
          dead = TRUE;
        } else
          uz = -uz;
        continue;
      }
      /* Drop */
      double dwa = w * s->mua / mut;
      w -= dwa;
      q[2] += dwa;
      /* Spin */
      double cost;
      double rnd = ds_rng_uniform (&rng);
      if (g == 0.0)
        cost = 2 * rnd - 1;
      else {
        double temp = (1 - g * g) / (1 - g + 2 * g * rnd);
        cost = (1 + g * g - temp * temp) / (2 * g);
        if (cost < -1)
          cost = -1;
        else if (cost > 1)
          cost = 1;
      }
      double sint = sqrt (1.0 - cost * cost), psi = 2.0 * G_PI * ds_rng_uniform (&rng), cosp = cos (psi);
      double sinp = psi < G_PI ? sqrt (1.0 - cosp * cosp) : -sqrt (1.0 - cosp * cosp);
      if (fabs (uz) > MCML_COSZERO) {
        ux = sint * cosp;
        uy = sint * sinp;
        uz = cost * (uz >= 0 ? 1 : -1);
      } else {
        double temp = sqrt (1.0 - uz * uz);
        double nux = sint * (ux * uz * cosp - uy * sinp) / temp + ux * cost;
        double nuy = sint * (uy * uz * cosp + ux * sinp) / temp + uy * cost;
        uz = -sint * cosp * temp + uz * cost;
        ux = nux;
        uy = nuy;
      }
      /* Roulette */
      if (w < MCML_WEIGHT) {
        if (w == 0.0 || ds_rng_uniform (&rng) > MCML_CHANCE)
          dead = TRUE;
        else
          w /= MCML_CHANCE;
      }
    }
    for (int k = 0; k < 3; k++) {
      t->sum[k] += q[k];
      t->sum2[k] += q[k] * q[k];
    }
  }
}

static double
se_of (double sum, double sum2, guint64 n)
{
  double m = sum / n;
  return sqrt (MAX (sum2 / n - m * m, 0.0) / n);
}

/* Best of `reps` alternating runs of both loops: the machine is shared, the minimum is the least
 * disturbed estimate, and alternating keeps both under the same load. */
static gboolean
compare_loops (const char *name, const DsSlab *slab, guint64 n, guint reps, double *ratio)
{
  double best_ours = G_MAXDOUBLE, best_mcml = G_MAXDOUBLE;
  DsSlabTally t;
  McmlTally m;
  for (guint r = 0; r < reps; r++) {
    g_autoptr (GError) error = NULL;
    double t0 = now ();
    if (!ds_mc_slab_run_threads (slab, n, 7, 90.0, 1, &t, &error)) {
      fprintf (stderr, "bench_monte_carlo: %s\n", error->message);
      return FALSE;
    }
    best_ours = MIN (best_ours, now () - t0);
    t0 = now ();
    mcml_run (slab, n, 8, &m);
    best_mcml = MIN (best_mcml, now () - t0);
  }
  double mr = m.sum[0] / n, mt = m.sum[1] / n, ma = m.sum[2] / n;
  double sr = se_of (m.sum[0], m.sum2[0], n), st = se_of (m.sum[1], m.sum2[1], n), sa = se_of (m.sum[2], m.sum2[2], n);
  *ratio = best_mcml / best_ours;
  printf ("%s: %.3g photons/s on one thread, MCML-style loop %.3g: %.2fx (best of %u, %" G_GUINT64_FORMAT
          " photons)\n", name, n / best_ours, n / best_mcml, *ratio, reps, n);
  printf ("  R %.4f / %.4f, T %.4f / %.4f, A %.4f / %.4f (ours / MCML-style)\n", t.reflectance, mr,
          t.transmittance, mt, t.absorbed, ma);
  gboolean ok = fabs (t.reflectance - mr) <= 5 * hypot (t.se_reflectance, sr) &&
                fabs (t.transmittance - mt) <= 5 * hypot (t.se_transmittance, st) &&
                fabs (t.absorbed - ma) <= 5 * hypot (t.se_absorbed, sa);
  if (!ok)
    fprintf (stderr, "bench_monte_carlo: %s: the loops disagree beyond 5 standard errors\n", name);
  return ok;
}

int
main (int argc, char **argv)
{
  gboolean quick = argc > 1 && strcmp (argv[1], "--quick") == 0;
  double scale = quick ? 0.02 : 1.0;
  guint reps = quick ? 1 : 5;

  /* Baseline of the generator: uniform draws per second. */
  guint64 draws = (guint64) (2e8 * scale);
  DsRng rng;
  ds_rng_seed (&rng, 1);
  double t0 = now (), sink = 0;
  for (guint64 i = 0; i < draws; i++)
    sink += ds_rng_uniform (&rng);
  double draw_rate = draws / (now () - t0);
  printf ("rng: %.3g uniform draws/s (checksum %.3f)\n", draw_rate, sink / draws);

  struct {
    const char *name;
    DsSlab slab;
    guint64 photons;
  } cases[] = {
    { "MCML benchmark slab (mua 1, mus 9, g 0.75, d 0.2 mm, n 1)", { 1.0, 9.0, 0.75, 0.2, 1.0, 1.0, 1.0 }, 2000000 },
    { "milk-like slab (mua 0.01, mus 5, g 0.8, d 5 mm, n 1.33)", { 0.01, 5.0, 0.8, 5.0, 1.33, 1.0, 1.0 }, 100000 },
    { "tissue-like slab (mua 0.05, mus 20, g 0.9, d 10 mm, n 1.4)", { 0.05, 20.0, 0.9, 10.0, 1.4, 1.0, 1.0 }, 20000 },
  };
  int status = 0;
  for (guint i = 0; i < G_N_ELEMENTS (cases); i++) {
    guint64 n = MAX ((guint64) (cases[i].photons * scale), 1000);
    double ratio;
    if (!compare_loops (cases[i].name, &cases[i].slab, n, reps, &ratio))
      status = 1;
    DsSlabTally t;
    g_autoptr (GError) error = NULL;
    t0 = now ();
    ds_mc_slab_run_threads (&cases[i].slab, n, 7, 90.0, 1, &t, NULL);
    double dt = now () - t0;
    t0 = now ();
    ds_mc_slab_run_threads (&cases[i].slab, n, 7, 90.0, 0, &t, NULL);
    double dt_all = now () - t0;
    printf ("  one photon costs %.0f generator draws; all %d processors: %.2fx one\n", draw_rate / (n / dt),
            g_get_num_processors (), dt / dt_all);
    /* The same slab as a 101 x 101 kernel at 0.1 mm: Monte Carlo against diffusion. */
    DsPsfGrid grid = { 0.1, 50, 90.0 };
    t0 = now ();
    g_autoptr (DsImage) mc = ds_slab_psf_monte_carlo_threads (&cases[i].slab, &grid, n, 8, 1, &error);
    double t_mc = now () - t0;
    t0 = now ();
    g_autoptr (DsImage) df = ds_slab_psf_diffusion (&cases[i].slab, &grid, &error);
    double t_df = now () - t0;
    if (!mc || !df) {
      fprintf (stderr, "bench_monte_carlo: %s\n", error->message);
      return 1;
    }
    printf ("  101x101 kernel: Monte Carlo %.3f s (one core), diffusion %.3f s (diffusion %.0fx faster)\n", t_mc,
            t_df, t_mc / t_df);
  }
  return status;
}
