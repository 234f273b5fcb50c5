/* daemon/output: result files written and read back. TIFF through OpenCV's reader (which
 * shares nothing with the libtiff writer), phase folders through proc's loader and a second
 * separation, the 16-bit PNG scale against its definition; the Python half
 * (test_output_files.py) reads the same files with tifffile and h5py. */
#include <glib.h>
#include <glib/gstdio.h>
#include <math.h>
#include <string.h>

#include "daemon/ctl/ctl_folder.h"
#include "daemon/output/hdf5_run.h"
#include "daemon/output/hdf5_set.h"
#include "daemon/output/output_error.h"
#include "daemon/output/phase_folder_write.h"
#include "daemon/output/result_files.h"
#include "daemon/output/result_meta.h"
#include "daemon/output/tiff_file.h"
#include "proc/phase_folder.h"
#include "proc/separation.h"
#include "sample_result.h"
#include "tests/common/test_tree.h"

static void
assert_images_equal (const DsImage *a, const DsImage *b)
{
  g_assert_true (ds_image_same_shape (a, b));
  gsize row = a->width * ds_sample_size (a->type);
  for (guint y = 0; y < a->height; y++)
    g_assert_cmpmem (ds_image_row (a, y), row, ds_image_row (b, y), row);
}

static guint
count_hidden (const char *dir)
{
  g_autoptr (GDir) d = g_dir_open (dir, 0, NULL);
  guint n = 0;
  const char *name;
  while (d && (name = g_dir_read_name (d)))
    n += name[0] == '.';
  return n;
}

/* A float TIFF written through libtiff reads back bit for bit through OpenCV, with the
 * description intact; the odd width exercises padded rows. */
static void
test_tiff_roundtrip (void)
{
  g_autofree char *dir = g_dir_make_tmp ("ds-output-XXXXXX", NULL);
  g_autoptr (SampleResult) s = sample_result_new (37, 5, 3, FALSE, FALSE);
  g_autofree char *path = g_build_filename (dir, "t.tiff", NULL);
  const char *desc = "{\"set_id\": 4, \"note\": \"µ\"}";
  DsTiffTags tags = { .description = desc };
  g_autoptr (GError) error = NULL;
  g_assert_true (ds_tiff_write (s->planes.transmissive, path, &tags, &error));
  g_assert_no_error (error);
  g_autoptr (DsImage) back = ds_image_read (path, &error);
  g_assert_no_error (error);
  assert_images_equal (s->planes.transmissive, back);
  g_autofree char *text = ds_tiff_read_description (path, &error);
  g_assert_no_error (error);
  g_assert_cmpstr (text, ==, desc);
  g_assert_cmpuint (count_hidden (dir), ==, 0);
  /* A folder that does not exist: a clear error naming the file, nothing left behind. */
  g_autofree char *bad = g_build_filename (dir, "missing", "t.tiff", NULL);
  g_assert_false (ds_tiff_write (s->planes.transmissive, bad, &tags, &error));
  g_assert_error (error, DS_OUTPUT_ERROR, DS_OUTPUT_ERROR_IO);
  g_assert_nonnull (strstr (error->message, bad));
  test_remove_tree (dir);
}

/* The scale is the largest power of two that keeps the maximum in 16 bits, so the maximum
 * lands in the upper half of the range and every value comes back within 0.5 / scale. */
