/* The kernel cache: a hit returns the computed data bit for bit, anything damaged or another
 * key's is recomputed, every shaping parameter is part of the key; and the `slab` subcommand's
 * interface. */
#include <glib/gstdio.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "drivers/sim/sim_error.h"
#include "drivers/sim/transport.h"
#include "tests/common/test_tree.h"

static const DsSlab slab = { 0.1, 4.0, 0.7, 1.0, 1.33, 1.0, 1.0 };

static void
assert_same (const DsImage *a, const DsImage *b)
{
  g_assert_true (ds_image_same_shape (a, b));
  for (guint y = 0; y < a->height; y++)
    g_assert_cmpmem (ds_image_row (a, y), a->width * sizeof (float), ds_image_row (b, y),
                     b->width * sizeof (float));
}

static void
assert_same_kernels (const DsSlabKernels *a, const DsSlabKernels *b)
{
  g_assert_cmpuint (a->radius_px, ==, b->radius_px);
  g_assert_cmpuint (a->planes.n_planes, ==, b->planes.n_planes);
  g_assert_cmpfloat (a->scattered_in_cone, ==, b->scattered_in_cone);
  g_assert_cmpfloat (a->held, ==, b->held);
  g_assert_cmpfloat (a->effective_records, ==, b->effective_records);
  assert_same (a->full, b->full);
  /* Without planes there are no segments or crossings. */
  for (guint j = 0; a->planes.n_planes && j <= a->planes.n_planes; j++) {
    g_assert_cmpfloat (a->segments[j].stays_ballistic, ==, b->segments[j].stays_ballistic);
    assert_same (a->segments[j].from_ballistic, b->segments[j].from_ballistic);
    if (j > 0) {
      assert_same (a->segments[j].from_scattered, b->segments[j].from_scattered);
      assert_same (a->crossings[j - 1].recross_scattered, b->crossings[j - 1].recross_scattered);
      g_assert_cmpfloat (a->crossings[j - 1].once_ballistic, ==, b->crossings[j - 1].once_ballistic);
      g_assert_cmpfloat (a->crossings[j - 1].recross_times[1], ==, b->crossings[j - 1].recross_times[1]);
    }
  }
}

static char *
only_file (const char *dir)
{
  g_autoptr (GDir) d = g_dir_open (dir, 0, NULL);
  g_assert_nonnull (d);
  const char *name = g_dir_read_name (d);
  g_assert_nonnull (name);
  g_assert_null (g_dir_read_name (d));
  return g_build_filename (dir, name, NULL);
}

static guint
count_files (const char *dir)
{
  g_autoptr (GDir) d = g_dir_open (dir, 0, NULL);
  guint n = 0;
  while (d && g_dir_read_name (d))
    n++;
  return n;
}

/* Kernels without object planes: a few thousand photons, a small kernel. */
static DsSlabKernelSpec
spec_of (DsTransportModel model, guint64 seed)
{
  DsSlabKernelSpec spec = { model, 0.1, 30.0, 0.995, 3000, seed, { 0, { 0 } } };
  return spec;
}

static DsSlabKernels *
cached (DsTransportModel model, const DsSlab *s, guint64 seed, const char *dir, gboolean *hit)
{
  g_autoptr (GError) error = NULL;
  DsSlabKernelSpec spec = spec_of (model, seed);
  DsSlabKernels *k = ds_slab_kernels_cached (s, &spec, dir, hit, &error);
  g_assert_no_error (error);
  g_assert_nonnull (k);
  return k;
}

static DsSlabKernels *
computed (DsTransportModel model, const DsSlab *s, guint64 seed)
{
  g_autoptr (GError) error = NULL;
  DsSlabKernelSpec spec = spec_of (model, seed);
  DsSlabKernels *k = ds_slab_kernels_compute (s, &spec, 1, &error);
  g_assert_no_error (error);
  g_assert_nonnull (k);
  return k;
}

