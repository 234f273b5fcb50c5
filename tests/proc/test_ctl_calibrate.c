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
#include "tests/common/test_tree.h"

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

static char *render_scene (const char *scene_text);

/* The clear scene's text with the [illuminator] keys replaced and `extra` appended. */
static char *
clear_scene (const char *period, const char *duty, const char *black, const char *blur, const char *irradiance,
             const char *extra)
{
  g_autofree char *text = NULL;
  g_autofree char *scene_path = g_build_filename (DS_SCENES_DIR, "clear-grid.scene", NULL);
  g_assert_true (g_file_get_contents (scene_path, &text, NULL, NULL));
  g_autofree char *illum = g_strdup_printf ("[illuminator]\nperiod-px=%s\nduty=%s\nblack-level=%s\nedge-blur-px=%s\n%s%s%s",
                                            period, duty, black, blur, irradiance ? "irradiance=" : "",
                                            irradiance ? irradiance : "", irradiance ? "\n" : "");
  /* drop the original keys of the group, keep pattern and irradiance */
  g_auto (GStrv) lines = g_strsplit (text, "\n", -1);
  GString *scene = g_string_new (NULL);
  gboolean skip = FALSE; /* the scene's [medium] when extra brings its own */
  for (guint i = 0; lines[i]; i++) {
    if (lines[i][0] == '[')
      skip = extra && strstr (extra, "[medium]") && g_str_equal (lines[i], "[medium]");
    if (skip)
      continue;
    if (g_str_has_prefix (lines[i], "period-px=") || g_str_has_prefix (lines[i], "duty=") ||
        g_str_has_prefix (lines[i], "black-level=") || g_str_has_prefix (lines[i], "edge-blur-px=") ||
        (irradiance && g_str_has_prefix (lines[i], "irradiance=")))
      continue;
    g_string_append (scene, g_str_equal (lines[i], "[illuminator]") ? illum : lines[i]);
    if (!g_str_equal (lines[i], "[illuminator]"))
      g_string_append_c (scene, '\n');
  }
  if (extra)
    g_string_append (scene, extra);
  return g_string_free (scene, FALSE);
}

/* Renders the clear scene, with the [illuminator] keys replaced; frames.json removed. */
static char *
render (const char *period, const char *duty, const char *black, const char *blur)
{
  g_autofree char *text = clear_scene (period, duty, black, blur, NULL, NULL);
  return render_scene (text);
}

