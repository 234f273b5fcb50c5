/* The spool (daemon/service/spool.c) on its own: recording never waits for the disk (a queue of
 * max_pending results, the rest counted as dropped), what was recorded is whole, the byte cap
 * removes the oldest sets first, a continuous run goes into one HDF5 file, and start-up removes
 * the files of a set whose sidecar never came while keeping a crashed run's .partial. */
#include <glib.h>
#include <glib/gstdio.h>
#include <string.h>

#include "daemon/output/result_files.h"
#include "daemon/service/spool.h"
#include "tests/common/test_tree.h"

static DsResult *
make_result (guint64 set_id, guint w, guint h)
{
  DsSeparation *sep = g_new0 (DsSeparation, 1);
  sep->transmissive = ds_image_new (DS_SAMPLE_F32, w, h, NULL);
  sep->scattered = ds_image_new (DS_SAMPLE_F32, w, h, NULL);
  sep->mask = ds_image_new (DS_SAMPLE_U8, w, h, NULL);
  for (guint y = 0; y < h; y++)
    for (guint x = 0; x < w; x++) {
      ((float *) ds_image_row (sep->transmissive, y))[x] = (float) (x + y + set_id);
      ((float *) ds_image_row (sep->scattered, y))[x] = (float) (x * 2 + set_id);
    }
  sep->meta.n_phases = 4;
  sep->meta.frames_per_phase = 1;
  DsCaptureSettings s = { .phases = 4, .averages = 1 };
  DsFrameCounters c = { .acquired = 4, .folded = 4 };
  gint64 now = g_get_monotonic_time ();
  return ds_result_new (set_id, sep, NULL, &s, &c, now - 1000, now - 100, now);
}

static guint
count (const char *dir, const char *prefix, const char *suffix)
{
  g_autoptr (GDir) d = g_dir_open (dir, 0, NULL);
  guint n = 0;
  const char *name;
  while (d && (name = g_dir_read_name (d)))
    n += g_str_has_prefix (name, prefix) && g_str_has_suffix (name, suffix);
  return n;
}

/* Twelve large results recorded back to back while the writer works on the first: recording
 * returns at once, at most max_pending wait, the rest are dropped and counted; every set that was
 * written is whole (sidecar and planes). */
static void
test_never_waits_for_the_disk (void)
{
  g_autofree char *dir = g_dir_make_tmp ("ds-spool-XXXXXX", NULL);
  g_autoptr (GError) error = NULL;
  DsSpool *spool = ds_spool_new (dir, G_MAXUINT64, DS_FILES_TIFF | DS_FILES_HDF5 | DS_FILES_PNG16 | DS_FILES_PREVIEW,
                                 2, &error);
  g_assert_no_error (error);
  guint accepted = 0;
  for (guint i = 1; i <= 12; i++) {
    g_autoptr (DsResult) r = make_result (i, 2048, 2048);
    accepted += ds_spool_record (spool, r, FALSE);
  }
  ds_spool_flush (spool);
  DsSpoolStats st;
  ds_spool_get_stats (spool, &st);
  g_test_message ("accepted %u, written %" G_GUINT64_FORMAT ", dropped %" G_GUINT64_FORMAT, accepted,
                  st.sets_written, st.dropped);
  /* The writer could not have written 12 sets of 2048 x 2048 in the microseconds the loop took. */
  g_assert_cmpuint (accepted, <, 12);
  g_assert_cmpuint (st.dropped, ==, 12 - accepted);
  g_assert_cmpuint (st.sets_written, ==, accepted);
  g_assert_cmpuint (st.pending, ==, 0);
  g_assert_cmpuint (count (dir, "set-", ".json"), ==, accepted);
  g_assert_cmpuint (count (dir, "set-", "-transmissive.tiff"), ==, accepted);
  g_assert_cmpuint (count (dir, "set-", ".h5"), ==, accepted);
  g_assert_cmpuint (count (dir, ".", ""), ==, 0);
  ds_spool_free (spool);
  test_remove_tree (dir);
}

/* Over the byte cap the oldest sets go first, whole; the newest always stays. */
static void
test_cap_removes_oldest (void)
{
  g_autofree char *dir = g_dir_make_tmp ("ds-spool-XXXXXX", NULL);
  g_autoptr (GError) error = NULL;
  /* One set of 64 x 64 in TIFF is about 35 KB: a 100 KB cap holds two. */
  DsSpool *spool = ds_spool_new (dir, 100 * 1024, DS_FILES_TIFF, 8, &error);
  g_assert_no_error (error);
  for (guint i = 1; i <= 6; i++) {
    g_autoptr (DsResult) r = make_result (i, 64, 64);
    g_assert_true (ds_spool_record (spool, r, FALSE));
    ds_spool_flush (spool);
  }
  DsSpoolStats st;
  ds_spool_get_stats (spool, &st);
  guint kept = count (dir, "set-", ".json");
  g_assert_cmpuint (kept, >=, 1);
  g_assert_cmpuint (kept, <, 6);
  g_assert_cmpuint (st.sets_removed, ==, 6 - kept);
  g_assert_cmpuint (st.bytes, <=, 100 * 1024);
  /* The ones kept are the newest. */
  g_assert_cmpuint (count (dir, "set-", "-000006.json"), ==, 1);
  g_assert_cmpuint (count (dir, "set-", "-000001.json"), ==, 0);
  /* Nothing of a removed set is left. */
  g_assert_cmpuint (count (dir, "set-", ""), ==, 4 * kept);
  ds_spool_free (spool);
  test_remove_tree (dir);
}

