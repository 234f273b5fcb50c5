/* `descatterctl separate` as a program: a generated phase folder whose scene has a closed-form
 * answer (Ld, Lg per pixel), run through ds_ctl_separate (), outputs read back from disk. */
#include <glib.h>
#include <glib/gstdio.h>
#include <json-glib/json-glib.h>
#include <math.h>
#include <string.h>

#include "daemon/ctl/ctl_separate.h"
#include "proc/image.h"
#include "separate_run.h"
#include "tests/common/test_tree.h"

#define W 37 /* odd on purpose */
#define H 9
#define N 8
#define P 8.0

/* The scene: direct and global light per pixel, chosen so that every expected value is an
 * integer (exact comparisons on the PNG outputs). */
static double ld_at (guint x, guint y) { return 1000.0 + 10.0 * x + 20.0 * (y % 3); }
static double lg_at (guint x, guint y) { return 40.0 * (10 + y) + 80.0 * (x % 4); }
static double dark_at (guint x, guint y) { return 50.0 + (x + y) % 5; }

/* Phase k: square stripes of duty a, black level b: lit where |frac(x/P - k/N)| < a/2.
 * value = dark + Ld (b + (1 - b) lit) + Lg (a + b (1 - a)). */
static void
make_folder_typed (const char *dir, double a, double b, gboolean with_black, DsSampleType type)
{
  for (guint k = 0; k < N; k++) {
    g_autoptr (DsImage) img = ds_image_new (type, W, H, NULL);
    for (guint y = 0; y < H; y++)
      for (guint x = 0; x < W; x++) {
        double u = x / P - (double) k / N;
        u -= floor (u + 0.5);
        double lit = fabs (u) < a / 2 ? 1.0 : 0.0;
        double v = (with_black ? dark_at (x, y) : 0.0) + ld_at (x, y) * (b + (1 - b) * lit) +
                   lg_at (x, y) * (a + b * (1 - a));
        g_assert_cmpfloat (v, ==, round (v));
        if (type == DS_SAMPLE_F32)
          ((float *) ds_image_row (img, y))[x] = (float) v;
        else
          ((guint16 *) ds_image_row (img, y))[x] = (guint16) v;
      }
    /* Names that sort wrongly as plain strings: phase order must come from natural order. */
    g_autofree char *path = g_strdup_printf ("%s/img_%u.%s", dir, k + 1 == 8 ? 10 : k + 1,
                                             type == DS_SAMPLE_F32 ? "tiff" : "png");
    g_assert_true (ds_image_write (img, path, NULL));
  }
  if (with_black) {
    g_autoptr (DsImage) black = ds_image_new (DS_SAMPLE_U16, W, H, NULL);
    for (guint y = 0; y < H; y++)
      for (guint x = 0; x < W; x++)
        ((guint16 *) ds_image_row (black, y))[x] = (guint16) dark_at (x, y);
    g_autofree char *path = g_build_filename (dir, "black.png", NULL);
    g_assert_true (ds_image_write (black, path, NULL));
  }
}

static void
make_folder (const char *dir, double a, double b, gboolean with_black)
{
  make_folder_typed (dir, a, b, with_black, DS_SAMPLE_U16);
}

/* The scale of a 16-bit PNG output, from separation.json's list of files. */
static double
png_scale (const char *out, const char *name)
{
  g_autofree char *path = g_build_filename (out, "separation.json", NULL);
  g_autoptr (JsonParser) parser = json_parser_new ();
  g_assert_true (json_parser_load_from_file (parser, path, NULL));
  JsonObject *files = json_object_get_object_member (json_node_get_object (json_parser_get_root (parser)), "files");
  return json_object_get_double_member (json_object_get_object_member (files, name), "scale");
}

