/* proc/calibration_json.h: a calibration written as JSON reads back field for field; the
 * document has exactly the members docs/protocol.md lists for the calibrate reply, in its order;
 * a member missing or of the wrong type is refused naming it; an older document without the
 * scattering check (or without its flags) still reads. */
#include <string.h>

#include "proc/calibration_json.h"
#include "proc/proc_error.h"

static DsCalibration
sample_calibration (void)
{
  DsCalibration c;
  memset (&c, 0, sizeof c);
  c.n_phases = 16;
  c.frames_per_phase = 3;
  c.pattern = DS_PATTERN_SINE;
  c.period_px = 12.25;
  c.period_measured = TRUE;
  c.phase_offset_cycles = 0.125;
  c.offset_spread = 0.0625;
  c.duty = 0.5;
  c.black_level = 0.03125;
  c.black_level_measured = TRUE; /* from a second period: no black_level_notice */
  c.contrast = 0.75;
  c.second_period_px = 25;
  c.second_contrast = 0.875;
  c.harmonic_gain = 0.5625;
  c.harmonic_gain_theory = 0.625;
  c.edge_blur_px = 0.75;
  c.pixels_used = G_GUINT64_CONSTANT (5000000000);
  c.scatter.scattering = TRUE;
  c.scatter.measured = TRUE;
  c.scatter.spatial = FALSE;
  c.scatter.off_dim = 0.25;
  c.scatter.off_bright = 0.125;
  c.scatter.brightness_contrast = 2.5;
  c.scatter.shape_misfit = TRUE;
  c.scatter.shape_residual = 0.0375;
  c.scatter.shape_noise = 0.005;
  return c;
}

static JsonObject *
to_object (const DsCalibration *c)
{
  g_autoptr (JsonBuilder) b = json_builder_new ();
  json_builder_begin_object (b);
  ds_calibration_add_json_members (b, c);
  json_builder_end_object (b);
  g_autoptr (JsonNode) root = json_builder_get_root (b);
  return json_object_ref (json_node_get_object (root));
}

static void
test_round_trip (void)
{
  DsCalibration c = sample_calibration ();
  g_autoptr (JsonObject) o = to_object (&c);
  /* docs/protocol.md, the calibrate reply: every member, in this order */
  static const char *const keys[] = { "pattern", "n_phases", "frames_per_phase", "period_measured", "period_px",
                                      "phase_offset_cycles", "offset_spread_cycles", "duty", "black_level",
                                      "black_level_measured", "contrast", "second_period_px", "second_contrast",
                                      "harmonic_gain", "harmonic_gain_theory", "edge_blur_px", "pixels_used",
                                      "scattering", "pattern_check", "warning" };
  g_autoptr (GList) names = json_object_get_members (o);
  guint i = 0;
  for (GList *l = names; l; l = l->next, i++) {
    g_assert_cmpuint (i, <, G_N_ELEMENTS (keys));
    g_assert_cmpstr (l->data, ==, keys[i]);
  }
  g_assert_cmpuint (i, ==, G_N_ELEMENTS (keys));
  static const char *const scatter_keys[] = { "suspected", "measured", "off_level_dim", "off_level_bright",
                                              "brightness_contrast", "dim_parts_brighter", "shape_residual",
                                              "shape_noise", "shape_misfit" };
  g_autoptr (GList) snames = json_object_get_members (json_object_get_object_member (o, "scattering"));
  i = 0;
  for (GList *l = snames; l; l = l->next, i++)
    g_assert_cmpstr (l->data, ==, scatter_keys[i]);
  g_assert_cmpuint (i, ==, G_N_ELEMENTS (scatter_keys));
  static const char *const pattern_keys[] = { "expected", "detected", "sine_residual", "square_residual",
                                              "square_blur_px", "noise", "square_fits" };
  g_autoptr (GList) pnames = json_object_get_members (json_object_get_object_member (o, "pattern_check"));
  i = 0;
  for (GList *l = pnames; l; l = l->next, i++)
    g_assert_cmpstr (l->data, ==, pattern_keys[i]);
  g_assert_cmpuint (i, ==, G_N_ELEMENTS (pattern_keys));
  g_assert_cmpint (json_object_get_int_member (o, "pixels_used"), ==, 5000000000);
  g_assert_cmpstr (json_object_get_string_member (o, "pattern"), ==, "sine");

  DsCalibration back;
  g_autoptr (GError) error = NULL;
  g_assert_true (ds_calibration_from_json (o, &back, &error));
  g_assert_no_error (error);
  g_assert_cmpint (back.pattern, ==, c.pattern);
  g_assert_cmpuint (back.n_phases, ==, 16);
  g_assert_cmpuint (back.frames_per_phase, ==, 3);
  g_assert_cmpuint (back.pixels_used, ==, c.pixels_used);
  g_assert_true (back.period_measured);
  g_assert_cmpfloat (back.period_px, ==, 12.25);
  g_assert_cmpfloat (back.phase_offset_cycles, ==, 0.125);
  g_assert_cmpfloat (back.offset_spread, ==, 0.0625);
  g_assert_cmpfloat (back.duty, ==, 0.5);
  g_assert_cmpfloat (back.black_level, ==, 0.03125);
  g_assert_cmpfloat (back.harmonic_gain, ==, 0.5625);
  g_assert_cmpfloat (back.harmonic_gain_theory, ==, 0.625);
  g_assert_cmpfloat (back.edge_blur_px, ==, 0.75);
  g_assert_true (back.scatter.scattering && back.scatter.measured && !back.scatter.spatial && back.scatter.shape_misfit);
  g_assert_cmpfloat (back.scatter.off_dim, ==, 0.25);
  g_assert_cmpfloat (back.scatter.off_bright, ==, 0.125);
  g_assert_cmpfloat (back.scatter.brightness_contrast, ==, 2.5);
  g_assert_cmpfloat (back.scatter.shape_residual, ==, 0.0375);
  g_assert_cmpfloat (back.scatter.shape_noise, ==, 0.005);
}

