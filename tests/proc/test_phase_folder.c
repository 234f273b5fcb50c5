/* Phase folders in the ICCP 2013 scripts' layout: order, skipping, errors naming files. */
#include <glib.h>
#include <glib/gstdio.h>
#include <math.h>
#include <string.h>

#include "daemon/ctl/ctl_folder.h"
#include "proc/phase_folder.h"
#include "proc/proc_error.h"
#include "tests/common/test_tree.h"

static void
write_image (const char *dir, const char *name, DsSampleType type, guint w, guint h, guint value)
{
  g_autoptr (DsImage) img = ds_image_new (type, w, h, NULL);
  for (guint y = 0; y < h; y++)
    for (guint x = 0; x < w; x++) {
      if (type == DS_SAMPLE_U8)
        ((guint8 *) ds_image_row (img, y))[x] = (guint8) value;
      else
        ((guint16 *) ds_image_row (img, y))[x] = (guint16) value;
    }
  g_autofree char *path = g_build_filename (dir, name, NULL);
  g_autoptr (GError) error = NULL;
  g_assert_true (ds_image_write (img, path, &error));
  g_assert_no_error (error);
}

static void
test_natural_order (void)
{
  g_assert_cmpint (ds_natural_compare ("img2", "img10"), <, 0);
  g_assert_cmpint (ds_natural_compare ("img10", "img2"), >, 0);
  g_assert_cmpint (ds_natural_compare ("a", "B"), <, 0);
  g_assert_cmpint (ds_natural_compare ("p007", "p7"), !=, 0);
  g_assert_cmpint (ds_natural_compare ("p007", "p8"), <, 0);
  g_assert_cmpint (ds_natural_compare ("x", "x"), ==, 0);
  g_assert_cmpint (ds_natural_compare ("x1", "x"), >, 0);
}

static void
test_layout (void)
{
  g_autofree char *dir = g_dir_make_tmp ("ds-folder-XXXXXX", NULL);
  /* Phases named so that plain strcmp would order them wrongly (10 before 2). */
  for (guint k = 1; k <= 11; k++) {
    g_autofree char *name = g_strdup_printf ("Phase%u.png", k);
    write_image (dir, name, DS_SAMPLE_U16, 5, 3, 100 + k);
  }
  write_image (dir, "black.png", DS_SAMPLE_U16, 5, 3, 7);
  write_image (dir, "white.png", DS_SAMPLE_U16, 5, 3, 9000);
  const char *outputs[] = { "direct.png", "global.png", "max.png", "min.png", "mask.png",
                            "truth_direct.png", "Truth.png", "scattered-preview.png" };
  for (gsize i = 0; i < G_N_ELEMENTS (outputs); i++)
    write_image (dir, outputs[i], DS_SAMPLE_U8, 2, 2, 1); /* other sizes: must not matter */
  write_image (dir, "transmissive.tiff", DS_SAMPLE_U16, 2, 2, 1);
  g_autofree char *notes = g_build_filename (dir, "notes.txt", NULL);
  g_assert_true (g_file_set_contents (notes, "not an image", -1, NULL));
  g_autofree char *hidden = g_build_filename (dir, ".direct.tmp-1.png", NULL);
  g_assert_true (g_file_set_contents (hidden, "half-written", -1, NULL));

  g_autoptr (GError) error = NULL;
  g_autoptr (DsPhaseFolder) f = ds_phase_folder_open (dir, ds_folder_read_sidecar, &error);
  g_assert_no_error (error);
  g_assert_cmpuint (ds_phase_folder_n_phases (f), ==, 11);
  g_assert_cmpstr (f->black_file, ==, "black.png");
  g_assert_cmpstr (f->white_file, ==, "white.png");
  g_assert_cmpuint (f->skipped->len, ==, 9);
  for (guint k = 0; k < 11; k++) {
    g_autofree char *want = g_strdup_printf ("Phase%u.png", k + 1);
    g_assert_cmpstr (f->phase_files->pdata[k], ==, want);
    g_autoptr (DsImage) img = ds_phase_folder_read (f, k, &error);
    g_assert_no_error (error);
    g_assert_cmpuint (((guint16 *) ds_image_row (img, 2))[4], ==, 101 + k);
  }
  g_autoptr (DsImage) black = ds_phase_folder_read_black (f, &error);
  g_assert_no_error (error);
  g_assert_cmpuint (((guint16 *) ds_image_row (black, 0))[0], ==, 7);
  g_assert_null (ds_phase_folder_read (f, 11, &error));
  g_assert_error (error, DS_PROC_ERROR, DS_PROC_ERROR_INVALID_ARGUMENT);
  test_remove_tree (dir);
}

