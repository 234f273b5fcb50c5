/* `descatter-sim render`: one phase set of a scene as a phase folder (docs/phase-folder.md):
 * phase-NN.png, black.png when the scene has ambient light, the truth as float32 TIFF, and
 * frames.json written last, so a folder with its sidecar is whole. */
#include <errno.h>
#include <glib/gstdio.h>
#include <json-glib/json-glib.h>
#include <stdio.h>

#include "build_info.h"
#include "drivers/sim/renderer.h"
#include "drivers/sim/sim_cli.h"

/* The PFNC name of unpacked integer samples of this many bits, or NULL when there is none. */
static const char *
pixel_format_name (guint bits)
{
  switch (bits) {
  case 8: return "Mono8";
  case 10: return "Mono10";
  case 12: return "Mono12";
  case 14: return "Mono14";
  case 16: return "Mono16";
  default: return NULL;
  }
}

/* Frame k's time (s): the midpoint of its exposure, frames one interval apart from time 0. */
static double
frame_time_s (int k, double interval_us, double exposure_us)
{
  return (k * interval_us + exposure_us / 2) * 1e-6;
}

/* The truth of a set of moving objects is taken at the set's middle: halfway between its first
 * and last frames' times. */
static double
truth_time_s (int phases, double interval_us, double exposure_us)
{
  return ((phases - 1) * interval_us / 2 + exposure_us / 2) * 1e-6;
}

