/* descatter-sim: the scene simulator from the command line.
 *   descatter-sim describe SCENE
 *   descatter-sim render SCENE --phases N --out DIR [--exposure-us E] [--gain-db G] [--seed X]
 *   descatter-sim slab --mua A --mus S --g G --thickness D --n N [--photons P] [--seed X] */
#include <locale.h>
#include <stdio.h>
#include <string.h>

#include "build_info.h"
#include "drivers/sim/sim_cli.h"
#include "drivers/sim/transport.h"

static int
usage_to (FILE *f, int status)
{
  fprintf (f, "usage: descatter-sim describe SCENE\n"
                   "       descatter-sim render SCENE --phases N --out DIR [--exposure-us E] [--gain-db G] [--seed X]\n"
                   "       descatter-sim slab --mua A --mus S --g G --thickness D --n N [--photons P] [--seed X]\n"
                   "       descatter-sim --version | --help\n"
                   "(coefficients per mm, thickness in mm: docs/transport.md; "
                   "`descatter-sim COMMAND --help` lists a command's options)\n");
  return status;
}

static int
usage (void)
{
  return usage_to (stderr, 2);
}

int
main (int argc, char **argv)
{
  setlocale (LC_ALL, "");
  if (argc < 2)
    return usage ();
  if (strcmp (argv[1], "--help") == 0 || strcmp (argv[1], "-h") == 0)
    return usage_to (stdout, 0);
  if (strcmp (argv[1], "--version") == 0 || strcmp (argv[1], "-V") == 0) {
    printf ("descatter-sim %s (%s)\n", DS_VERSION, DS_GIT_DESCRIBE);
    return 0;
  }
  if (strcmp (argv[1], "describe") == 0)
    return ds_sim_describe_main (argc - 1, argv + 1);
  if (strcmp (argv[1], "render") == 0)
    return ds_sim_render_main (argc - 1, argv + 1);
  if (strcmp (argv[1], "slab") == 0)
    return ds_sim_slab_main (argc - 1, argv + 1);
  return usage ();
}
