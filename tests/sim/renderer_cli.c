/* descatter-sim render/describe: the folder it writes is the layout the phase-folder loader
 * (and so `descatterctl separate`) reads; black.png exactly when the scene has ambient light;
 * frames.json as docs/phase-folder.md specifies, its saturation level the one the frames clip at. */
#include <glib/gstdio.h>
#include <json-glib/json-glib.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "daemon/ctl/ctl_folder.h"
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
check_render (const char *scene, gboolean expect_black, double expect_exposure, double expect_period)
{
  g_autoptr (GError) error = NULL;
  g_autofree char *dir = g_dir_make_tmp ("ds-sim-cli-XXXXXX", &error);
  g_assert_no_error (error);
  g_autofree char *path = g_strdup_printf ("%s/%s.scene", DS_SCENES_DIR, scene);
  const char *args[] = { DS_SIM_BIN, "render", path, "--phases", "4", "--out", dir, "--seed", "2", NULL };
  int status = -1;
  g_autofree char *out = run (args, &status);
  g_assert_true (g_spawn_check_wait_status (status, NULL));
  g_autoptr (DsPhaseFolder) f = ds_phase_folder_open (dir, ds_folder_read_sidecar, &error);
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
  /* The sidecar: every key docs/phase-folder.md names, with the scene's values (12-bit scenes,
   * K 0.25 DN/e- x 20000 e- = 5000 DN above the ADC's 4095: the ADC clips first). */
  g_autoptr (JsonParser) parser = json_parser_new ();
  g_autofree char *sidecar = g_build_filename (dir, "frames.json", NULL);
  g_assert_true (json_parser_load_from_file (parser, sidecar, &error));
  g_assert_no_error (error);
  JsonObject *o = json_node_get_object (json_parser_get_root (parser));
  g_assert_cmpstr (json_object_get_string_member (o, "format"), ==, "descatter-phase-folder");
  g_assert_cmpint (json_object_get_int_member (o, "version"), ==, 1);
  JsonObject *prod = json_object_get_object_member (o, "producer");
  g_assert_cmpstr (json_object_get_string_member (prod, "program"), ==, "descatter-sim");
  g_assert_cmpstr (json_object_get_string_member (prod, "backend"), ==, "descatter-sim");
  g_assert_nonnull (json_object_get_string_member (prod, "version"));
  g_assert_nonnull (json_object_get_string_member (prod, "git"));
  g_autoptr (GDateTime) when = g_date_time_new_from_iso8601 (json_object_get_string_member (o, "time_utc"), NULL);
  g_assert_nonnull (when);
  g_assert_cmpint (json_object_get_int_member (o, "width"), ==, 256);
  g_assert_cmpint (json_object_get_int_member (o, "height"), ==, 192);
  g_assert_cmpint (json_object_get_int_member (o, "bit_depth"), ==, 12);
  g_assert_cmpint (json_object_get_int_member (o, "saturation_dn"), ==, 4095);
  g_assert_cmpstr (json_object_get_string_member (o, "pixel_format"), ==, "Mono12");
  g_assert_cmpfloat (json_object_get_double_member (o, "exposure_us"), ==, expect_exposure);
  g_assert_cmpfloat (json_object_get_double_member (o, "gain_db"), ==, 0);
  JsonObject *pat = json_object_get_object_member (o, "pattern");
  g_assert_cmpstr (json_object_get_string_member (pat, "kind"), ==, "square");
  g_assert_cmpfloat (json_object_get_double_member (pat, "period_px"), ==, expect_period);
  g_assert_cmpfloat (json_object_get_double_member (pat, "duty"), ==, 0.5);
  g_assert_cmpfloat (json_object_get_double_member (pat, "black_level"), ==, 0);
  g_assert_cmpfloat (json_object_get_double_member (pat, "phase_offset_cycles"), ==, 0);
  g_assert_cmpint (json_object_get_int_member (o, "n_phases"), ==, 4);
  JsonArray *frames = json_object_get_array_member (o, "frames");
  g_assert_cmpuint (json_array_get_length (frames), ==, 4);
  for (guint k = 0; k < 4; k++) {
    JsonObject *fr = json_array_get_object_element (frames, k);
    g_autofree char *name = g_strdup_printf ("phase-%02u.png", k);
    g_assert_cmpstr (json_object_get_string_member (fr, "file"), ==, name);
    g_assert_cmpint (json_object_get_int_member (fr, "phase"), ==, k);
  }
  if (expect_black) {
    JsonArray *bf = json_object_get_array_member (json_object_get_object_member (o, "black"), "files");
    g_assert_cmpuint (json_array_get_length (bf), ==, 1);
    g_assert_cmpstr (json_array_get_string_element (bf, 0), ==, "black.png");
  } else
    g_assert_false (json_object_has_member (o, "black"));
  /* Clean up: every file we expect, then the folder (fails if anything else was left). */
  const char *files[] = { "phase-00.png", "phase-01.png", "phase-02.png", "phase-03.png", "black.png",
                          "truth_transmissive.tiff", "truth_scattered.tiff", "frames.json" };
  for (guint i = 0; i < G_N_ELEMENTS (files); i++) {
    g_autofree char *p = g_build_filename (dir, files[i], NULL);
    g_unlink (p);
  }
  g_assert_cmpint (g_rmdir (dir), ==, 0);
}