static gboolean
write_sidecar (const char *dir, const char *scene_path, const DsRenderer *r, int phases, double exposure,
               double interval, double gain, gint64 seed, gboolean has_black, GError **error)
{
  gboolean moves = ds_scene_has_motion (ds_renderer_scene (r));
  const DsScene *scene = ds_renderer_scene (r);
  g_autoptr (JsonBuilder) b = json_builder_new ();
  json_builder_begin_object (b);
  json_builder_set_member_name (b, "format");
  json_builder_add_string_value (b, "descatter-phase-folder");
  json_builder_set_member_name (b, "version");
  json_builder_add_int_value (b, 1);
  json_builder_set_member_name (b, "producer");
  json_builder_begin_object (b);
  json_builder_set_member_name (b, "program");
  json_builder_add_string_value (b, "descatter-sim");
  json_builder_set_member_name (b, "version");
  json_builder_add_string_value (b, DS_VERSION);
  json_builder_set_member_name (b, "git");
  json_builder_add_string_value (b, DS_GIT_DESCRIBE);
  json_builder_set_member_name (b, "backend");
  json_builder_add_string_value (b, "descatter-sim");
  json_builder_end_object (b);
  g_autoptr (GDateTime) now = g_date_time_new_now_utc ();
  g_autofree char *stamp = g_date_time_format (now, "%Y-%m-%dT%H:%M:%S");
  g_autofree char *when = g_strdup_printf ("%s.%03dZ", stamp, g_date_time_get_microsecond (now) / 1000);
  json_builder_set_member_name (b, "time_utc");
  json_builder_add_string_value (b, when);
  json_builder_set_member_name (b, "width");
  json_builder_add_int_value (b, ds_scene_width (scene));
  json_builder_set_member_name (b, "height");
  json_builder_add_int_value (b, ds_scene_height (scene));
  json_builder_set_member_name (b, "bit_depth");
  json_builder_add_int_value (b, ds_scene_bit_depth (scene));
  json_builder_set_member_name (b, "saturation_dn");
  json_builder_add_int_value (b, (gint64) ds_renderer_saturation_dn (r, gain));
  const char *pf = pixel_format_name (ds_scene_bit_depth (scene));
  if (pf) {
    json_builder_set_member_name (b, "pixel_format");
    json_builder_add_string_value (b, pf);
  }
  json_builder_set_member_name (b, "exposure_us");
  json_builder_add_double_value (b, exposure);
  json_builder_set_member_name (b, "gain_db");
  json_builder_add_double_value (b, gain);
  json_builder_set_member_name (b, "pattern");
  json_builder_begin_object (b);
  json_builder_set_member_name (b, "kind");
  json_builder_add_string_value (b, ds_scene_pattern_is_sine (scene) ? "sine" : "square");
  json_builder_set_member_name (b, "period_px");
  json_builder_add_double_value (b, ds_scene_period_px (scene));
  json_builder_set_member_name (b, "duty");
  json_builder_add_double_value (b, ds_scene_duty (scene));
  json_builder_set_member_name (b, "black_level");
  json_builder_add_double_value (b, ds_scene_black_level (scene));
  /* The simulator's convention: phase 0 lights the stripe centred on column 0. */
  json_builder_set_member_name (b, "phase_offset_cycles");
  json_builder_add_double_value (b, 0.0);
  json_builder_end_object (b);
  json_builder_set_member_name (b, "n_phases");
  json_builder_add_int_value (b, phases);
  json_builder_set_member_name (b, "frames");
  json_builder_begin_array (b);
  for (int k = 0; k < phases; k++) {
    g_autofree char *name = g_strdup_printf ("phase-%02d.png", k);
    json_builder_begin_object (b);
    json_builder_set_member_name (b, "file");
    json_builder_add_string_value (b, name);
    json_builder_set_member_name (b, "phase");
    json_builder_add_int_value (b, k);
    if (moves) {
      /* Optional: where the moving objects were (docs/scene-format.md, "Motion"). */
      json_builder_set_member_name (b, "time_s");
      json_builder_add_double_value (b, frame_time_s (k, interval, exposure));
    }
    json_builder_end_object (b);
  }
  json_builder_end_array (b);
  if (has_black) {
    json_builder_set_member_name (b, "black");
    json_builder_begin_object (b);
    json_builder_set_member_name (b, "files");
    json_builder_begin_array (b);
    json_builder_add_string_value (b, "black.png");
    json_builder_end_array (b);
    json_builder_end_object (b);
  }
  /* Optional keys (kept and ignored by readers that do not know them). */
  g_autofree char *abs_scene = g_canonicalize_filename (scene_path, NULL);
  json_builder_set_member_name (b, "scene");
  json_builder_add_string_value (b, abs_scene);
  json_builder_set_member_name (b, "seed");
  json_builder_add_int_value (b, seed);
  json_builder_set_member_name (b, "truth");
  json_builder_begin_object (b);
  json_builder_set_member_name (b, "transmissive");
  json_builder_add_string_value (b, "truth_transmissive.tiff");
  json_builder_set_member_name (b, "scattered");
  json_builder_add_string_value (b, "truth_scattered.tiff");
  if (moves) {
    json_builder_set_member_name (b, "time_s");
    json_builder_add_double_value (b, truth_time_s (phases, interval, exposure));
  }
  json_builder_end_object (b);
  json_builder_end_object (b);
  g_autoptr (JsonGenerator) gen = json_generator_new ();
  g_autoptr (JsonNode) root = json_builder_get_root (b);
  json_generator_set_root (gen, root);
  json_generator_set_pretty (gen, TRUE);
  gsize len = 0;
  g_autofree char *text = json_generator_to_data (gen, &len);
  g_autofree char *path = g_build_filename (dir, "frames.json", NULL);
  return g_file_set_contents_full (path, text, (gssize) len,
                                   G_FILE_SET_CONTENTS_CONSISTENT | G_FILE_SET_CONTENTS_DURABLE, 0644, error);
}

static int
fail (const GError *error)
{
  fprintf (stderr, "descatter-sim: %s\n", error->message);
  return 1;
}