static void
test_hit_and_keys (void)
{
  g_autofree char *dir = g_dir_make_tmp ("ds-psf-XXXXXX", NULL);
  g_autofree char *sub = g_build_filename (dir, "a", "b", NULL); /* created on demand */
  gboolean hit = TRUE;
  g_autoptr (DsSlabKernels) first = cached (DS_TRANSPORT_MONTE_CARLO, &slab, 9, sub, &hit);
  g_assert_false (hit);
  g_autoptr (DsSlabKernels) direct = computed (DS_TRANSPORT_MONTE_CARLO, &slab, 9);
  assert_same_kernels (first, direct);
  g_autoptr (DsSlabKernels) again = cached (DS_TRANSPORT_MONTE_CARLO, &slab, 9, sub, &hit);
  g_assert_true (hit);
  assert_same_kernels (first, again);
  /* Another seed, another slab parameter, another model: misses. */
  g_autoptr (DsSlabKernels) other_seed = cached (DS_TRANSPORT_MONTE_CARLO, &slab, 10, sub, &hit);
  g_assert_false (hit);
  DsSlab s2 = slab;
  s2.n_below = 1.5;
  g_autoptr (DsSlabKernels) other_slab = cached (DS_TRANSPORT_MONTE_CARLO, &s2, 9, sub, &hit);
  g_assert_false (hit);
  g_autoptr (DsSlabKernels) diffusion = cached (DS_TRANSPORT_DIFFUSION, &slab, 9, sub, &hit);
  g_assert_false (hit);
  /* Diffusion without planes does not depend on photons or seed, so they are not part of its key. */
  g_autoptr (DsSlabKernels) diffusion2 = cached (DS_TRANSPORT_DIFFUSION, &slab, 12345, sub, &hit);
  g_assert_true (hit);
  assert_same_kernels (diffusion, diffusion2);
  g_assert_cmpuint (count_files (sub), ==, 4);
  test_remove_tree (dir);
}

static void
test_corrupt_recomputed (void)
{
  g_autofree char *dir = g_dir_make_tmp ("ds-psf-XXXXXX", NULL);
  gboolean hit = TRUE;
  g_autoptr (DsSlabKernels) good = cached (DS_TRANSPORT_MONTE_CARLO, &slab, 9, dir, &hit);
  g_assert_false (hit);
  g_autofree char *path = only_file (dir);
  g_autofree char *bytes = NULL;
  gsize len = 0;
  g_assert_true (g_file_get_contents (path, &bytes, &len, NULL));
  /* A flipped bit in the data, a truncated file, garbage of the right length, an empty file,
   * trailing bytes after a whole file. */
  for (int kind = 0; kind < 5; kind++) {
    g_autofree char *bad = g_malloc (len + 4);
    memcpy (bad, bytes, len);
    gsize bad_len = len;
    if (kind == 0)
      bad[len / 2] ^= 0x10;
    else if (kind == 1)
      bad_len = len - 7;
    else if (kind == 2)
      memset (bad, 0x7f, len);
    else if (kind == 3)
      bad_len = 0;
    else
      bad_len = len + 4;
    g_assert_true (g_file_set_contents (path, bad, (gssize) bad_len, NULL));
    g_autoptr (DsSlabKernels) k = cached (DS_TRANSPORT_MONTE_CARLO, &slab, 9, dir, &hit);
    g_assert_false (hit);
    assert_same_kernels (good, k);
    /* The recomputed kernels replaced the damaged file. */
    g_autoptr (DsSlabKernels) next = cached (DS_TRANSPORT_MONTE_CARLO, &slab, 9, dir, &hit);
    g_assert_true (hit);
  }
  test_remove_tree (dir);
}

/* A whole, well-formed file of another key under this key's name (a copied cache, a name
 * collision) is not this key's kernels. */
static void
test_wrong_key (void)
{
  g_autofree char *dir_a = g_dir_make_tmp ("ds-psf-XXXXXX", NULL);
  g_autofree char *dir_b = g_dir_make_tmp ("ds-psf-XXXXXX", NULL);
  gboolean hit = TRUE;
  g_autoptr (DsSlabKernels) a = cached (DS_TRANSPORT_MONTE_CARLO, &slab, 9, dir_a, &hit);
  g_autoptr (DsSlabKernels) b = cached (DS_TRANSPORT_MONTE_CARLO, &slab, 10, dir_b, &hit);
  g_autofree char *path_a = only_file (dir_a);
  g_autofree char *path_b = only_file (dir_b);
  g_assert_cmpstr (strrchr (path_a, '/'), !=, strrchr (path_b, '/'));
  g_autofree char *bytes = NULL;
  gsize len = 0;
  g_assert_true (g_file_get_contents (path_a, &bytes, &len, NULL));
  g_assert_true (g_file_set_contents (path_b, bytes, (gssize) len, NULL));
  g_autoptr (DsSlabKernels) again = cached (DS_TRANSPORT_MONTE_CARLO, &slab, 10, dir_b, &hit);
  g_assert_false (hit);
  g_autoptr (DsSlabKernels) direct = computed (DS_TRANSPORT_MONTE_CARLO, &slab, 10);
  assert_same_kernels (direct, again);
  test_remove_tree (dir_a);
  test_remove_tree (dir_b);
}