static void
test_render_milk (void)
{
  check_render ("milk-disc", TRUE, 5000, 6);
}

static void
test_render_clear (void)
{
  check_render ("clear-grid", FALSE, 5000, 12);
}

/* A 14-bit sensor whose full well (20000 e- x K 0.25 = 5000 DN, x 10^(6/20) at 6 dB: 9976 DN) is
 * below the ADC's 16383: lit stripes saturate, and every saturated pixel reads exactly the
 * sidecar's saturation_dn while no pixel exceeds it. */
static void
test_render_saturation (void)
{
  g_autoptr (GError) error = NULL;
  g_autofree char *dir = g_dir_make_tmp ("ds-sim-sat-XXXXXX", &error);
  g_assert_no_error (error);
  g_autofree char *scene = g_build_filename (dir, "sat.scene", NULL);
  const char *text = "[sensor]\nwidth=64\nheight=32\nbit-depth=14\nsystem-gain=0.25\nfull-well-e=20000\n"
                     "quantum-efficiency=0.5\nexposure-us=1000\n[illuminator]\nperiod-px=8\nirradiance=10\n";
  g_assert_true (g_file_set_contents (scene, text, -1, &error));
  g_autofree char *out = g_build_filename (dir, "out", NULL);
  const double gains[] = { 0, 6 };
  const double expect[] = { 5000, 9976 };
  for (guint i = 0; i < 2; i++) {
    g_autofree char *gain = g_strdup_printf ("%g", gains[i]);
    const char *args[] = { DS_SIM_BIN, "render", scene, "--phases", "2", "--out", out, "--gain-db", gain, NULL };
    int status = -1;
    g_autofree char *stdout_text = run (args, &status);
    g_assert_true (g_spawn_check_wait_status (status, NULL));
    g_autoptr (JsonParser) parser = json_parser_new ();
    g_autofree char *sidecar = g_build_filename (out, "frames.json", NULL);
    g_assert_true (json_parser_load_from_file (parser, sidecar, &error));
    JsonObject *o = json_node_get_object (json_parser_get_root (parser));
    g_assert_cmpint (json_object_get_int_member (o, "bit_depth"), ==, 14);
    g_assert_cmpstr (json_object_get_string_member (o, "pixel_format"), ==, "Mono14");
    gint64 sat = json_object_get_int_member (o, "saturation_dn");
    g_assert_cmpint (sat, ==, (gint64) expect[i]);
    g_assert_cmpfloat (json_object_get_double_member (o, "gain_db"), ==, gains[i]);
    /* 10 photons/um^2/ms x 100 um^2 x 1 ms x QE 0.5 = 5e5 e-: lit pixels are full. */
    g_autofree char *p0 = g_build_filename (out, "phase-00.png", NULL);
    g_autoptr (DsImage) im = ds_image_read (p0, &error);
    g_assert_no_error (error);
    guint saturated = 0;
    for (guint y = 0; y < im->height; y++)
      for (guint x = 0; x < im->width; x++) {
        guint v = ((guint16 *) ds_image_row (im, y))[x];
        g_assert_cmpuint (v, <=, sat);
        saturated += v == sat;
      }
    g_assert_cmpuint (saturated, >=, 64 * 32 / 2 - 32); /* half the columns, less the edge pixels */
  }
  const char *files[] = { "phase-00.png", "phase-01.png", "truth_transmissive.tiff", "truth_scattered.tiff",
                          "frames.json" };
  for (guint i = 0; i < G_N_ELEMENTS (files); i++) {
    g_autofree char *p = g_build_filename (out, files[i], NULL);
    g_assert_cmpint (g_unlink (p), ==, 0);
  }
  g_assert_cmpint (g_rmdir (out), ==, 0);
  g_unlink (scene);
  g_assert_cmpint (g_rmdir (dir), ==, 0);
}

/* Energy bookkeeping: without objects, the scattered truth over the frame is, per pixel of
 * incident light, the slab's scattered transmittance within the acceptance cone that
 * `descatter-sim slab` tallies for the same medium (an independent run, another seed), within
 * Monte Carlo error and the 0.5 % the kernel is allowed to leave beyond its radius. */