static void
test_png16_scale (void)
{
  const double tops[] = { 4000.0, 65535.0, 0.3, 200000.0, 40000.5 };
  for (guint c = 0; c < G_N_ELEMENTS (tops); c++) {
    g_autoptr (DsImage) img = ds_image_new (DS_SAMPLE_F32, 64, 3, NULL);
    for (guint y = 0; y < 3; y++)
      for (guint x = 0; x < 64; x++)
        ((float *) ds_image_row (img, y))[x] = (float) (tops[c] * (x + 1) / 64.0);
    ((float *) ds_image_row (img, 2))[0] = -5.0f;
    ((float *) ds_image_row (img, 2))[1] = NAN;
    double scale = 0;
    g_autoptr (DsImage) out = ds_png16_scaled (img, &scale, NULL);
    g_assert_nonnull (out);
    int e;
    g_assert_cmpfloat (frexp (scale, &e), ==, 0.5); /* a power of two */
    double top = (float) tops[c];
    g_assert_cmpfloat (top * scale, <=, 65535.5);
    if (scale < 65536.0) /* 2^16 is the largest scale: tiny planes stay below half */
      g_assert_cmpfloat (top * scale * 2, >, 65535.5);
    for (guint y = 0; y < 3; y++)
      for (guint x = 0; x < 64; x++) {
        double v = ((float *) ds_image_row (img, y))[x];
        double got = ((guint16 *) ds_image_row (out, y))[x];
        if (!(v > 0))
          g_assert_cmpfloat (got, ==, 0);
        else
          g_assert_cmpfloat (fabs (got / scale - v), <=, 0.5 / scale + 1e-9);
      }
  }
  g_autoptr (DsImage) zero = ds_image_new (DS_SAMPLE_F32, 4, 4, NULL);
  double scale = 0;
  g_autoptr (DsImage) out = ds_png16_scaled (zero, &scale, NULL);
  g_assert_cmpfloat (scale, ==, 1.0);
}

static JsonNode *
read_json (const char *path)
{
  g_autofree char *text = NULL;
  g_assert_true (g_file_get_contents (path, &text, NULL, NULL));
  JsonNode *n = json_from_string (text, NULL);
  g_assert_nonnull (n);
  return n;
}

/* Every kind at once: the files of the naming scheme exist, the sidecar lists each with its
 * kind (and the PNG scale), no temporary is left. */
static void
test_write_all_kinds (void)
{
  g_autofree char *dir = g_dir_make_tmp ("ds-output-XXXXXX", NULL);
  g_autoptr (SampleResult) s = sample_result_new (16, 8, 7, TRUE, TRUE);
  g_autofree char *stem = ds_result_stem (s->planes.meta);
  g_assert_cmpstr (stem, ==, "set-20260102T030407Z-000008");
  guint kinds = 0;
  g_assert_true (ds_file_kinds_parse ("tiff, png16,preview,hdf5", &kinds, NULL));
  kinds |= DS_FILES_PHASES;
  g_autoptr (GPtrArray) written = g_ptr_array_new_with_free_func (g_free);
  g_autoptr (GError) error = NULL;
  g_assert_true (ds_result_write_files (&s->planes, dir, stem, kinds, written, &error));
  g_assert_no_error (error);
  const char *expected[] = { "-transmissive.tiff", "-scattered.tiff", "-mask.png", "-mean.tiff", "-direct.png",
                             "-global.png", "-transmissive-preview.png", "-scattered-preview.png", ".h5", "-phases",
                             ".json" };
  g_assert_cmpuint (written->len, ==, G_N_ELEMENTS (expected));
  /* The caller's metadata is untouched (it may be shared with other writers and threads). */
  g_assert_false (json_object_has_member (json_node_get_object (s->planes.meta), "files"));
  g_assert_false (json_object_has_member (json_node_get_object (s->planes.meta), "plane"));
  g_autofree char *jpath = g_strdup_printf ("%s/%s.json", dir, stem);
  g_autoptr (JsonNode) side = read_json (jpath);
  for (guint i = 0; i < G_N_ELEMENTS (expected); i++) {
    g_autofree char *name = g_strconcat (stem, expected[i], NULL);
    g_autofree char *p = g_build_filename (dir, name, NULL);
    g_assert_true (g_file_test (p, G_FILE_TEST_EXISTS));
    if (i + 1 < G_N_ELEMENTS (expected)) {
      g_autofree char *key = g_strconcat ("files.", name, NULL);
      /* Names contain dots: look the member up directly. */
      JsonObject *files = json_object_get_object_member (json_node_get_object (side), "files");
      g_assert_true (json_object_has_member (files, name));
    }
  }
  JsonObject *files = json_object_get_object_member (json_node_get_object (side), "files");
  g_autofree char *dname = g_strconcat (stem, "-direct.png", NULL);
  JsonObject *direct = json_object_get_object_member (files, dname);
  /* transmissive peaks at 1000 + 150 + 7 + 7/4 = 1158.75: scale 32 puts it at 37080. */
  g_assert_cmpfloat (json_object_get_double_member (direct, "scale"), ==, 32.0);
  g_autofree char *dpath = g_build_filename (dir, dname, NULL);
  g_autoptr (DsImage) dimg = ds_image_read (dpath, NULL);
  g_assert_cmpuint (((guint16 *) ds_image_row (dimg, 7))[15], ==, (guint) lround (1158.75 * 32));
  g_assert_cmpuint (count_hidden (dir), ==, 0);
  /* Unknown kinds are named. */
  g_assert_false (ds_file_kinds_parse ("tiff,jpeg", &kinds, &error));
  g_assert_nonnull (strstr (error->message, "jpeg"));
  test_remove_tree (dir);
}