/* The renderer's kernels with their chain through two planes: a hit is the computation bit for
 * bit, the planes are part of the key, and damage means recomputation. */
static void
test_kernels_cached (void)
{
  g_autofree char *dir = g_dir_make_tmp ("ds-psf-XXXXXX", NULL);
  DsSlabKernelSpec spec = { DS_TRANSPORT_MONTE_CARLO, 0.1, 30.0, 0.995, 20000, 4, { 2, { 0.3, 0.7 } } };
  g_autoptr (GError) error = NULL;
  gboolean hit = TRUE;
  g_autoptr (DsSlabKernels) first = ds_slab_kernels_cached (&slab, &spec, dir, &hit, &error);
  g_assert_no_error (error);
  g_assert_false (hit);
  g_autoptr (DsSlabKernels) direct = ds_slab_kernels_compute (&slab, &spec, 1, &error);
  g_assert_no_error (error);
  assert_same_kernels (first, direct);
  g_autoptr (DsSlabKernels) again = ds_slab_kernels_cached (&slab, &spec, dir, &hit, &error);
  g_assert_true (hit);
  assert_same_kernels (first, again);
  spec.planes.depth_mm[1] = 0.8;
  g_autoptr (DsSlabKernels) moved = ds_slab_kernels_cached (&slab, &spec, dir, &hit, &error);
  g_assert_false (hit);
  g_assert_cmpfloat (moved->planes.depth_mm[1], ==, 0.8);
  spec.planes.depth_mm[1] = 0.7;
  /* Damage every file: a flipped bit, a truncation. */
  for (int kind = 0; kind < 2; kind++) {
    g_autoptr (GDir) d = g_dir_open (dir, 0, NULL);
    for (const char *name; (name = g_dir_read_name (d));) {
      g_autofree char *path = g_build_filename (dir, name, NULL);
      g_autofree char *bytes = NULL;
      gsize len = 0;
      g_assert_true (g_file_get_contents (path, &bytes, &len, NULL));
      if (kind == 0)
        bytes[len / 3] ^= 0x01;
      g_assert_true (g_file_set_contents (path, bytes, (gssize) (kind == 1 ? len - 9 : len), NULL));
    }
    g_autoptr (DsSlabKernels) k = ds_slab_kernels_cached (&slab, &spec, dir, &hit, &error);
    g_assert_no_error (error);
    g_assert_false (hit);
    assert_same_kernels (first, k);
  }
  test_remove_tree (dir);
}

static void
test_default_dir_and_unwritable (void)
{
  g_autofree char *dir = g_dir_make_tmp ("ds-psf-XXXXXX", NULL);
  g_setenv ("XDG_CACHE_HOME", dir, TRUE);
  gboolean hit = TRUE;
  g_autoptr (DsSlabKernels) a = cached (DS_TRANSPORT_DIFFUSION, &slab, 1, NULL, &hit);
  g_assert_false (hit);
  g_autofree char *psf_dir = g_build_filename (dir, "descatter", "psf", NULL);
  g_autofree char *path = only_file (psf_dir);
  g_assert_true (g_str_has_suffix (path, ".kernels"));
  /* A cache folder that cannot exist (below a regular file): computed, not cached, said so. */
  g_autofree char *file = g_build_filename (dir, "plain", NULL);
  g_assert_true (g_file_set_contents (file, "x", 1, NULL));
  g_autofree char *below = g_build_filename (file, "psf", NULL);
  g_test_expect_message (NULL, G_LOG_LEVEL_MESSAGE, "kernel cache: cannot create*");
  g_autoptr (DsSlabKernels) b = cached (DS_TRANSPORT_DIFFUSION, &slab, 1, below, &hit);
  g_test_assert_expected_messages ();
  g_assert_false (hit);
  assert_same_kernels (a, b);
  /* Bad input is an error, not a crash, and nothing is written. */
  g_autofree char *empty = g_build_filename (dir, "empty", NULL);
  DsSlab bad = slab;
  bad.g = 1.5;
  DsSlabKernelSpec spec = spec_of (DS_TRANSPORT_MONTE_CARLO, 1);
  g_autoptr (GError) error = NULL;
  g_assert_null (ds_slab_kernels_cached (&bad, &spec, empty, &hit, &error));
  g_assert_error (error, DS_SIM_ERROR, DS_SIM_ERROR_INVALID);
  g_clear_error (&error);
  spec.model = (DsTransportModel) 7;
  g_assert_null (ds_slab_kernels_cached (&slab, &spec, empty, &hit, &error));
  g_assert_error (error, DS_SIM_ERROR, DS_SIM_ERROR_INVALID);
  g_clear_error (&error);
  spec = spec_of (DS_TRANSPORT_MONTE_CARLO, 1);
  spec.planes.n_planes = 1;
  spec.planes.depth_mm[0] = 2 * slab.thickness_mm;
  g_assert_null (ds_slab_kernels_cached (&slab, &spec, empty, &hit, &error));
  g_assert_error (error, DS_SIM_ERROR, DS_SIM_ERROR_INVALID);
  g_assert_false (g_file_test (empty, G_FILE_TEST_EXISTS));
  test_remove_tree (dir);
}

