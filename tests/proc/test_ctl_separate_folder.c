/* `descatterctl separate` on folders that need more than the images: frames.json (bit depth,
 * saturation, several frames per phase, its refusals), and the phase order measured in the
 * frames (swapped, duplicated and in-between phases), with the period given or detected.
 * Messages are read from the command's stderr in a subprocess. */
#include <glib.h>
#include <glib/gstdio.h>
#include <json-glib/json-glib.h>
#include <math.h>
#include <string.h>

#include "daemon/ctl/ctl_separate.h"
#include "proc/image.h"
#include "separate_run.h"
#include "tests/common/test_tree.h"

#define W 60
#define H 6
#define N 4
#define P 10.0

static double ld_at (guint x, guint y) { return 1000.0 + 10.0 * x + 20.0 * y; }
static double lg_at (guint x, guint y) { return 600.0 + 20.0 * (x % 7) + 4.0 * y; }

/* Phase k of N at offset 0: lit where |frac(x/P - k/N)| < 1/4 (integer values). */
static double
value_at (guint x, guint y, double shift_cycles)
{
  double u = x / P - shift_cycles;
  u -= floor (u + 0.5);
  return ld_at (x, y) * (fabs (u) < 0.25 ? 1.0 : 0.0) + lg_at (x, y) * 0.5;
}

static void
write_frame (const char *dir, const char *name, double shift_cycles, double add)
{
  g_autoptr (DsImage) img = ds_image_new (DS_SAMPLE_U16, W, H, NULL);
  for (guint y = 0; y < H; y++)
    for (guint x = 0; x < W; x++)
      ((guint16 *) ds_image_row (img, y))[x] = (guint16) (value_at (x, y, shift_cycles) + add);
  g_autofree char *path = g_build_filename (dir, name, NULL);
  g_assert_true (ds_image_write (img, path, NULL));
}

static void
set_pixel (const char *dir, const char *name, guint x, guint y, guint16 v)
{
  g_autofree char *path = g_build_filename (dir, name, NULL);
  g_autoptr (DsImage) img = ds_image_read (path, NULL);
  ((guint16 *) ds_image_row (img, y))[x] = v;
  g_assert_true (ds_image_write (img, path, NULL));
}

static void
write_text (const char *dir, const char *name, const char *text)
{
  g_autofree char *path = g_build_filename (dir, name, NULL);
  g_assert_true (g_file_set_contents (path, text, -1, NULL));
}

/* The four phases as phase-0k.png, in order. */
static char *
make_set (void)
{
  char *dir = g_dir_make_tmp ("ds-sepf-XXXXXX", NULL);
  for (guint k = 0; k < N; k++) {
    g_autofree char *name = g_strdup_printf ("phase-%02u.png", k);
    write_frame (dir, name, (double) k / N, 0);
  }
  return dir;
}

static char *
sidecar (guint width, guint height, guint bits, double saturation, guint n, double period, const char *frames)
{
  return g_strdup_printf ("{\"format\": \"descatter-phase-folder\", \"version\": 1, \"width\": %u, \"height\": %u,"
                          " \"bit_depth\": %u, \"saturation_dn\": %g, \"n_phases\": %u,"
                          " \"pattern\": {\"kind\": \"square\", \"period_px\": %g, \"duty\": 0.5, \"black_level\": 0},"
                          " \"frames\": [%s]}",
                          width, height, bits, saturation, n, period, frames);
}

static void
assert_exact (const char *out)
{
  g_autoptr (DsImage) t = separate_read_out (out, "transmissive.tiff");
  g_autoptr (DsImage) s = separate_read_out (out, "scattered.tiff");
  for (guint y = 0; y < H; y++)
    for (guint x = 0; x < W; x++) {
      g_assert_cmpfloat (((float *) ds_image_row (t, y))[x], ==, ld_at (x, y));
      g_assert_cmpfloat (((float *) ds_image_row (s, y))[x], ==, lg_at (x, y));
    }
}

static guint
mask_at (const char *out, guint x, guint y)
{
  g_autoptr (DsImage) m = separate_read_out (out, "mask.png");
  return ((guint8 *) ds_image_row (m, y))[x];
}

/* 12-bit data in 16-bit PNGs: 4095 is saturated with frames.json's bit_depth or --bit-depth,
 * not with the file's 16 bits; a full well below the ADC maximum through saturation_dn or
 * --saturation; a sample above 4095 in a 12-bit folder is refused, naming file and pixel. */