static void
check_outputs (const char *out, double a, double b)
{
  (void) a;
  (void) b;
  /* direct.png and global.png are scaled to be visible: value = file / scale, scale a power
   * of two that puts the largest value in the upper half of 16 bits. */
  double sd = png_scale (out, "direct.png"), sg = png_scale (out, "global.png");
  int e;
  g_assert_cmpfloat (frexp (sd, &e), ==, 0.5);
  g_assert_cmpfloat (frexp (sg, &e), ==, 0.5);
  g_autoptr (DsImage) direct = separate_read_out (out, "direct.png");
  g_autoptr (DsImage) global = separate_read_out (out, "global.png");
  g_autoptr (DsImage) trans = separate_read_out (out, "transmissive.tiff");
  g_autoptr (DsImage) scat = separate_read_out (out, "scattered.tiff");
  g_autoptr (DsImage) mask = separate_read_out (out, "mask.png");
  g_assert_cmpint (direct->type, ==, DS_SAMPLE_U16);
  g_assert_cmpint (global->type, ==, DS_SAMPLE_U16);
  g_assert_cmpint (trans->type, ==, DS_SAMPLE_F32);
  g_assert_cmpint (scat->type, ==, DS_SAMPLE_F32);
  g_assert_cmpint (mask->type, ==, DS_SAMPLE_U8);
  for (guint y = 0; y < H; y++)
    for (guint x = 0; x < W; x++) {
      double ld = ld_at (x, y), lg = lg_at (x, y);
      g_assert_cmpfloat_with_epsilon (((float *) ds_image_row (trans, y))[x], ld, 1e-4 * ld);
      g_assert_cmpfloat_with_epsilon (((float *) ds_image_row (scat, y))[x], lg, 1e-4 * lg);
      g_assert_cmpuint (((guint16 *) ds_image_row (direct, y))[x], ==, (guint) (ld * sd));
      g_assert_cmpuint (((guint16 *) ds_image_row (global, y))[x], ==, (guint) (lg * sg));
      /* Clean, well-modulated, unsaturated data: no flag may be set. */
      g_assert_cmpuint (((guint8 *) ds_image_row (mask, y))[x], ==, 0);
    }
}

static void
test_defaults_with_black (void)
{
  g_autofree char *dir = g_dir_make_tmp ("ds-sep-XXXXXX", NULL);
  make_folder (dir, 0.5, 0.0, TRUE);
  g_assert_cmpint (separate_run ("--quiet", dir, NULL), ==, 0);
  check_outputs (dir, 0.5, 0.0);

  g_autofree char *json = g_build_filename (dir, "separation.json", NULL);
  g_autoptr (JsonParser) parser = json_parser_new ();
  g_autoptr (GError) error = NULL;
  g_assert_true (json_parser_load_from_file (parser, json, &error));
  JsonObject *root = json_node_get_object (json_parser_get_root (parser));
  JsonObject *inputs = json_object_get_object_member (root, "inputs");
  JsonArray *phases = json_object_get_array_member (inputs, "phases");
  g_assert_cmpuint (json_array_get_length (phases), ==, N);
  g_assert_cmpstr (json_array_get_string_element (phases, 0), ==, "img_1.png");
  g_assert_cmpstr (json_array_get_string_element (phases, 7), ==, "img_10.png");
  g_assert_cmpstr (json_object_get_string_member (inputs, "black"), ==, "black.png");
  /* The daemon's metadata keys (daemon/output/result_meta.h). */
  JsonObject *meta = json_object_get_object_member (root, "separation");
  g_assert_cmpint (json_object_get_int_member (meta, "phases"), ==, N);
  g_assert_true (json_object_get_boolean_member (meta, "dark_subtracted"));
  g_assert_cmpstr (json_object_get_string_member (meta, "estimator"), ==, "maxmin");
  JsonObject *params = json_object_get_object_member (root, "params");
  g_assert_cmpfloat (json_object_get_double_member (params, "duty"), ==, 0.5);

  /* A second run in the same folder skips its own outputs and gives the same result. */
  g_assert_cmpint (separate_run ("--quiet", dir, NULL), ==, 0);
  check_outputs (dir, 0.5, 0.0);
  test_remove_tree (dir);
}

