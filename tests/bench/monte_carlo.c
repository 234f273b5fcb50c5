/* Monte Carlo slab transport speed on one core (docs/benchmarks.md).
 * Prints photons per second on one core for three slabs and, as same-run baselines, the cost
 * of one photon in draws of the random generator, the speed-up on all processors and the time
 * of the diffusion kernel for the same slab.
 *   bench_monte_carlo [--quick] */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "drivers/sim/rng.h"
#include "drivers/sim/transport.h"

static double
now (void)
{
  return g_get_monotonic_time () / 1e6;
}

int
main (int argc, char **argv)
{
  gboolean quick = argc > 1 && strcmp (argv[1], "--quick") == 0;
  double scale = quick ? 0.02 : 1.0;

  /* Baseline: uniform draws per second. */
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
    { "MCML benchmark slab (mua 1, mus 9, g 0.75, d 0.2 mm, n 1)", { 1.0, 9.0, 0.75, 0.2, 1.0, 1.0, 1.0 }, 4000000 },
    { "milk-like slab (mua 0.01, mus 5, g 0.8, d 5 mm, n 1.33)", { 0.01, 5.0, 0.8, 5.0, 1.33, 1.0, 1.0 }, 200000 },
    { "tissue-like slab (mua 0.05, mus 20, g 0.9, d 10 mm, n 1.4)", { 0.05, 20.0, 0.9, 10.0, 1.4, 1.0, 1.0 }, 40000 },
  };
  for (guint i = 0; i < G_N_ELEMENTS (cases); i++) {
    guint64 n = MAX ((guint64) (cases[i].photons * scale), 1000);
    DsSlabTally t;
    g_autoptr (GError) error = NULL;
    t0 = now ();
    if (!ds_mc_slab_run_threads (&cases[i].slab, n, 7, 90.0, 1, &t, &error)) {
      fprintf (stderr, "bench_monte_carlo: %s\n", error->message);
      return 1;
    }
    double dt = now () - t0, rate = n / dt;
    t0 = now ();
    ds_mc_slab_run_threads (&cases[i].slab, n, 7, 90.0, 0, &t, NULL);
    double dt_all = now () - t0;
    printf ("%s: %.3g photons/s (%" G_GUINT64_FORMAT " photons, %.2f s), one photon costs %.0f rng draws; "
            "R %.4f T %.4f A %.4f\n", cases[i].name, rate, n, dt, draw_rate / rate, t.reflectance,
            t.transmittance, t.absorbed);
    printf ("  all %d processors: %.3g photons/s (%.2fx one core)\n", g_get_num_processors (),
            n / dt_all, dt / dt_all);
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
  return 0;
}