static int
slab_main (const char *args)
{
  g_auto (GStrv) strings = g_strsplit (args, " ", -1);
  /* Option parsing removes what it consumed from argv: hand it a copy of the pointers so
   * that every string is still freed here. */
  guint n = g_strv_length (strings);
  g_autofree char **argv = g_memdup2 (strings, (n + 1) * sizeof (char *));
  return ds_sim_slab_main ((int) n, argv);
}

static void
test_cli (void)
{
  if (g_test_subprocess ()) {
    exit (slab_main ("slab --mua 1 --mus 9 --g 0.75 --thickness 0.2 --n 1 --photons 20000 --seed 3"));
  }
  g_test_trap_subprocess (NULL, 0, G_TEST_SUBPROCESS_DEFAULT);
  g_test_trap_assert_passed ();
  g_test_trap_assert_stdout ("*total diffuse reflectance  0.0*+-*total transmittance        0.6*+-*"
                             "ballistic transmittance    0.13*+-*absorbed fraction          0.2*+-*");
}

/* Missing parameter, out-of-range g, unknown option, stray argument, n < 1: exit status 1
 * with a message naming the command. */
static const char *bad_args[] = { "slab --mus 9 --g 0.75 --thickness 0.2 --n 1",
                                  "slab --mua 1 --mus 9 --g 1.5 --thickness 0.2 --n 1",
                                  "slab --mua 1 --mus 9 --g 0.5 --thickness 0.2 --n 1 --bogus 3",
                                  "slab --mua 1 --mus 9 --g 0.5 --thickness 0.2 --n 1 extra",
                                  "slab --mua 1 --mus 9 --g 0.5 --thickness 0.2 --n 0.5" };

static void
test_cli_errors (void)
{
  for (guint i = 0; i < G_N_ELEMENTS (bad_args); i++) {
    g_autofree char *path = g_strdup_printf ("/sim/transport/cli-errors/subprocess/%u", i);
    g_test_trap_subprocess (path, 0, G_TEST_SUBPROCESS_DEFAULT);
    g_test_trap_assert_failed ();
    g_test_trap_assert_stderr ("*descatter-sim slab: *");
  }
}

static void
run_bad (gconstpointer data)
{
  /* Only meaningful inside test_cli_errors' subprocesses. */
  if (g_test_subprocess ())
    exit (slab_main (data));
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  g_test_add_func ("/sim/transport/cache/hit-and-keys", test_hit_and_keys);
  g_test_add_func ("/sim/transport/cache/corrupt-recomputed", test_corrupt_recomputed);
  g_test_add_func ("/sim/transport/cache/wrong-key", test_wrong_key);
  g_test_add_func ("/sim/transport/cache/kernels", test_kernels_cached);
  g_test_add_func ("/sim/transport/cache/default-dir-and-unwritable", test_default_dir_and_unwritable);
  g_test_add_func ("/sim/transport/cli", test_cli);
  g_test_add_func ("/sim/transport/cli-errors", test_cli_errors);
  for (guint i = 0; i < G_N_ELEMENTS (bad_args); i++) {
    g_autofree char *path = g_strdup_printf ("/sim/transport/cli-errors/subprocess/%u", i);
    g_test_add_data_func (path, bad_args[i], run_bad);
  }
  return g_test_run ();
}