static void
expect_open_error (const char *dir, int code, const char *fragment)
{
  g_autoptr (GError) error = NULL;
  DsPhaseFolder *f = ds_phase_folder_open (dir, ds_folder_read_sidecar, &error);
  g_assert_null (f);
  g_assert_error (error, DS_PROC_ERROR, code);
  if (!strstr (error->message, fragment))
    g_error ("message \"%s\" lacks \"%s\"", error->message, fragment);
}

/* Reads every phase and returns the first error. */
static GError *
read_all (const char *dir)
{
  GError *error = NULL;
  g_autoptr (DsPhaseFolder) f = ds_phase_folder_open (dir, ds_folder_read_sidecar, &error);
  g_assert_no_error (error);
  for (guint k = 0; k < ds_phase_folder_n_phases (f); k++) {
    g_autoptr (DsImage) img = ds_phase_folder_read (f, k, &error);
    if (!img)
      return error;
  }
  if (f->black_file) {
    g_autoptr (DsImage) img = ds_phase_folder_read_black (f, &error);
    if (!img)
      return error;
  }
  return NULL;
}

static void
test_errors (void)
{
  g_autofree char *dir = g_dir_make_tmp ("ds-folder-XXXXXX", NULL);
  expect_open_error (dir, DS_PROC_ERROR_EMPTY, "no phase images");
  write_image (dir, "direct.png", DS_SAMPLE_U8, 4, 4, 1);
  write_image (dir, "black.png", DS_SAMPLE_U8, 4, 4, 1);
  expect_open_error (dir, DS_PROC_ERROR_EMPTY, "skipped 1 earlier outputs");
  write_image (dir, "p0.png", DS_SAMPLE_U8, 4, 4, 1);
  expect_open_error (dir, DS_PROC_ERROR_NOT_ENOUGH_PHASES, "p0.png");
  expect_open_error ("/nonexistent/ds-folder", DS_PROC_ERROR_IO, "/nonexistent/ds-folder");

  /* Mixed sizes: both files named. */
  write_image (dir, "p1.png", DS_SAMPLE_U8, 5, 4, 1);
  g_autoptr (GError) e1 = read_all (dir);
  g_assert_error (e1, DS_PROC_ERROR, DS_PROC_ERROR_SIZE_MISMATCH);
  g_assert_nonnull (strstr (e1->message, "p0.png"));
  g_assert_nonnull (strstr (e1->message, "p1.png"));

  /* Mixed bit depths (8 and 16 bits, same size). */
  write_image (dir, "p1.png", DS_SAMPLE_U16, 4, 4, 1);
  g_autoptr (GError) e2 = read_all (dir);
  g_assert_error (e2, DS_PROC_ERROR, DS_PROC_ERROR_SIZE_MISMATCH);
  g_assert_nonnull (strstr (e2->message, "p1.png"));
  g_assert_nonnull (strstr (e2->message, "16 bits"));

  /* A black frame that does not match the phases. */
  write_image (dir, "p1.png", DS_SAMPLE_U8, 4, 4, 1);
  write_image (dir, "black.png", DS_SAMPLE_U8, 3, 4, 1);
  g_autoptr (GError) e3 = read_all (dir);
  g_assert_error (e3, DS_PROC_ERROR, DS_PROC_ERROR_SIZE_MISMATCH);
  g_assert_nonnull (strstr (e3->message, "black.png"));
  write_image (dir, "black.png", DS_SAMPLE_U8, 4, 4, 1);

  /* An unreadable image: garbage with a .png name. */
  g_autofree char *bad = g_build_filename (dir, "p2.png", NULL);
  g_assert_true (g_file_set_contents (bad, "\x89PNG garbage", -1, NULL));
  g_autoptr (GError) e4 = read_all (dir);
  g_assert_nonnull (e4);
  g_assert_true (e4->domain == DS_PROC_ERROR);
  g_assert_nonnull (strstr (e4->message, "p2.png"));

  /* Two black frames. */
  g_remove (bad);
  write_image (dir, "BLACK.tif", DS_SAMPLE_U8, 4, 4, 1);
  expect_open_error (dir, DS_PROC_ERROR_INVALID_ARGUMENT, "two black frames");
  test_remove_tree (dir);
}