int
ds_sim_render_main (int argc, char **argv)
{
  int phases = 0;
  double exposure = 0, gain = 0, interval = 0;
  gint64 seed = 1;
  g_autofree char *out = NULL;
  GOptionEntry entries[] = {
    { "phases", 'n', 0, G_OPTION_ARG_INT, &phases, "phases N (>= 2)", "N" },
    { "out", 'o', 0, G_OPTION_ARG_FILENAME, &out, "output folder", "DIR" },
    { "exposure-us", 'e', 0, G_OPTION_ARG_DOUBLE, &exposure, "exposure (default: the scene's)", "E" },
    { "gain-db", 'g', 0, G_OPTION_ARG_DOUBLE, &gain, "gain (dB)", "G" },
    { "frame-interval-us", 0, 0, G_OPTION_ARG_DOUBLE, &interval,
      "time between frame starts, for moving objects (default: the exposure, frames back to back)", "T" },
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
  if (!r)
    return fail (error);
  if (exposure <= 0)
    exposure = ds_scene_default_exposure_us (scene);
  if (interval == 0)
    interval = exposure;
  if (!(interval >= exposure && interval <= 1e7)) {
    fprintf (stderr, "descatter-sim render: --frame-interval-us %g must be in [exposure %g, 1e7]\n", interval,
             exposure);
    return 2;
  }
  if (g_mkdir_with_parents (out, 0755) != 0) {
    fprintf (stderr, "descatter-sim: %s: %s\n", out, g_strerror (errno));
    return 1;
  }
  /* A sidecar from an earlier render would vouch for a folder being rewritten: it goes first. */
  g_autofree char *sidecar = g_build_filename (out, "frames.json", NULL);
  if (g_unlink (sidecar) != 0 && errno != ENOENT) {
    fprintf (stderr, "descatter-sim: %s: %s\n", sidecar, g_strerror (errno));
    return 1;
  }
  for (int k = 0; k < phases; k++) {
    DsRenderRequest req = { .phase = (guint) k, .n_phases = (guint) phases, .illuminator_on = TRUE,
                            .exposure_us = exposure, .gain_db = gain, .seed = (guint64) seed * 1000 + (guint64) k,
                            .time_s = frame_time_s (k, interval, exposure) };
    g_autoptr (DsImage) f = ds_renderer_render (r, &req, &error);
    g_autofree char *path = g_strdup_printf ("%s/phase-%02d.png", out, k);
    if (!f || !ds_image_write (f, path, &error))
      return fail (error);
  }
  /* Ambient light (and the sensor's dark signal) show in a frame with the illuminator off:
   * written whenever the scene has ambient light, as the folder layout expects. */
  gboolean has_black = ds_scene_spec (scene)->has_ambient;
  if (has_black) {
    DsRenderRequest req = { .illuminator_on = FALSE, .exposure_us = exposure, .gain_db = gain,
                            .seed = (guint64) seed * 1000 + 999, .time_s = frame_time_s (phases, interval, exposure) };
    g_autoptr (DsImage) f = ds_renderer_render (r, &req, &error);
    g_autofree char *path = g_strdup_printf ("%s/black.png", out);
    if (!f || !ds_image_write (f, path, &error))
      return fail (error);
  }
  DsImage *t = NULL, *s = NULL;
  if (!ds_renderer_truth_at (r, exposure, gain, truth_time_s (phases, interval, exposure), &t, &s, &error))
    return fail (error);
  g_autoptr (DsImage) tt = t;
  g_autoptr (DsImage) ts = s;
  g_autofree char *p1 = g_strdup_printf ("%s/truth_transmissive.tiff", out);
  g_autofree char *p2 = g_strdup_printf ("%s/truth_scattered.tiff", out);
  if (!ds_image_write (tt, p1, &error) || !ds_image_write (ts, p2, &error))
    return fail (error);
  if (!write_sidecar (out, argv[1], r, phases, exposure, interval, gain, seed, has_black, &error))
    return fail (error);
  printf ("descatter-sim: %d phases of %s written to %s\n", phases, argv[1], out);
  return 0;
}