static void
expect_refused (const char *json, const char *names)
{
  g_autoptr (JsonParser) p = json_parser_new ();
  g_assert_true (json_parser_load_from_data (p, json, -1, NULL));
  DsCalibration c;
  g_autoptr (GError) error = NULL;
  g_assert_false (ds_calibration_from_json (json_node_get_object (json_parser_get_root (p)), &c, &error));
  g_assert_error (error, DS_PROC_ERROR, DS_PROC_ERROR_INVALID_ARGUMENT);
  g_test_message ("%s", error->message);
  g_assert_nonnull (strstr (error->message, names));
}

static char *
document_without (const char *key, const char *replacement)
{
  DsCalibration c = sample_calibration ();
  g_autoptr (JsonObject) o = to_object (&c);
  JsonObject *target = o;
  const char *dot = strchr (key, '.');
  if (dot) {
    target = json_object_get_object_member (o, "scattering");
    key = dot + 1;
  }
  json_object_remove_member (target, key);
  if (replacement) {
    g_autoptr (JsonParser) p = json_parser_new ();
    g_assert_true (json_parser_load_from_data (p, replacement, -1, NULL));
    json_object_set_member (target, key, json_node_copy (json_parser_get_root (p)));
  }
  g_autoptr (JsonNode) root = json_node_new (JSON_NODE_OBJECT);
  json_node_set_object (root, o);
  return json_to_string (root, FALSE);
}

static void
test_refused (void)
{
  static const struct {
    const char *key, *value, *message;
  } cases[] = {
    { "pattern", NULL, "\"pattern\" is missing" },
    { "pattern", "\"stripes\"", "neither" },
    { "n_phases", NULL, "\"n_phases\" is missing" },
    { "n_phases", "-3", "\"n_phases\" is not a count" },
    { "frames_per_phase", "2.5", "\"frames_per_phase\" is not a count" },
    { "pixels_used", "\"many\"", "\"pixels_used\" is not a count" },
    { "period_measured", "1", "\"period_measured\" is not a boolean" },
    { "period_px", "\"12\"", "\"period_px\" is not a number" },
    { "edge_blur_px", NULL, "\"edge_blur_px\" is missing" },
    { "black_level", "[0.1]", "\"black_level\" is not a number" },
    { "scattering", "3", "\"scattering\" is not an object" },
    { "scattering.shape_noise", NULL, "\"scattering.shape_noise\" is missing" },
    { "scattering.off_level_dim", "true", "\"scattering.off_level_dim\" is not a number" },
    { "scattering.suspected", "\"yes\"", "\"scattering.suspected\" is not a boolean" },
  };
  for (guint i = 0; i < G_N_ELEMENTS (cases); i++) {
    g_autofree char *json = document_without (cases[i].key, cases[i].value);
    expect_refused (json, cases[i].message);
  }
}

/* An older daemon's reply: no scattering check at all, or one without its flags. */
static void
test_older_documents (void)
{
  DsCalibration c;
  g_autoptr (GError) error = NULL;
  g_autofree char *no_check = document_without ("scattering", NULL);
  g_autoptr (JsonParser) p = json_parser_new ();
  g_assert_true (json_parser_load_from_data (p, no_check, -1, NULL));
  g_assert_true (ds_calibration_from_json (json_node_get_object (json_parser_get_root (p)), &c, &error));
  g_assert_false (c.scatter.measured || c.scatter.scattering);
  g_assert_cmpfloat (c.harmonic_gain, ==, 0.5625);

  g_autofree char *no_flag = document_without ("scattering.shape_misfit", NULL);
  g_autoptr (JsonParser) q = json_parser_new ();
  g_assert_true (json_parser_load_from_data (q, no_flag, -1, NULL));
  g_assert_true (ds_calibration_from_json (json_node_get_object (json_parser_get_root (q)), &c, &error));
  g_assert_no_error (error);
  g_assert_false (c.scatter.shape_misfit);
  g_assert_true (c.scatter.scattering);
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  g_test_add_func ("/calibration-json/round-trip", test_round_trip);
  g_test_add_func ("/calibration-json/refused", test_refused);
  g_test_add_func ("/calibration-json/older-documents", test_older_documents);
  return g_test_run ();
}