/* A failure late in the set (the phase folder's name is taken) removes what was written and
 * leaves no sidecar: nothing of the set looks whole. */
static void
test_failure_leaves_nothing (void)
{
  g_autofree char *dir = g_dir_make_tmp ("ds-output-XXXXXX", NULL);
  g_autoptr (SampleResult) s = sample_result_new (16, 8, 1, TRUE, FALSE);
  g_autofree char *stem = ds_result_stem (s->planes.meta);
  g_autofree char *taken = g_strdup_printf ("%s/%s-phases", dir, stem);
  g_assert_cmpint (g_mkdir (taken, 0755), ==, 0);
  g_autoptr (GError) error = NULL;
  g_assert_false (ds_result_write_files (&s->planes, dir, stem, DS_FILES_TIFF | DS_FILES_HDF5 | DS_FILES_PHASES,
                                         NULL, &error));
  g_assert_nonnull (strstr (error->message, "already exists"));
  g_autoptr (GDir) d = g_dir_open (dir, 0, NULL);
  const char *name;
  guint n = 0;
  while ((name = g_dir_read_name (d)))
    n++;
  g_assert_cmpuint (n, ==, 1); /* only the folder that was there before */
  test_remove_tree (dir);
}

/* The phase folder reads back through proc's loader (the one `descatterctl separate` uses
 * today): same phases in order, the black frame, and a separation of the files equals, bit for
 * bit, one of the frames in memory. */
static void
test_phase_folder_today_loader (void)
{
  g_autofree char *dir = g_dir_make_tmp ("ds-output-XXXXXX", NULL);
  g_autoptr (SampleResult) s = sample_result_new (21, 6, 2, TRUE, FALSE);
  g_autofree char *folder = g_build_filename (dir, "set-phases", NULL);
  g_autoptr (GError) error = NULL;
  g_assert_true (ds_phase_folder_write (s->raw, s->planes.meta, folder, &error));
  g_assert_no_error (error);
  g_autoptr (DsPhaseFolder) pf = ds_phase_folder_open (folder, ds_folder_read_sidecar, &error);
  g_assert_no_error (error);
  g_assert_cmpuint (ds_phase_folder_n_phases (pf), ==, SAMPLE_PHASES);
  g_assert_cmpstr (pf->black_file, ==, "black.png");

  DsSeparationParams p;
  ds_separation_params_init (&p, SAMPLE_PHASES);
  p.saturation_level = 4095;
  g_autoptr (DsPhaseSet) mem = ds_phase_set_new (&p, 21, 6, NULL);
  g_autoptr (DsPhaseSet) disk = ds_phase_set_new (&p, 21, 6, NULL);
  g_assert_true (ds_phase_set_set_dark (mem, s->raw->black, NULL));
  g_autoptr (DsImage) black = ds_phase_folder_read_black (pf, &error);
  g_assert_no_error (error);
  g_assert_true (ds_phase_set_set_dark (disk, black, NULL));
  for (guint k = 0; k < SAMPLE_PHASES; k++) {
    const DsRawFrame *f = s->raw->frames->pdata[k];
    g_assert_true (ds_phase_set_accumulate (mem, f->phase, f->image, NULL));
    g_autoptr (DsImage) img = ds_phase_folder_read (pf, k, &error);
    g_assert_no_error (error);
    assert_images_equal (f->image, img);
    g_assert_true (ds_phase_set_accumulate (disk, k, img, NULL));
  }
  g_autoptr (DsSeparation) a = ds_phase_set_finalize (mem, NULL);
  g_autoptr (DsSeparation) b = ds_phase_set_finalize (disk, NULL);
  assert_images_equal (a->transmissive, b->transmissive);
  assert_images_equal (a->scattered, b->scattered);
  assert_images_equal (a->mask, b->mask);

  /* The sidecar says what the images cannot. */
  g_autofree char *side_path = g_build_filename (folder, "frames.json", NULL);
  g_autoptr (JsonNode) side = read_json (side_path);
  g_assert_cmpstr (ds_json_path_string (side, "format", NULL), ==, "descatter-phase-folder");
  g_assert_cmpint (ds_json_path_int (side, "bit_depth", 0), ==, 12);
  g_assert_cmpfloat (ds_json_path_double (side, "saturation_dn", 0), ==, 4095);
  g_assert_cmpfloat (ds_json_path_double (side, "pattern.phase_offset_cycles", 0), ==, 0.25);
  g_assert_cmpstr (ds_json_path_string (side, "producer.camera.serial", NULL), ==, "S2");
  JsonArray *frames = json_object_get_array_member (json_node_get_object (side), "frames");
  g_assert_cmpuint (json_array_get_length (frames), ==, SAMPLE_PHASES);
  JsonObject *f2 = json_array_get_object_element (frames, 2);
  g_assert_cmpstr (json_object_get_string_member (f2, "file"), ==, "phase-02-0.png");
  g_assert_cmpint (json_object_get_int_member (f2, "frame_id"), ==, 2002);
  /* Writing it again does not overwrite. */
  g_assert_false (ds_phase_folder_write (s->raw, s->planes.meta, folder, &error));
  g_assert_error (error, DS_OUTPUT_ERROR, DS_OUTPUT_ERROR_IO);
  g_assert_cmpuint (count_hidden (dir), ==, 0);
  test_remove_tree (dir);
}

