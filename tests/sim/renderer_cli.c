/* descatter-sim render/describe: the folder it writes is the layout the phase-folder loader
 * (and so `descatterctl separate`) reads; black.png exactly when the scene has ambient light. */
#include <glib/gstdio.h>
#include <string.h>

#include "proc/phase_folder.h"

static char *
run (const char *const *args, int *status)
{
  g_autoptr (GError) error = NULL;
  char *out = NULL;
  g_autofree char *err = NULL;
  g_assert_true (g_spawn_sync (NULL, (char **) args, NULL, G_SPAWN_DEFAULT, NULL, NULL, &out, &err, status, &error));
  g_assert_no_error (error);
  if (*status != 0)
    g_test_message ("stderr: %s", err);
  return out;
}

static void
check_render (const char *scene, gboolean expect_black)
{
  g_autoptr (GError) error = NULL;
  g_autofree char *dir = g_dir_make_tmp ("ds-sim-cli-XXXXXX", &error);
  g_assert_no_error (error);
  g_autofree char *path = g_strdup_printf ("%s/%s.scene", DS_SCENES_DIR, scene);
  const char *args[] = { DS_SIM_BIN, "render", path, "--phases", "4", "--out", dir, "--seed", "2", NULL };
  int status = -1;
  g_autofree char *out = run (args, &status);
  g_assert_true (g_spawn_check_wait_status (status, NULL));
  g_autoptr (DsPhaseFolder) f = ds_phase_folder_open (dir, &error);
  g_assert_no_error (error);
  g_assert_cmpuint (f->phase_files->len, ==, 4);
  for (guint k = 0; k < 4; k++) {
    g_autofree char *name = g_strdup_printf ("phase-%02u.png", k);
    g_assert_cmpstr (g_ptr_array_index (f->phase_files, k), ==, name);
    g_autofree char *p = g_build_filename (dir, name, NULL);
    g_autoptr (DsImage) im = ds_image_read (p, &error);
    g_assert_no_error (error);
    g_assert_cmpint (im->type, ==, DS_SAMPLE_U16);
    for (guint y = 0; y < im->height; y++)
      for (guint x = 0; x < im->width; x++)
        g_assert_cmpuint (((guint16 *) ds_image_row (im, y))[x], <=, 4095); /* 12-bit scenes */
  }
  if (expect_black)
    g_assert_cmpstr (f->black_file, ==, "black.png");
  else
    g_assert_null (f->black_file);
  const char *truth[] = { "truth_transmissive.tiff", "truth_scattered.tiff" };
  for (guint i = 0; i < 2; i++) {
    g_autofree char *p = g_build_filename (dir, truth[i], NULL);
    g_autoptr (DsImage) im = ds_image_read (p, &error);
    g_assert_no_error (error);
    g_assert_cmpint (im->type, ==, DS_SAMPLE_F32);
    g_assert_cmpuint (im->width, ==, 256);
    g_assert_cmpuint (im->height, ==, 192);
  }
  /* Clean up: every file we expect, then the folder (fails if anything else was left). */
  const char *files[] = { "phase-00.png", "phase-01.png", "phase-02.png", "phase-03.png", "black.png",
                          "truth_transmissive.tiff", "truth_scattered.tiff" };
  for (guint i = 0; i < G_N_ELEMENTS (files); i++) {
    g_autofree char *p = g_build_filename (dir, files[i], NULL);
    g_unlink (p);
  }
  g_assert_cmpint (g_rmdir (dir), ==, 0);
}

static void
test_render_milk (void)
{
  check_render ("milk-disc", TRUE);
}

static void
test_render_clear (void)
{
  check_render ("clear-grid", FALSE);
}

static void
test_describe (void)
{
  g_autofree char *path = g_strdup_printf ("%s/clear-grid.scene", DS_SCENES_DIR);
  const char *args[] = { DS_SIM_BIN, "describe", path, NULL };
  int status = -1;
  g_autofree char *out = run (args, &status);
  g_assert_true (g_spawn_check_wait_status (status, NULL));
  g_assert_nonnull (strstr (out, "ballistic-attenuation"));
  g_assert_nonnull (strstr (out, "not built (not declared by the scene): scattering ambient"));
  const char *bad[] = { DS_SIM_BIN, "describe", "/nonexistent.scene", NULL };
  g_free (run (bad, &status));
  g_assert_false (g_spawn_check_wait_status (status, NULL));
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  g_test_add_func ("/sim/cli/render-milk", test_render_milk);
  g_test_add_func ("/sim/cli/render-clear", test_render_clear);
  g_test_add_func ("/sim/cli/describe", test_describe);
  return g_test_run ();
}