/* frames.json: its frames (several per phase, in its order) replace the names' guesses, images it
 * does not list are not phases, its black files are averaged as the daemon averages dark frames
 * (to the nearest DN), and its bit depth is given to the images. */
static void
test_sidecar (void)
{
  g_autofree char *dir = g_dir_make_tmp ("ds-folder-XXXXXX", NULL);
  write_image (dir, "a.png", DS_SAMPLE_U16, 4, 2, 100);
  write_image (dir, "b.png", DS_SAMPLE_U16, 4, 2, 200);
  write_image (dir, "c.png", DS_SAMPLE_U16, 4, 2, 300);
  write_image (dir, "unlisted.png", DS_SAMPLE_U16, 4, 2, 9);
  write_image (dir, "dark1.png", DS_SAMPLE_U16, 4, 2, 7);
  write_image (dir, "dark2.png", DS_SAMPLE_U16, 4, 2, 8);
  g_autofree char *json = g_build_filename (dir, "frames.json", NULL);
  g_assert_true (g_file_set_contents (json,
    "{\"format\": \"descatter-phase-folder\", \"version\": 1, \"width\": 4, \"height\": 2,"
    " \"bit_depth\": 10, \"n_phases\": 2, \"future_key\": [1, 2],"
    " \"frames\": [{\"file\": \"c.png\", \"phase\": 1, \"frame_id\": 17}, {\"file\": \"a.png\", \"phase\": 0},"
    " {\"file\": \"b.png\", \"phase\": 0}], \"black\": {\"files\": [\"dark1.png\", \"dark2.png\"]}}", -1, NULL));
  g_autoptr (GError) error = NULL;
  g_autoptr (DsPhaseFolder) f = ds_phase_folder_open (dir, ds_folder_read_sidecar, &error);
  g_assert_no_error (error);
  g_assert_true (f->sidecar.present);
  g_assert_cmpuint (ds_phase_folder_n_phases (f), ==, 2);
  g_assert_cmpuint (ds_phase_folder_n_frames (f), ==, 3);
  g_assert_cmpstr (ds_phase_folder_frame (f, 0)->file, ==, "c.png");
  g_assert_cmpuint (ds_phase_folder_frame (f, 0)->phase, ==, 1);
  g_assert_true (ds_phase_folder_frame (f, 0)->has_frame_id);
  g_assert_cmpuint (ds_phase_folder_frame (f, 0)->frame_id, ==, 17);
  g_assert_false (ds_phase_folder_frame (f, 1)->has_frame_id);
  g_assert_true (isnan (f->sidecar.saturation_dn));
  g_autoptr (DsImage) c = ds_phase_folder_read (f, 0, &error);
  g_assert_no_error (error);
  g_assert_cmpuint (c->bit_depth, ==, 10);
  g_assert_cmpuint (((guint16 *) ds_image_row (c, 1))[3], ==, 300);
  g_autoptr (DsImage) black = ds_phase_folder_read_black (f, &error);
  g_assert_no_error (error);
  g_assert_cmpuint (((guint16 *) ds_image_row (black, 0))[0], ==, 8); /* 7.5 to the nearest DN */
  g_assert_cmpuint (black->bit_depth, ==, 10);
  test_remove_tree (dir);
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  g_test_add_func ("/phase-folder/natural-order", test_natural_order);
  g_test_add_func ("/phase-folder/layout", test_layout);
  g_test_add_func ("/phase-folder/errors", test_errors);
  g_test_add_func ("/phase-folder/sidecar", test_sidecar);
  return g_test_run ();
}
