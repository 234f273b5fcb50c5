/* Fuzz target: the scene parser. Any text yields a scene or an error naming the place; an
 * accepted scene has a sane geometry. */
#include <stdint.h>

#include "drivers/sim/scene.h"

int LLVMFuzzerTestOneInput (const uint8_t *data, size_t size);

int
LLVMFuzzerTestOneInput (const uint8_t *data, size_t size)
{
  GError *error = NULL;
  DsScene *scene = ds_scene_load_data ((const char *) data, size, "fuzz.scene", &error);
  if (!scene) {
    g_assert (error && error->message && *error->message);
    g_error_free (error);
    return 0;
  }
  g_assert (ds_scene_width (scene) > 0 && ds_scene_height (scene) > 0);
  g_assert (ds_scene_period_px (scene) > 0);
  ds_scene_free (scene);
  return 0;
}