/* A run closed normally is renamed to its final name; a result of another size is refused. */
static void
test_hdf5_run_close_and_refuse (void)
{
  g_autofree char *dir = g_dir_make_tmp ("ds-output-XXXXXX", NULL);
  g_autofree char *path = g_build_filename (dir, "run.h5", NULL);
  g_autoptr (SampleResult) a = sample_result_new (12, 4, 0, FALSE, FALSE);
  g_autoptr (SampleResult) b = sample_result_new (13, 4, 1, FALSE, FALSE);
  g_autoptr (GError) error = NULL;
  DsHdf5Run *run = ds_hdf5_run_open (path, &a->planes, &error);
  g_assert_no_error (error);
  g_assert_true (g_file_test (ds_hdf5_run_partial_path (run), G_FILE_TEST_EXISTS));
  g_assert_true (ds_hdf5_run_append (run, &a->planes, &error));
  g_assert_false (ds_hdf5_run_append (run, &b->planes, &error));
  g_assert_error (error, DS_OUTPUT_ERROR, DS_OUTPUT_ERROR_INVALID);
  g_clear_error (&error);
  g_assert_cmpuint (ds_hdf5_run_sets (run), ==, 1);
  g_autofree char *partial = g_strdup (ds_hdf5_run_partial_path (run));
  /* The library's own reason reaches the message. */
  g_autofree char *nowhere = g_build_filename (dir, "missing", "set.h5", NULL);
  g_assert_false (ds_hdf5_write_set (&a->planes, nowhere, &error));
  g_assert_error (error, DS_OUTPUT_ERROR, DS_OUTPUT_ERROR_HDF5);
  g_assert_nonnull (strstr (error->message, nowhere));
  g_assert_null (strstr (error->message, "HDF5 error"));
  g_test_message ("%s", error->message);
  g_clear_error (&error);
  g_assert_true (ds_hdf5_run_close (run, &error));
  g_assert_no_error (error);
  g_assert_true (g_file_test (path, G_FILE_TEST_EXISTS));
  g_assert_false (g_file_test (partial, G_FILE_TEST_EXISTS));
  test_remove_tree (dir);
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  g_test_add_func ("/output/tiff-roundtrip", test_tiff_roundtrip);
  g_test_add_func ("/output/png16-scale", test_png16_scale);
  g_test_add_func ("/output/write-all-kinds", test_write_all_kinds);
  g_test_add_func ("/output/failure-leaves-nothing", test_failure_leaves_nothing);
  g_test_add_func ("/output/phase-folder-today-loader", test_phase_folder_today_loader);
  g_test_add_func ("/output/hdf5-run-close-and-refuse", test_hdf5_run_close_and_refuse);
  return g_test_run ();
}
