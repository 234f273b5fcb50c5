/* `descatterctl calibrate` against scenes whose illuminator is known: descatter-sim renders a
 * clear scene (no scattering) with sharp stripes, and one with narrow, blurred stripes and a
 * black level; the frames.json is removed so that nothing is read from it. The calibrated
 * values must match the scene file's, and the calibrated harmonic gain must make the sine
 * estimator agree with the simulator's truth image (the theory's gain does not). */
#include <glib.h>
#include <glib/gstdio.h>
#include <json-glib/json-glib.h>
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "proc/image.h"
#include "tests/test_tree.h"

static char *
spawn (const char *const *argv, int *status)
{
  g_autofree char *out = NULL, *err = NULL;
  g_autoptr (GError) error = NULL;
  g_assert_true (g_spawn_sync (NULL, (char **) argv, NULL, G_SPAWN_DEFAULT, NULL, NULL, &out, &err, status, &error));
  g_assert_no_error (error);
  if (err && *err)
    g_test_message ("%s stderr: %s", argv[1], err);
  return g_strconcat (out ? out : "", err ? err : "", NULL);
}

/* Renders the clear scene, with the [illuminator] keys replaced; frames.json removed. */
static char *
render (const char *period, const char *duty, const char *black, const char *blur)
{
  g_autofree char *text = NULL;
  g_autofree char *scene_path = g_build_filename (DS_SCENES_DIR, "clear-grid.scene", NULL);
  g_assert_true (g_file_get_contents (scene_path, &text, NULL, NULL));
  g_autofree char *illum = g_strdup_printf ("[illuminator]\nperiod-px=%s\nduty=%s\nblack-level=%s\nedge-blur-px=%s\n",
                                            period, duty, black, blur);
  /* drop the original keys of the group, keep pattern and irradiance */
  g_auto (GStrv) lines = g_strsplit (text, "\n", -1);
  GString *scene = g_string_new (NULL);
  for (guint i = 0; lines[i]; i++) {
    if (g_str_has_prefix (lines[i], "period-px=") || g_str_has_prefix (lines[i], "duty=") ||
        g_str_has_prefix (lines[i], "black-level=") || g_str_has_prefix (lines[i], "edge-blur-px="))
      continue;
    g_string_append (scene, g_str_equal (lines[i], "[illuminator]") ? illum : lines[i]);
    if (!g_str_equal (lines[i], "[illuminator]"))
      g_string_append_c (scene, '\n');
  }
  char *dir = g_dir_make_tmp ("ds-cal-XXXXXX", NULL);
  g_autofree char *spath = g_build_filename (dir, "reference.scene", NULL);
  g_assert_true (g_file_set_contents (spath, scene->str, -1, NULL));
  g_string_free (scene, TRUE);
  g_autofree char *out = g_build_filename (dir, "set", NULL);
  const char *argv[] = { DS_SIM_BIN, "render", spath, "--phases", "8", "--out", out, "--seed", "3", NULL };
  int status;
  g_autofree char *log = spawn (argv, &status);
  g_assert_true (g_spawn_check_wait_status (status, NULL));
  g_autofree char *sidecar = g_build_filename (out, "frames.json", NULL);
  g_remove (sidecar);
  return dir;
}

static JsonObject *
calibrate (const char *set, JsonParser *parser)
{
  const char *argv[] = { DS_CTL_BIN, "calibrate", "--json", "--quiet", "--bit-depth", "12", set, NULL };
  int status;
  g_autofree char *out = spawn (argv, &status);
  g_assert_true (g_spawn_check_wait_status (status, NULL));
  g_autoptr (GError) error = NULL;
  g_assert_true (json_parser_load_from_data (parser, out, -1, &error));
  g_assert_no_error (error);
  return json_node_get_object (json_parser_get_root (parser));
}

/* The text output's descatterd.conf block is a key file whose [illuminator] values are the
 * scene's, and its separate line carries the same numbers. */
