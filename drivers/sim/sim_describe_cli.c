/* `descatter-sim describe`: the stages a scene builds and why, and what its physics means for
 * the method (docs/scene-format.md). */
#include <stdio.h>

#include "drivers/sim/renderer.h"
#include "drivers/sim/sim_cli.h"

int
ds_sim_describe_main (int argc, char **argv)
{
  if (argc != 2) {
    fprintf (stderr, "usage: descatter-sim describe SCENE\n");
    return 2;
  }
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