/* Renders a scene's text into DIR/set (8 phases); returns DIR. frames.json removed. */
static char *
render_scene (const char *scene_text)
{
  char *dir = g_dir_make_tmp ("ds-cal-XXXXXX", NULL);
  g_autofree char *spath = g_build_filename (dir, "reference.scene", NULL);
  g_assert_true (g_file_set_contents (spath, scene_text, -1, NULL));
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
  /* a clear reference: no scattering warning */
  g_assert_false (json_object_get_boolean_member (json_object_get_object_member (c, "scattering"), "suspected"));
  g_assert_false (json_object_has_member (c, "warning"));
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

/* The scattering check's verdict on a rendered scene, with the text output's warning (in the
 * comment above the configuration lines and on stderr) when and only when it is suspected. */
static gboolean
scatters (const char *scene_text, double *black_level)
{
  g_autofree char *dir = render_scene (scene_text);
  g_autofree char *set = g_build_filename (dir, "set", NULL);
  g_autoptr (JsonParser) parser = json_parser_new ();
  JsonObject *c = calibrate (set, parser);
  JsonObject *sc = json_object_get_object_member (c, "scattering");
  gboolean suspected = json_object_get_boolean_member (sc, "suspected");
  *black_level = json_object_get_double_member (c, "black_level");
  g_test_message ("black level %.4f, scattering suspected %d: shape residual %.4f (noise %.5f), off-stripe dim %.3f "
                  "bright %.3f at contrast x%.2f",
                  *black_level, suspected, json_object_get_double_member (sc, "shape_residual"),
                  json_object_get_double_member (sc, "shape_noise"), json_object_get_double_member (sc, "off_level_dim"),
                  json_object_get_double_member (sc, "off_level_bright"),
                  json_object_get_double_member (sc, "brightness_contrast"));
  g_assert_true (json_object_has_member (c, "warning") == suspected);
  const char *argv[] = { DS_CTL_BIN, "calibrate", "--bit-depth", "12", set, NULL };
  int status;
  g_autofree char *out = spawn (argv, &status);
  g_assert_true (g_spawn_check_wait_status (status, NULL));
  g_assert_true ((strstr (out, "# WARNING: the reference scatters") != NULL) == suspected);
  g_assert_true ((strstr (out, "descatterctl calibrate: warning: the reference scatters") != NULL) == suspected);
  if (suspected) {
    g_assert_nonnull (strstr (out, "not to be trusted"));
    g_assert_nonnull (strstr (out, "Calibrate on a clear reference"));
  }
  test_remove_tree (dir);
  return suspected;
}

/* Clear references of other duties, black levels, blurs and light levels (noise) never warn. */
static void
test_clear_never_warns (void)
{
  const char *cases[][5] = {
    { "14", "0.67", "0.14", "0.5", "0.5" },
    { "13.5", "0.42", "0.12", "1.5", "0.04" },
    { "8.5", "0.55", "0", "0.5", "0.03" },
    { "10.25", "0.41", "0.12", "0", "0.05" },
  };
  for (guint i = 0; i < G_N_ELEMENTS (cases); i++) {
    g_autofree char *text = clear_scene (cases[i][0], cases[i][1], cases[i][2], cases[i][3], cases[i][4], NULL);
    double b;
    g_assert_false (scatters (text, &b));
    g_assert_cmpfloat (fabs (b - g_ascii_strtod (cases[i][2], NULL)), <, 0.01);
  }
}

/* References in a forward-scattering medium (g 0.9; a part of the scattered light keeps the
 * stripes) read scattered light as black level: the calibration says so. The second is the
 * lab-user trial's kind of scene (gen-21-00: lines and a grid that absorb, black level 0.12),
 * over the scene's own wire grid. */
static void
test_scattering_warns (void)
{
  static const char medium[] = "\n[medium]\nthickness-mm=5\nmua=0.0043\nmus=0.35\ng=0.9\nn=1.33\nphotons=100000\n"
                               "seed=7\n";
  g_autofree char *grid = clear_scene ("12", "0.5", "0", "0", NULL, medium);
  double b;
  g_assert_true (scatters (grid, &b));
  g_assert_cmpfloat (b, >, 0.05); /* what the check is for: the scene's black level is 0 */
  static const char lines[] = "\n[medium]\nthickness-mm=5.3\nmua=0.088\nmus=0.35\ng=0.91\nn=1.43\nphotons=100000\n"
                              "seed=11\n\n[object.lines]\nshape=lines\npitch=17\nline-width=2\ndepth-mm=0.33\n"
                              "transmittance=0\n\n[object.mesh]\nshape=grid\npitch=17\nline-width=4\ndepth-mm=1.69\n"
                              "transmittance=0\n";
  g_autofree char *absorbing = clear_scene ("13.5", "0.42", "0.12", "1.0", NULL, lines);
  g_assert_true (scatters (absorbing, &b));
  g_assert_cmpfloat (b, >, 0.17);
}

/* A clear reference lit by a sine illuminator (the lab-user trial's gen-22-02 read it as a
 * blurred square and warned of scattering): pattern sine, said so with the remedy, no warning.
 * At 13 px the folder's detected period is 13.016: refined on the phase set, or the smeared
 * profile fits neither model. */
static void
test_clear_sine (void)
{
  g_autofree char *text = clear_scene ("13", "0.5", "0", "0", NULL, NULL);
  char *at = strstr (text, "pattern=square");
  g_assert_nonnull (at);
  memcpy (at, "pattern=sine  ", 14);
  double b;
  g_assert_false (scatters (text, &b));
  g_autofree char *dir = render_scene (text);
  g_autofree char *set = g_build_filename (dir, "set", NULL);
  g_autoptr (JsonParser) parser = json_parser_new ();
  JsonObject *c = calibrate (set, parser);
  g_assert_cmpstr (json_object_get_string_member (c, "pattern"), ==, "sine");
  g_assert_nonnull (strstr (json_object_get_string_member (c, "pattern_notice"), "pattern=sine"));
  g_assert_false (json_object_has_member (c, "warning"));
  g_assert_cmpfloat (fabs (json_object_get_double_member (c, "period_px") / 13 - 1), <, 3e-4);
  test_remove_tree (dir);
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
  g_assert_nonnull (strstr (out, "no stripes at any period"));
  test_remove_tree (dir);
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  g_test_add_func ("/ctl-calibrate/clear-sharp", test_clear_sharp);
  g_test_add_func ("/ctl-calibrate/narrow-blurred", test_narrow_blurred);
  g_test_add_func ("/ctl-calibrate/no-stripes", test_no_stripes);
  g_test_add_func ("/ctl-calibrate/clear-never-warns", test_clear_never_warns);
  g_test_add_func ("/ctl-calibrate/scattering-warns", test_scattering_warns);
  g_test_add_func ("/ctl-calibrate/clear-sine", test_clear_sine);
  return g_test_run ();
}