/* A continuous run goes into one growing HDF5 file, closed (renamed from .partial) when the run
 * ends; a result outside a run gets a file of its own. */
static void
test_run_file (void)
{
  g_autofree char *dir = g_dir_make_tmp ("ds-spool-XXXXXX", NULL);
  g_autoptr (GError) error = NULL;
  DsSpool *spool = ds_spool_new (dir, G_MAXUINT64, DS_FILES_HDF5_RUN, 8, &error);
  g_assert_no_error (error);
  for (guint i = 1; i <= 3; i++) {
    g_autoptr (DsResult) r = make_result (i, 32, 16);
    g_assert_true (ds_spool_record (spool, r, TRUE));
  }
  ds_spool_flush (spool);
  DsSpoolStats st;
  ds_spool_get_stats (spool, &st);
  g_assert_true (st.run_open);
  g_assert_cmpuint (count (dir, "run-", ".h5.partial"), ==, 1);
  ds_spool_end_run (spool);
  g_autoptr (DsResult) single = make_result (4, 32, 16);
  g_assert_true (ds_spool_record (spool, single, FALSE));
  ds_spool_flush (spool);
  ds_spool_get_stats (spool, &st);
  g_assert_false (st.run_open);
  g_assert_cmpuint (st.sets_written, ==, 4);
  g_assert_cmpuint (count (dir, "run-", ".h5"), ==, 1);
  g_assert_cmpuint (count (dir, "run-", ".partial"), ==, 0);
  g_assert_cmpuint (count (dir, "set-", "-000004.h5"), ==, 1);
  g_assert_cmpuint (count (dir, "set-", "-000004.json"), ==, 1);
  ds_spool_free (spool);
  test_remove_tree (dir);
}

/* At start-up: the files of a set without its sidecar (an interrupted write) and temporaries go,
 * complete sets and a crashed run's .partial stay and count. */
static void
test_start_up_stock (void)
{
  g_autofree char *dir = g_dir_make_tmp ("ds-spool-XXXXXX", NULL);
  const char *keep[] = { "set-20260101T000000Z-000001.json", "set-20260101T000000Z-000001-transmissive.tiff",
                         "run-20260101T000001Z-000002.h5.partial" };
  const char *gone[] = { "set-20260101T000002Z-000003-transmissive.tiff", "set-20260101T000002Z-000003.h5",
                         ".set-20260101T000002Z-000003.tmp-1-2.json" };
  for (guint i = 0; i < G_N_ELEMENTS (keep); i++) {
    g_autofree char *p = g_build_filename (dir, keep[i], NULL);
    g_assert_true (g_file_set_contents (p, "0123456789", 10, NULL));
  }
  for (guint i = 0; i < G_N_ELEMENTS (gone); i++) {
    g_autofree char *p = g_build_filename (dir, gone[i], NULL);
    g_assert_true (g_file_set_contents (p, "x", 1, NULL));
  }
  g_autofree char *phases = g_build_filename (dir, "set-20260101T000002Z-000003-phases", NULL);
  g_assert_cmpint (g_mkdir (phases, 0755), ==, 0);
  g_autoptr (GError) error = NULL;
  DsSpool *spool = ds_spool_new (dir, G_MAXUINT64, DS_FILES_TIFF, 8, &error);
  g_assert_no_error (error);
  for (guint i = 0; i < G_N_ELEMENTS (keep); i++) {
    g_autofree char *p = g_build_filename (dir, keep[i], NULL);
    g_assert_true (g_file_test (p, G_FILE_TEST_EXISTS));
  }
  for (guint i = 0; i < G_N_ELEMENTS (gone); i++) {
    g_autofree char *p = g_build_filename (dir, gone[i], NULL);
    g_assert_false (g_file_test (p, G_FILE_TEST_EXISTS));
  }
  g_assert_false (g_file_test (phases, G_FILE_TEST_EXISTS));
  DsSpoolStats st;
  ds_spool_get_stats (spool, &st);
  g_assert_cmpuint (st.bytes, ==, 30);
  ds_spool_free (spool);
  test_remove_tree (dir);
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  g_test_add_func ("/spool/never-waits-for-the-disk", test_never_waits_for_the_disk);
  g_test_add_func ("/spool/cap-removes-oldest", test_cap_removes_oldest);
  g_test_add_func ("/spool/run-file", test_run_file);
  g_test_add_func ("/spool/start-up-stock", test_start_up_stock);
  return g_test_run ();
}