static void
check_config_lines (const char *set, double period, double duty, double black)
{
  const char *argv[] = { DS_CTL_BIN, "calibrate", "--quiet", "--bit-depth", "12", set, NULL };
  int status;
  g_autofree char *out = spawn (argv, &status);
  g_assert_true (g_spawn_check_wait_status (status, NULL));
  const char *conf = strstr (out, "# descatterd.conf\n");
  const char *sep = strstr (out, "# descatterctl separate\n");
  g_assert_nonnull (conf);
  g_assert_nonnull (sep);
  g_autofree char *block = g_strndup (conf, (gsize) (sep - conf));
  g_autoptr (GKeyFile) kf = g_key_file_new ();
  g_autoptr (GError) error = NULL;
  g_assert_true (g_key_file_load_from_data (kf, block, -1, G_KEY_FILE_NONE, &error));
  g_assert_no_error (error);
  g_autofree char *pattern = g_key_file_get_string (kf, "illuminator", "pattern", NULL);
  g_assert_cmpstr (pattern, ==, "square");
  g_assert_cmpfloat (fabs (g_key_file_get_double (kf, "illuminator", "period-px", NULL) / period - 1), <, 1e-3);
  g_assert_cmpfloat (fabs (g_key_file_get_double (kf, "illuminator", "duty", NULL) - duty), <, 0.01);
  g_assert_cmpfloat (fabs (g_key_file_get_double (kf, "illuminator", "black-level", NULL) - black), <, 0.01);
  double p = NAN;
  const char *opt = strstr (sep, "--period ");
  g_assert_nonnull (opt);
  g_assert_cmpint (sscanf (opt, "--period %lf", &p), ==, 1);
  g_assert_cmpfloat (fabs (p / period - 1), <, 1e-3);
}

/* Mean over the clearly lit pixels of the separated transmissive image over the truth. */
static double
sine_over_truth (const char *dir, const char *set, double duty, double black, double h)
{
  g_autofree char *out = g_build_filename (dir, "sine", NULL);
  g_autofree char *sduty = g_strdup_printf ("%.6f", duty), *sblack = g_strdup_printf ("%.6f", black);
  g_autofree char *sh = g_strdup_printf ("%.6f", h);
  g_autoptr (GPtrArray) args = g_ptr_array_new ();
  const char *fixed[] = { DS_CTL_BIN, "separate", "-q", "--no-preview", "--bit-depth", "12", "--estimator", "sine",
                          "--duty", sduty, "--black-level", sblack, "--out", out };
  for (guint i = 0; i < G_N_ELEMENTS (fixed); i++)
    g_ptr_array_add (args, (gpointer) fixed[i]);
  if (h > 0) { /* else the theory's gain */
    g_ptr_array_add (args, (gpointer) "--harmonic-gain");
    g_ptr_array_add (args, sh);
  }
  g_ptr_array_add (args, (gpointer) set);
  g_ptr_array_add (args, NULL);
  const char *const *argv = (const char *const *) args->pdata;
  int status;
  g_autofree char *log = spawn (argv, &status);
  g_assert_true (g_spawn_check_wait_status (status, NULL));
  g_autofree char *tpath = g_build_filename (set, "truth_transmissive.tiff", NULL);
  g_autofree char *spath = g_build_filename (out, "transmissive.tiff", NULL);
  g_autoptr (DsImage) truth = ds_image_read (tpath, NULL);
  g_autoptr (DsImage) sep = ds_image_read (spath, NULL);
  double top = 0, st = 0, ss = 0;
  for (guint y = 0; y < truth->height; y++)
    for (guint x = 0; x < truth->width; x++)
      top = MAX (top, ((float *) ds_image_row (truth, y))[x]);
  for (guint y = 0; y < truth->height; y++)
    for (guint x = 0; x < truth->width; x++) {
      float t = ((float *) ds_image_row (truth, y))[x];
      if (t > 0.3 * top) {
        st += t;
        ss += ((float *) ds_image_row (sep, y))[x];
      }
    }
  return ss / st;
}