static void
test_duty_black_level_out_extrema (void)
{
  g_autofree char *dir = g_dir_make_tmp ("ds-sep-XXXXXX", NULL);
  g_autofree char *out = g_build_filename (dir, "results", "run1", NULL);
  make_folder (dir, 0.25, 0.1, FALSE);
  g_assert_cmpint (separate_run ("-q", "--duty", "0.25", "--black-level", "0.1", "--extrema", "--out", out, dir, NULL),
                   ==, 0);
  check_outputs (out, 0.25, 0.1);
  /* max = Ld + Lg (a + b (1 - a)), min = b Ld + Lg (a + b (1 - a)). */
  g_autoptr (DsImage) mx = separate_read_out (out, "max.tiff");
  g_autoptr (DsImage) mn = separate_read_out (out, "min.tiff");
  g_autoptr (DsImage) mean = separate_read_out (out, "mean.tiff");
  for (guint y = 0; y < H; y++)
    for (guint x = 0; x < W; x++) {
      double ld = ld_at (x, y), lg = lg_at (x, y), c = 0.25 + 0.1 * 0.75;
      g_assert_cmpfloat_with_epsilon (((float *) ds_image_row (mx, y))[x], ld + lg * c, 1e-3);
      g_assert_cmpfloat_with_epsilon (((float *) ds_image_row (mn, y))[x], 0.1 * ld + lg * c, 1e-3);
      g_assert_nonnull (mean);
    }
  /* Nothing was written into the input folder. */
  g_autofree char *stray = g_build_filename (dir, "direct.png", NULL);
  g_assert_false (g_file_test (stray, G_FILE_TEST_EXISTS));
  test_remove_tree (dir);
}

static void
test_float_input (void)
{
  /* Float32 TIFF phases: the "like input" outputs are float TIFFs too, unclamped. */
  g_autofree char *dir = g_dir_make_tmp ("ds-sep-XXXXXX", NULL);
  make_folder_typed (dir, 0.5, 0.0, FALSE, DS_SAMPLE_F32);
  g_assert_cmpint (separate_run ("-q", "--no-preview", dir, NULL), ==, 0);
  g_autoptr (DsImage) direct = separate_read_out (dir, "direct.tiff");
  g_autoptr (DsImage) global = separate_read_out (dir, "global.tiff");
  g_assert_cmpint (direct->type, ==, DS_SAMPLE_F32);
  for (guint y = 0; y < H; y++)
    for (guint x = 0; x < W; x++) {
      g_assert_cmpfloat_with_epsilon (((float *) ds_image_row (direct, y))[x], ld_at (x, y), 1e-2);
      g_assert_cmpfloat_with_epsilon (((float *) ds_image_row (global, y))[x], lg_at (x, y), 1e-2);
    }
  g_autofree char *preview = g_build_filename (dir, "transmissive-preview.png", NULL);
  g_assert_false (g_file_test (preview, G_FILE_TEST_EXISTS));
  test_remove_tree (dir);
}

static void
test_errors (void)
{
  g_autofree char *dir = g_dir_make_tmp ("ds-sep-XXXXXX", NULL);
  /* Empty folder: the operation fails (1), nothing written. */
  g_assert_cmpint (separate_run ("-q", dir, NULL), ==, 1);
  g_autofree char *json = g_build_filename (dir, "separation.json", NULL);
  g_assert_false (g_file_test (json, G_FILE_TEST_EXISTS));
  /* Usage errors (2). */
  g_assert_cmpint (separate_run ("-q", NULL), ==, 2);
  g_assert_cmpint (separate_run ("-q", "--no-such-option", dir, NULL), ==, 2);
  g_assert_cmpint (separate_run ("-q", "--duty", "half", dir, NULL), ==, 2);
  make_folder (dir, 0.5, 0.0, FALSE);
  g_assert_cmpint (separate_run ("-q", "--estimator", "magic", dir, NULL), ==, 2);
  g_assert_cmpint (separate_run ("-q", "--duty", "1.5", dir, NULL), ==, 2);
  g_assert_cmpint (separate_run ("-q", "--black-level", "0.999", dir, NULL), ==, 2);
  g_assert_false (g_file_test (json, G_FILE_TEST_EXISTS));
  test_remove_tree (dir);
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  g_test_add_func ("/ctl-separate/defaults-black", test_defaults_with_black);
  g_test_add_func ("/ctl-separate/duty-black-out-extrema", test_duty_black_level_out_extrema);
  g_test_add_func ("/ctl-separate/float-input", test_float_input);
  g_test_add_func ("/ctl-separate/errors", test_errors);
  return g_test_run ();
}