static void
test_energy_bookkeeping (void)
{
  g_autoptr (GError) error = NULL;
  g_autofree char *dir = g_dir_make_tmp ("ds-sim-energy-XXXXXX", &error);
  g_assert_no_error (error);
  g_autofree char *scene = g_build_filename (dir, "milk.scene", NULL);
  /* 1 photon/um^2/ms on (5 um / 0.05)^2 = 1e4 um^2 for 1 ms, QE 0.5, K 0.5: 2500 DN per pixel. */
  const char *text = "[sensor]\nwidth=64\nheight=48\nbit-depth=16\nquantum-efficiency=0.5\nsystem-gain=0.5\n"
                     "full-well-e=1e7\nexposure-us=1000\n[illuminator]\nperiod-px=8\nirradiance=1\n"
                     "[medium]\nthickness-mm=10\nmua=0.002\nmus=0.3\ng=0.7\nn=1.33\nphotons=1000000\nseed=7\n"
                     "[camera]\nacceptance-half-angle-deg=10\n";
  g_assert_true (g_file_set_contents (scene, text, -1, &error));
  g_autofree char *out = g_build_filename (dir, "out", NULL);
  const char *render[] = { DS_SIM_BIN, "render", scene, "--phases", "2", "--out", out, NULL };
  int status = -1;
  g_free (run (render, &status));
  g_assert_true (g_spawn_check_wait_status (status, NULL));
  const char *slab[] = { DS_SIM_BIN, "slab", "--mua", "0.002", "--mus", "0.3", "--g", "0.7", "--thickness", "10",
                         "--n", "1.33", "--acceptance", "10", "--photons", "1000000", "--seed", "3", NULL };
  g_autofree char *tally = run (slab, &status);
  g_assert_true (g_spawn_check_wait_status (status, NULL));
  const char *line = strstr (tally, "scattered transmittance within 10 deg");
  g_assert_nonnull (line);
  double t = 0, se = 0;
  g_assert_cmpint (sscanf (line, "scattered transmittance within 10 deg %lf +- %lf", &t, &se), ==, 2);
  g_autofree char *p = g_build_filename (out, "truth_scattered.tiff", NULL);
  g_autoptr (DsImage) truth = ds_image_read (p, &error);
  g_assert_no_error (error);
  double sum = 0;
  for (guint y = 0; y < truth->height; y++)
    for (guint x = 0; x < truth->width; x++)
      sum += ((const float *) ds_image_row (truth, y))[x];
  double per_px = sum / (truth->width * truth->height) / 2500.0;
  g_test_message ("scattered truth %.5f of the incident light per pixel; descatter-sim slab %.5f +- %.5f", per_px, t, se);
  g_assert_cmpfloat (per_px, <=, t + 4 * G_SQRT2 * se);
  g_assert_cmpfloat (per_px, >=, 0.995 * t - 4 * G_SQRT2 * se);
  g_autofree char *rm = g_strdup_printf ("rm -rf '%s'", dir);
  g_assert_cmpint (system (rm), ==, 0);
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
  /* The kernel's energy and the share of scattered light still modulated; a warning where the
   * scattered light keeps the stripes (hdr-saturation: a weak, forward-peaked medium whose kernel
   * is hardly wider than the 8 px period), none where it does not (milk-disc). */
  g_autofree char *hdr = g_strdup_printf ("%s/hdr-saturation.scene", DS_SCENES_DIR);
  const char *args_hdr[] = { DS_SIM_BIN, "describe", hdr, NULL };
  g_autofree char *out_hdr = run (args_hdr, &status);
  g_assert_true (g_spawn_check_wait_status (status, NULL));
  g_assert_nonnull (strstr (out_hdr, "holds 99."));
  g_assert_nonnull (strstr (out_hdr, "still modulated at the period (8 px)"));
  g_assert_nonnull (strstr (out_hdr, "warning: the scattered light keeps the stripes"));
  g_autofree char *milk = g_strdup_printf ("%s/milk-disc.scene", DS_SCENES_DIR);
  const char *args_milk[] = { DS_SIM_BIN, "describe", milk, NULL };
  g_autofree char *out_milk = run (args_milk, &status);
  g_assert_true (g_spawn_check_wait_status (status, NULL));
  g_assert_nonnull (strstr (out_milk, "followed through 1 plane at 5 mm"));
  g_assert_null (strstr (out_milk, "warning"));
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
  g_test_add_func ("/sim/cli/render-saturation", test_render_saturation);
  g_test_add_func ("/sim/cli/energy-bookkeeping", test_energy_bookkeeping);
  g_test_add_func ("/sim/cli/describe", test_describe);
  return g_test_run ();
}
