/* The scene generator's versions (daemon/ctl/scene_gen.h).
 *
 * Independent expectations:
 * - every version 2 scene is a valid scene for the simulator: its own checker
 *   (ds_scene_load_data) loads it and its render-cost ceiling (ds_render_cost_check) passes;
 * - its keys lie in the widened ranges the generator's header promises (read back from the
 *   simulator's parsed spec, not from the generator), and over a few hundred draws each kind of
 *   scene it promises occurs: periods below 3 px, square duty near 0.2 and 0.8, black levels
 *   above 0.3, thin forward-peaked films, objects at the entry and at the exit face, 8- and
 *   16-bit sensors with a full well that fills between half and 1.2 times the ADC's range;
 * - version 1 still means what it meant: seed 21's first scene is the file committed with the
 *   validation round that ran it (docs/accuracy/validation/generated-21/scenes). */
#include <math.h>
#include <string.h>

#include "daemon/ctl/scene_gen.h"
#include "drivers/sim/render_cost.h"
#include "drivers/sim/scene.h"

/* Development seeds of the generator's tests: outside the held-out range (docs/accuracy.md). */
#define DEV_SEED 500
#define DRAWS 300

static void
test_v2_ranges_and_coverage (void)
{
  guint short_period = 0, duty_low = 0, duty_high = 0, leaky = 0, films = 0, entry = 0, exit_face = 0, bits8 = 0,
        bits16 = 0, sine = 0, square = 0;
  for (guint i = 0; i < DRAWS; i++) {
    g_autoptr (GError) error = NULL;
    g_autofree char *text = ds_scene_draw (DEV_SEED, i, 2, NULL, &error);
    g_assert_no_error (error);
    g_autoptr (DsScene) scene = ds_scene_load_data (text, strlen (text), "drawn", &error);
    g_assert_no_error (error);
    g_assert_true (ds_render_cost_check (scene, &error));
    const DsSceneSpec *s = ds_scene_spec (scene);
    g_assert_cmpfloat (s->period_px, >=, 2.5);
    g_assert_cmpfloat (s->black_level, <=, 0.4);
    g_assert_cmpuint (s->bit_depth, >=, 8);
    g_assert_cmpuint (s->bit_depth, <=, 16);
    double adc = (double) ((1u << s->bit_depth) - 1), well_dn = s->full_well_e * s->system_gain;
    g_assert_cmpfloat (well_dn, >=, 0.5 * adc * 0.999);
    g_assert_cmpfloat (well_dn, <=, 1.2 * adc * 1.001);
    if (s->sine)
      sine++;
    else {
      square++;
      g_assert_cmpfloat (s->duty, >=, 0.2);
      g_assert_cmpfloat (s->duty, <=, 0.8);
      duty_low += s->duty < 0.3;
      duty_high += s->duty > 0.7;
    }
    short_period += s->period_px < 3;
    leaky += s->black_level > 0.3;
    bits8 += s->bit_depth == 8;
    bits16 += s->bit_depth == 16;
    if (s->has_medium) {
      g_assert_cmpfloat (s->g, <=, 0.95);
      films += s->g >= 0.85 && s->mus * s->thickness_mm <= 0.5 && s->thickness_mm <= 1;
      for (guint k = 0; k < s->n_objects; k++) {
        g_assert_cmpfloat (s->objects[k].depth_mm, >=, 0);
        g_assert_cmpfloat (s->objects[k].depth_mm, <=, s->thickness_mm);
        entry += s->objects[k].depth_mm == 0;
        exit_face += s->objects[k].depth_mm == s->thickness_mm;
      }
    }
  }
  /* Each kind drawn with a probability of a few % at least: absent from 300 draws only by a bug. */
  g_assert_cmpuint (short_period, >, 0);
  g_assert_cmpuint (duty_low, >, 0);
  g_assert_cmpuint (duty_high, >, 0);
  g_assert_cmpuint (leaky, >, 0);
  g_assert_cmpuint (films, >, 0);
  g_assert_cmpuint (entry, >, 0);
  g_assert_cmpuint (exit_face, >, 0);
  g_assert_cmpuint (bits8, >, 0);
  g_assert_cmpuint (bits16, >, 0);
  g_assert_cmpuint (sine, >, DRAWS / 5);
  g_assert_cmpuint (square, >, DRAWS / 5);
}

static void
test_versions (void)
{
  g_autoptr (GError) error = NULL;
  g_autofree char *a = ds_scene_draw (DEV_SEED, 3, 2, NULL, &error);
  g_autofree char *b = ds_scene_draw (DEV_SEED, 3, 2, NULL, &error);
  g_autofree char *old = ds_scene_draw (DEV_SEED, 3, 1, NULL, &error);
  g_assert_no_error (error);
  g_assert_cmpstr (a, ==, b);
  g_assert_cmpstr (a, !=, old);
  g_autofree char *none = ds_scene_draw (DEV_SEED, 3, 3, NULL, &error);
  g_assert_null (none);
  g_assert_nonnull (strstr (error->message, "versions 1 to 2"));
}

static void
test_v1_unchanged (void)
{
  g_autofree char *path = g_build_filename (DS_SOURCE_DIR, "docs", "accuracy", "validation", "generated-21", "scenes",
                                            "gen-21-00.scene", NULL);
  g_autofree char *committed = NULL;
  g_autoptr (GError) error = NULL;
  g_assert_true (g_file_get_contents (path, &committed, NULL, &error));
  g_autofree char *text = ds_scene_generate (21, 0, 1, &error);
  g_assert_no_error (error);
  g_assert_cmpstr (text, ==, committed);
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  g_test_add_func ("/scene-gen/v2-ranges-and-coverage", test_v2_ranges_and_coverage);
  g_test_add_func ("/scene-gen/versions", test_versions);
  g_test_add_func ("/scene-gen/v1-unchanged", test_v1_unchanged);
  return g_test_run ();
}