static void
test_bit_depth_saturation (void)
{
  if (g_test_subprocess ()) {
    g_autofree char *dir = make_set ();
    set_pixel (dir, "phase-02.png", 7, 2, 5000);
    const char *frames = "{\"file\": \"phase-00.png\", \"phase\": 0}, {\"file\": \"phase-01.png\", \"phase\": 1},"
                         "{\"file\": \"phase-02.png\", \"phase\": 2}, {\"file\": \"phase-03.png\", \"phase\": 3}";
    g_autofree char *sc = sidecar (W, H, 12u, 4095.0, N, P, frames);
    write_text (dir, "frames.json", sc);
    int status = separate_run ("-q", "--no-preview", dir, NULL);
    test_remove_tree (dir);
    g_assert_cmpint (status, ==, 1);
    return;
  }
  g_test_trap_subprocess (NULL, 0, G_TEST_SUBPROCESS_DEFAULT);
  g_test_trap_assert_passed ();
  g_test_trap_assert_stderr ("*phase-02.png pixel (7, 2) is 5000, above 4095*bit_depth*");

  g_autofree char *dir = make_set ();
  /* pixel (3, 1) reaches 4095 when lit (phase 0 lights x = 0..2 and 8..12 of P = 10... x = 3 is
   * lit by phase 1), pixel (20, 4) reaches 3950 */
  set_pixel (dir, "phase-01.png", 3, 1, 4095);
  set_pixel (dir, "phase-00.png", 20, 4, 3950);
  g_autofree char *out = g_build_filename (dir, "out", NULL);
  g_assert_cmpint (separate_run ("-q", "--no-preview", "--no-phase-check", "--out", out, dir, NULL), ==, 0);
  g_assert_cmpuint (mask_at (out, 3, 1) & 1, ==, 0); /* 16 bits: 65535 would be the level */
  g_assert_cmpint (separate_run ("-q", "--no-preview", "--no-phase-check", "--bit-depth", "12", "--out", out, dir, NULL),
                   ==, 0);
  g_assert_cmpuint (mask_at (out, 3, 1) & 1, ==, 1);
  g_assert_cmpuint (mask_at (out, 20, 4) & 1, ==, 0);
  g_assert_cmpuint (mask_at (out, 3, 2) & 1, ==, 0);
  g_assert_cmpint (
      separate_run ("-q", "--no-preview", "--no-phase-check", "--saturation", "3900", "--out", out, dir, NULL), ==, 0);
  g_assert_cmpuint (mask_at (out, 20, 4) & 1, ==, 1);
  /* the same from frames.json */
  const char *frames = "{\"file\": \"phase-00.png\", \"phase\": 0}, {\"file\": \"phase-01.png\", \"phase\": 1},"
                       "{\"file\": \"phase-02.png\", \"phase\": 2}, {\"file\": \"phase-03.png\", \"phase\": 3}";
  g_autofree char *sc = sidecar (W, H, 12u, 3900.0, N, P, frames);
  write_text (dir, "frames.json", sc);
  g_assert_cmpint (separate_run ("-q", "--no-preview", "--out", out, dir, NULL), ==, 0);
  g_assert_cmpuint (mask_at (out, 3, 1) & 1, ==, 1);
  g_assert_cmpuint (mask_at (out, 20, 4) & 1, ==, 1);
  g_assert_cmpuint (mask_at (out, 21, 4) & 1, ==, 0);
  test_remove_tree (dir);
}

/* frames.json with two frames per phase, listed in acquisition order, and an image it does not
 * list: the listed frames are averaged per phase (here +-2 around the scene), the other ignored. */
