/* descatter-sim: the scene simulator from the command line.
 *   descatter-sim describe SCENE
 *   descatter-sim render SCENE --phases N --out DIR [--exposure-us E] [--gain-db G] [--seed X]
 *   descatter-sim slab --mua A --mus S --g G --thickness D --n N [--photons P] [--seed X] */
#include <locale.h>
#include <stdio.h>
#include <string.h>

#include "drivers/sim/sim_cli.h"
#include "drivers/sim/transport.h"

static int
usage (void)
{
  fprintf (stderr, "usage: descatter-sim describe SCENE\n"
                   "       descatter-sim render SCENE --phases N --out DIR [--exposure-us E] [--gain-db G] [--seed X]\n"
                   "       descatter-sim slab --mua A --mus S --g G --thickness D --n N [--photons P] [--seed X]\n"
                   "(coefficients per mm, thickness in mm: docs/transport.md)\n");
  return 2;
}

int
main (int argc, char **argv)
{
  setlocale (LC_ALL, "");
  if (argc < 2)
    return usage ();
  if (strcmp (argv[1], "describe") == 0)
    return ds_sim_describe_main (argc - 1, argv + 1);
  if (strcmp (argv[1], "render") == 0)
    return ds_sim_render_main (argc - 1, argv + 1);
  if (strcmp (argv[1], "slab") == 0)
    return ds_sim_slab_main (argc - 1, argv + 1);
  return usage ();
}
