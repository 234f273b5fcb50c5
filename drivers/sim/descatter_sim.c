/* descatter-sim: the scene simulator from the command line.
 *   descatter-sim describe SCENE
 *   descatter-sim render SCENE --phases N --out DIR [--exposure-us E] [--gain-db G] [--seed X]
 *   descatter-sim slab --mua A --mus S --g G --thickness D --n N [--photons P] [--seed X] */
#include <glib/gstdio.h>
#include <locale.h>
#include <stdio.h>
#include <string.h>

#include "drivers/sim/renderer.h"
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

static int
cmd_describe (int argc, char **argv)
{
  if (argc != 2)
    return usage ();
  g_autoptr (GError) error = NULL;
  g_autoptr (DsScene) scene = ds_scene_load (argv[1], &error);
  g_autoptr (DsRenderer) r = scene ? ds_renderer_new (scene, NULL, &error) : NULL;
  if (!r) {
    fprintf (stderr, "descatter-sim: %s\n", error->message);
    return 1;
  }
  printf ("%s: %ux%u, stages:\n", argv[1], ds_scene_width (scene), ds_scene_height (scene));
  for (guint i = 0; i < ds_renderer_n_stages (r); i++)
    printf ("  %-22s %s\n", ds_renderer_stage_name (r, i), ds_renderer_stage_reason (r, i));
  printf ("not built (not declared by the scene):");
  guint n_skipped = 0;
  for (guint s = 0; s < DS_RENDER_N_STAGES; s++)
    if (!ds_renderer_has_stage (r, (DsRenderStage) s)) {
      printf (" %s", ds_render_stage_name ((DsRenderStage) s));
      n_skipped++;
    }
  printf ("%s\n", n_skipped ? "" : " none");
  return 0;
}

static int
cmd_render (int argc, char **argv)
{
  int phases = 0;
  double exposure = 0, gain = 0;
  gint64 seed = 1;
  g_autofree char *out = NULL;
  GOptionEntry entries[] = {
    { "phases", 'n', 0, G_OPTION_ARG_INT, &phases, "phases N (>= 2)", "N" },
    { "out", 'o', 0, G_OPTION_ARG_FILENAME, &out, "output folder", "DIR" },
    { "exposure-us", 'e', 0, G_OPTION_ARG_DOUBLE, &exposure, "exposure (default: the scene's)", "E" },
    { "gain-db", 'g', 0, G_OPTION_ARG_DOUBLE, &gain, "gain (dB)", "G" },
    { "seed", 0, 0, G_OPTION_ARG_INT64, &seed, "noise seed", "X" },
    { NULL },
  };
  g_autoptr (GOptionContext) ctx = g_option_context_new ("SCENE");
  g_option_context_add_main_entries (ctx, entries, NULL);
  g_autoptr (GError) error = NULL;
  if (!g_option_context_parse (ctx, &argc, &argv, &error) || argc != 2 || phases < 2 || !out) {
    fprintf (stderr, "descatter-sim render: %s\n", error ? error->message : "need SCENE, --phases N >= 2 and --out DIR");
    return 2;
  }
  g_autoptr (DsScene) scene = ds_scene_load (argv[1], &error);
  g_autoptr (DsRenderer) r = scene ? ds_renderer_new (scene, NULL, &error) : NULL;
  if (!r) {
    fprintf (stderr, "descatter-sim: %s\n", error->message);
    return 1;
  }
  if (exposure <= 0)
    exposure = ds_scene_default_exposure_us (scene);
  g_mkdir_with_parents (out, 0755);
  for (int k = 0; k < phases; k++) {
    DsRenderRequest req = { .phase = (guint) k, .n_phases = (guint) phases, .illuminator_on = TRUE,
                            .exposure_us = exposure, .gain_db = gain, .seed = (guint64) seed * 1000 + (guint64) k };
    g_autoptr (DsImage) f = ds_renderer_render (r, &req, &error);
    g_autofree char *path = g_strdup_printf ("%s/phase-%02d.png", out, k);
    if (!f || !ds_image_write (f, path, &error)) {
      fprintf (stderr, "descatter-sim: %s\n", error->message);
      return 1;
    }
  }
  /* Ambient light (and the sensor's dark signal) show in a frame with the illuminator off:
   * written whenever the scene has ambient light, as the folder layout expects. */
  if (ds_scene_spec (scene)->has_ambient) {
    DsRenderRequest req = { .illuminator_on = FALSE, .exposure_us = exposure, .gain_db = gain,
                            .seed = (guint64) seed * 1000 + 999 };
    g_autoptr (DsImage) f = ds_renderer_render (r, &req, &error);
    g_autofree char *path = g_strdup_printf ("%s/black.png", out);
    if (!f || !ds_image_write (f, path, &error)) {
      fprintf (stderr, "descatter-sim: %s\n", error->message);
      return 1;
    }
  }
  DsImage *t = NULL, *s = NULL;
  if (!ds_renderer_truth (r, exposure, gain, &t, &s, &error)) {
    fprintf (stderr, "descatter-sim: %s\n", error->message);
    return 1;
  }
  g_autoptr (DsImage) tt = t;
  g_autoptr (DsImage) ts = s;
  g_autofree char *p1 = g_strdup_printf ("%s/truth_transmissive.tiff", out);
  g_autofree char *p2 = g_strdup_printf ("%s/truth_scattered.tiff", out);
  if (!ds_image_write (tt, p1, &error) || !ds_image_write (ts, p2, &error)) {
    fprintf (stderr, "descatter-sim: %s\n", error->message);
    return 1;
  }
  printf ("descatter-sim: %d phases of %s written to %s\n", phases, argv[1], out);
  return 0;
}

int
main (int argc, char **argv)
{
  setlocale (LC_ALL, "");
  if (argc < 2)
    return usage ();
  if (strcmp (argv[1], "describe") == 0)
    return cmd_describe (argc - 1, argv + 1);
  if (strcmp (argv[1], "render") == 0)
    return cmd_render (argc - 1, argv + 1);
  if (strcmp (argv[1], "slab") == 0)
    return ds_sim_slab_main (argc - 1, argv + 1);
  return usage ();
}