static void
test_sidecar_averaging (void)
{
  g_autofree char *dir = g_dir_make_tmp ("ds-sepf-XXXXXX", NULL);
  GString *frames = g_string_new (NULL);
  for (guint k = 0; k < N; k++)
    for (guint m = 0; m < 2; m++) {
      g_autofree char *name = g_strdup_printf ("f%u-%u.png", k, m);
      write_frame (dir, name, (double) k / N, m ? 2 : -2);
      g_string_append_printf (frames, "%s{\"file\": \"%s\", \"phase\": %u, \"frame_id\": %u}",
                              frames->len ? ", " : "", name, k, 100 + 2 * k + m);
    }
  write_frame (dir, "stray.png", 0.37, 5000); /* not listed: not a phase */
  g_autofree char *sc = sidecar (W, H, 16u, 65535.0, N, P, frames->str);
  g_string_free (frames, TRUE);
  write_text (dir, "frames.json", sc);
  g_autofree char *out = g_build_filename (dir, "out", NULL);
  g_assert_cmpint (separate_run ("-q", "--no-preview", "--out", out, dir, NULL), ==, 0);
  assert_exact (out);
  g_autofree char *json = g_build_filename (out, "separation.json", NULL);
  g_autoptr (JsonParser) parser = json_parser_new ();
  g_assert_true (json_parser_load_from_file (parser, json, NULL));
  JsonObject *sep = json_object_get_object_member (json_node_get_object (json_parser_get_root (parser)), "separation");
  g_assert_cmpint (json_object_get_int_member (sep, "frames_per_phase"), ==, 2);
  test_remove_tree (dir);
}

/* Sidecars that must be refused, each naming the key; nothing is written. */
static const char *frames_ok = "{\"file\": \"phase-00.png\", \"phase\": 0}, {\"file\": \"phase-01.png\", \"phase\": 1},"
                               "{\"file\": \"phase-02.png\", \"phase\": 2}, {\"file\": \"phase-03.png\", \"phase\": 3}";
static const struct {
  const char *frames;
  guint width, bits, n;
  const char *raw; /* the whole file instead */
  const char *expect;
} bad_sidecars[] = {
  { NULL, 0, 0, 0, "{\"format\": \"descatter-phase-folder\", \"version\": 1", "*frames.json: not valid JSON at byte 49*" },
  { NULL, 0, 0, 0, "{\"format\": \"other\", \"version\": 1}", "*key \"format\"*" },
  { NULL, 0, 0, 0, "{\"format\": \"descatter-phase-folder\", \"version\": 2}", "*key \"version\"*newer*" },
  { "{\"file\": \"phase-00.png\", \"phase\": 0}, {\"file\": \"gone.png\", \"phase\": 1}", W, 16, 2, NULL,
    "*key \"frames[1].file\": names gone.png*" },
  { "{\"file\": \"phase-00.png\", \"phase\": 0}, {\"file\": \"phase-01.png\", \"phase\": 4}", W, 16, 4, NULL,
    "*key \"frames[1].phase\"*" },
  { "{\"file\": \"phase-00.png\", \"phase\": 0}, {\"file\": \"phase-01.png\", \"phase\": 1}", W, 16, 3, NULL,
    "*no frame of phase 2*" },
  { "{\"file\": \"phase-00.png\", \"phase\": 0}, {\"file\": \"phase-00.png\", \"phase\": 1}", W, 16, 2, NULL,
    "*listed twice*" },
  { NULL, W + 1, 16, N, NULL, "*frames.json says width 61*" },
  { NULL, W, 17, N, NULL, "*key \"bit_depth\"*" },
};

static void
test_sidecar_error (gconstpointer data)
{
  guint i = GPOINTER_TO_UINT (data);
  if (g_test_subprocess ()) {
    g_autofree char *dir = make_set ();
    const char *frames = bad_sidecars[i].frames ? bad_sidecars[i].frames : frames_ok;
    g_autofree char *sc = bad_sidecars[i].raw ? g_strdup (bad_sidecars[i].raw)
                                              : sidecar (bad_sidecars[i].width, H,
                                                                 bad_sidecars[i].bits, 65535.0, bad_sidecars[i].n, P, frames);
    write_text (dir, "frames.json", sc);
    int status = separate_run ("-q", "--no-preview", dir, NULL);
    g_autofree char *json = g_build_filename (dir, "separation.json", NULL);
    gboolean written = g_file_test (json, G_FILE_TEST_EXISTS);
    test_remove_tree (dir);
    g_assert_false (written);
    g_assert_cmpint (status, ==, 1);
    return;
  }
  g_test_trap_subprocess (NULL, 0, G_TEST_SUBPROCESS_DEFAULT);
  g_test_trap_assert_passed ();
  g_test_trap_assert_stderr (bad_sidecars[i].expect);
}

