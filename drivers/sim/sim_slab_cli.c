/* `descatter-sim slab`: Monte Carlo totals of a slab, for checks against published tables
 * (docs/transport.md). argv[0] is the subcommand's name. */
#include <math.h>
#include <stdio.h>

#include "drivers/sim/transport.h"

int
ds_sim_slab_main (int argc, char **argv)
{
  double mua = NAN, mus = NAN, g = NAN, d = NAN, n = NAN, n_above = 1.0, n_below = 1.0;
  double accept = 90.0;
  gint64 photons = 1000000, seed = 1;
  GOptionEntry entries[] = {
    { "mua", 0, 0, G_OPTION_ARG_DOUBLE, &mua, "absorption coefficient (per mm)", "A" },
    { "mus", 0, 0, G_OPTION_ARG_DOUBLE, &mus, "scattering coefficient (per mm)", "S" },
    { "g", 0, 0, G_OPTION_ARG_DOUBLE, &g, "Henyey-Greenstein anisotropy, in (-1, 1)", "G" },
    { "thickness", 0, 0, G_OPTION_ARG_DOUBLE, &d, "slab thickness (mm)", "D" },
    { "n", 0, 0, G_OPTION_ARG_DOUBLE, &n, "refractive index of the slab", "N" },
    { "n-above", 0, 0, G_OPTION_ARG_DOUBLE, &n_above, "index of the entry side (default 1)", "N" },
    { "n-below", 0, 0, G_OPTION_ARG_DOUBLE, &n_below, "index of the exit side (default 1)", "N" },
    { "acceptance", 0, 0, G_OPTION_ARG_DOUBLE, &accept,
      "also print the scattered transmittance within this half-angle (degrees, default 90)", "DEG" },
    { "photons", 0, 0, G_OPTION_ARG_INT64, &photons, "photons to trace (default 1000000)", "P" },
    { "seed", 0, 0, G_OPTION_ARG_INT64, &seed, "random seed (default 1)", "X" },
    { NULL, 0, 0, 0, NULL, NULL, NULL },
  };
  g_autoptr (GOptionContext) ctx = g_option_context_new ("- Monte Carlo transport through a slab");
  g_option_context_set_summary (ctx, "Coefficients are per mm, the thickness in mm. Prints the "
                                     "fractions of a unit normally incident beam, each with its "
                                     "Monte Carlo standard error (docs/transport.md).");
  g_option_context_add_main_entries (ctx, entries, NULL);
  g_autoptr (GError) error = NULL;
  if (!g_option_context_parse (ctx, &argc, &argv, &error)) {
    fprintf (stderr, "descatter-sim slab: %s\n", error->message);
    return 1;
  }
  const char *missing = isnan (mua) ? "--mua" : isnan (mus) ? "--mus" : isnan (g) ? "--g"
                        : isnan (d) ? "--thickness" : isnan (n) ? "--n" : NULL;
  if (missing) {
    fprintf (stderr, "descatter-sim slab: %s is required (see --help)\n", missing);
    return 1;
  }
  if (argc > 1) {
    fprintf (stderr, "descatter-sim slab: unexpected argument '%s'\n", argv[1]);
    return 1;
  }
  if (photons < 2 || seed < 0) {
    fprintf (stderr, "descatter-sim slab: --photons must be >= 2 and --seed >= 0\n");
    return 1;
  }
  DsSlab slab = { mua, mus, g, d, n, n_above, n_below };
  DsSlabTally t;
  if (!ds_mc_slab_run_cone (&slab, (guint64) photons, (guint64) seed, accept, &t, &error)) {
    fprintf (stderr, "descatter-sim slab: %s\n", error->message);
    return 1;
  }
  printf ("slab: mua %g /mm, mus %g /mm, g %g, thickness %g mm, n %g (entry side %g, exit side %g)\n",
          mua, mus, g, d, n, n_above, n_below);
  printf ("photons: %" G_GUINT64_FORMAT ", seed %" G_GINT64_FORMAT "\n", t.photons, seed);
  printf ("specular reflectance       %.5f (exact)\n", t.specular);
  printf ("total diffuse reflectance  %.5f +- %.5f\n", t.reflectance, t.se_reflectance);
  printf ("total transmittance        %.5f +- %.5f\n", t.transmittance, t.se_transmittance);
  printf ("ballistic transmittance    %.5f +- %.5f\n", t.ballistic, t.se_ballistic);
  printf ("absorbed fraction          %.5f +- %.5f\n", t.absorbed, t.se_absorbed);
  printf ("scattered transmittance within %g deg  %.5f +- %.5f\n", accept, t.scattered_in_cone,
          t.se_scattered_in_cone);
  return 0;
}