static void
check_scene (double period, double duty, double black, double blur)
{
  g_autofree char *sp = g_strdup_printf ("%g", period), *sd = g_strdup_printf ("%g", duty);
  g_autofree char *sb = g_strdup_printf ("%g", black), *sbl = g_strdup_printf ("%g", blur);
  g_autofree char *dir = render (sp, sd, sb, sbl);
  g_autofree char *set = g_build_filename (dir, "set", NULL);
  g_autoptr (JsonParser) parser = json_parser_new ();
  JsonObject *c = calibrate (set, parser);
  double p = json_object_get_double_member (c, "period_px"), a = json_object_get_double_member (c, "duty");
  double b = json_object_get_double_member (c, "black_level"), s = json_object_get_double_member (c, "edge_blur_px");
  double o = json_object_get_double_member (c, "phase_offset_cycles");
  double h = json_object_get_double_member (c, "harmonic_gain");
  g_test_message ("scene P %g a %g b %g sigma %g: calibrated P %.4f a %.4f b %.4f sigma %.3f offset %.4f h %.4f", period,
                  duty, black, blur, p, a, b, s, o, h);
  g_assert_true (json_object_get_boolean_member (c, "period_measured"));
  g_assert_cmpfloat (fabs (p / period - 1), <, 1e-3);
  g_assert_cmpfloat (fabs (a - duty), <, 0.01);
  g_assert_cmpfloat (fabs (b - black), <, 0.01);
  g_assert_cmpfloat (fabs (s - blur), <, 0.1);
  g_assert_cmpfloat (fabs (o - round (o)), <, 0.01); /* the simulator's phase 0 is at 0 */
  check_config_lines (set, period, duty, black);
  /* the calibrated gain makes the sine estimator right; the sharp-stripe theory's is off
   * wherever the stripes are blurred (or sampled coarsely) */
  double with_cal = sine_over_truth (dir, set, a, b, h);
  double with_theory = sine_over_truth (dir, set, a, b, 0);
  g_test_message ("sine estimator / truth: calibrated h %.4f, theory h %.4f", with_cal, with_theory);
  g_assert_cmpfloat (fabs (with_cal - 1), <, 0.01);
  if (blur > 0)
    g_assert_cmpfloat (fabs (with_theory - 1), >, 0.1);
  test_remove_tree (dir);
}

static void
test_clear_sharp (void)
{
  check_scene (12, 0.5, 0, 0);
}

static void
test_narrow_blurred (void)
{
  check_scene (9.5, 0.3, 0.1, 1.0);
}

/* Frames without stripes: refused with a reason. */
static void
test_no_stripes (void)
{
  g_autofree char *dir = g_dir_make_tmp ("ds-cal-XXXXXX", NULL);
  GRand *r = g_rand_new_with_seed (1);
  for (guint k = 0; k < 4; k++) {
    g_autoptr (DsImage) img = ds_image_new (DS_SAMPLE_U16, 64, 16, NULL);
    for (guint y = 0; y < 16; y++)
      for (guint x = 0; x < 64; x++)
        ((guint16 *) ds_image_row (img, y))[x] = (guint16) (1000 + g_rand_int_range (r, 0, 20));
    g_autofree char *path = g_strdup_printf ("%s/p%u.png", dir, k);
    g_assert_true (ds_image_write (img, path, NULL));
  }
  g_rand_free (r);
  const char *argv[] = { DS_CTL_BIN, "calibrate", dir, NULL };
  int status;
  g_autofree char *out = spawn (argv, &status);
  g_assert_false (g_spawn_check_wait_status (status, NULL));
  g_assert_nonnull (strstr (out, "no stripes found"));
  test_remove_tree (dir);
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  g_test_add_func ("/ctl-calibrate/clear-sharp", test_clear_sharp);
  g_test_add_func ("/ctl-calibrate/narrow-blurred", test_narrow_blurred);
  g_test_add_func ("/ctl-calibrate/no-stripes", test_no_stripes);
  return g_test_run ();
}