/* Without frames.json the period is found in the frames, and every frame's phase measured:
 * swapped phases are folded as they show (or refused with --strict-phases), a duplicated
 * phase or a frame between two phases is refused, each naming the files. */
static const struct {
  const char *name;
  int status;
  const char *stderr_pattern, *stdout_pattern;
} order_cases[] = {
  { "swapped", 0, "*phase-01.png: given phase 1, shows phase 2*phase-02.png: given phase 2, shows phase 1*", NULL },
  { "strict", 1, "*phase order*phase-01.png: given phase 1, shows phase 2*", NULL },
  { "duplicated", 1, "*phase-02.png: given phase 2, shows phase 1*phase 2: no frame shows it*", NULL },
  { "between", 1, "*phase-03.png: given phase 3, shows none*", NULL },
  { "detected", 0, NULL, "*stripe period * px (detected), phase 0 at * cycles, phase order verified*" },
  /* Frames without stripes at the given period (the stock Aravis fake camera's, in the lab-user
   * trial): separated, the order not verified, and no "phase 0 at nan cycles" printed. */
  { "flat", 0, "*phase order not verified*", "*stripe period 10 px (--period), phase 0 unknown, phase order not verified*" },
};

static void
test_phase_order (gconstpointer data)
{
  guint i = GPOINTER_TO_UINT (data);
  const char *what = order_cases[i].name;
  if (g_test_subprocess ()) {
    g_autofree char *dir = make_set ();
    g_autofree char *out = g_build_filename (dir, "out", NULL);
    if (g_str_equal (what, "swapped") || g_str_equal (what, "strict")) {
      write_frame (dir, "phase-01.png", 2.0 / N, 0);
      write_frame (dir, "phase-02.png", 1.0 / N, 0);
    } else if (g_str_equal (what, "duplicated")) {
      write_frame (dir, "phase-02.png", 1.0 / N, 0);
    } else if (g_str_equal (what, "between")) {
      write_frame (dir, "phase-03.png", 3.5 / N, 0);
    } else if (g_str_equal (what, "flat")) {
      for (guint k = 0; k < N; k++) {
        g_autoptr (DsImage) img = ds_image_new (DS_SAMPLE_U16, W, H, NULL);
        for (guint y = 0; y < H; y++)
          for (guint x = 0; x < W; x++)
            ((guint16 *) ds_image_row (img, y))[x] = (guint16) (1000 + k);
        g_autofree char *path = g_strdup_printf ("%s/phase-%02u.png", dir, k);
        g_assert_true (ds_image_write (img, path, NULL));
      }
    }
    int status = g_str_equal (what, "strict") ? separate_run ("--no-preview", "--out", out, "--strict-phases", dir, NULL)
                 : g_str_equal (what, "flat") ? separate_run ("--no-preview", "--out", out, "--period", "10", dir, NULL)
                                              : separate_run ("--no-preview", "--out", out, dir, NULL);
    if (status == 0 && !g_str_equal (what, "flat"))
      assert_exact (out);
    test_remove_tree (dir);
    g_assert_cmpint (status, ==, order_cases[i].status);
    return;
  }
  g_test_trap_subprocess (NULL, 0, G_TEST_SUBPROCESS_DEFAULT);
  g_test_trap_assert_passed ();
  if (order_cases[i].stderr_pattern)
    g_test_trap_assert_stderr (order_cases[i].stderr_pattern);
  if (order_cases[i].stdout_pattern)
    g_test_trap_assert_stdout (order_cases[i].stdout_pattern);
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  g_test_add_func ("/ctl-separate-folder/bit-depth-saturation", test_bit_depth_saturation);
  g_test_add_func ("/ctl-separate-folder/sidecar-averaging", test_sidecar_averaging);
  for (guint i = 0; i < G_N_ELEMENTS (bad_sidecars); i++) {
    g_autofree char *path = g_strdup_printf ("/ctl-separate-folder/sidecar-error/%u", i);
    g_test_add_data_func (path, GUINT_TO_POINTER (i), test_sidecar_error);
  }
  for (guint i = 0; i < G_N_ELEMENTS (order_cases); i++) {
    g_autofree char *path = g_strdup_printf ("/ctl-separate-folder/phase-order/%s", order_cases[i].name);
    g_test_add_data_func (path, GUINT_TO_POINTER (i), test_phase_order);
  }
  return g_test_run ();
}
