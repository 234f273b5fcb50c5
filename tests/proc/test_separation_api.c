/* The separation API that the daemon's zero-copy pipeline builds on: folding from views of
 * memory the set does not own, finalizing into caller-owned (pooled) planes, and splitting the
 * per-pixel work over threads with results bit-identical to one thread. */
#include <glib.h>
#include <math.h>
#include <string.h>

#include "proc/pixfmt.h"
#include "proc/proc_error.h"
#include "proc/separation.h"
#include "tests/proc/separation_scene.h"

static void
assert_same_plane (const DsImage *a, const DsImage *b, const char *what)
{
  if (!a || !b) {
    if (a != b)
      g_error ("%s: one result has the plane, the other not", what);
    return;
  }
  g_assert_cmpuint (a->width, ==, b->width);
  g_assert_cmpuint (a->height, ==, b->height);
  g_assert_cmpint (a->type, ==, b->type);
  gsize row = (gsize) a->width * ds_sample_size (a->type);
  for (guint y = 0; y < a->height; y++)
    if (memcmp (ds_image_row (a, y), ds_image_row (b, y), row) != 0)
      g_error ("%s: row %u differs", what, y);
}

static void
assert_same_result (const DsSeparation *a, const DsSeparation *b)
{
  assert_same_plane (a->transmissive, b->transmissive, "transmissive");
  assert_same_plane (a->scattered, b->scattered, "scattered");
  assert_same_plane (a->mask, b->mask, "mask");
  assert_same_plane (a->max, b->max, "max");
  assert_same_plane (a->min, b->min, "min");
  assert_same_plane (a->mean, b->mean, "mean");
  assert_same_plane (a->sigma_transmissive, b->sigma_transmissive, "sigma_transmissive");
  assert_same_plane (a->sigma_scattered, b->sigma_scattered, "sigma_scattered");
  /* every field, NaNs included: compared as bits */
  g_assert_cmpmem (&a->meta, sizeof a->meta, &b->meta, sizeof b->meta);
}

typedef struct {
  const char *name;
  DsEstimator estimator;
  DsSampleType type;
  guint averages;
  gboolean extrema, model, dark, nonfinite;
} Case;

/* One phase set of a scene with structure in x and y, noise, optionally NaNs and a dark frame.
 * mixed_folds: every other frame is folded on one thread only, the others on all (as descatterd
 * folds while the next frame arrives, and the last one with every thread). */
static DsSeparation *
run_case (const Case *cs, guint threads, gboolean mixed_folds, guint w, guint h, guint n)
{
  DsSeparationParams p;
  ds_separation_params_init (&p, n);
  p.estimator = cs->estimator;
  p.keep_extrema = cs->extrema;
  p.threads = threads;
  if (cs->model) {
    p.system_gain = 0.5;
    p.read_noise_dn = 3;
  }
  g_autoptr (GError) error = NULL;
  g_autoptr (DsPhaseSet) set = ds_phase_set_new (&p, w, h, &error);
  g_assert_no_error (error);
  g_autofree double *ld = g_new (double, (gsize) w * h);
  g_autofree double *lg = g_new (double, (gsize) w * h);
  double scale = cs->type == DS_SAMPLE_U8 ? 0.25 : 1.0; /* u8 frames stay below 255 */
  for (guint y = 0; y < h; y++)
    for (guint x = 0; x < w; x++) {
      ld[(gsize) y * w + x] = scale * (200 + 150 * sin (x * 0.05) * cos (y * 0.07) + (x % 97 == 0 ? -190 : 0));
      lg[(gsize) y * w + x] = scale * (600 + 300 * cos (x * 0.011 + y * 0.02));
    }
  TestPattern pat = { DS_PATTERN_SQUARE, 9.0, 0.5, 0.0 };
  GRand *r = g_rand_new_with_seed (7);
  if (cs->dark) {
    g_autoptr (DsImage) dark = test_make_frame (cs->type, w, h, 0, &pat, 0, n, NULL, NULL, 40 * scale, 2, r);
    g_assert_true (ds_phase_set_set_dark (set, dark, &error));
  }
  for (guint k = 0; k < n; k++)
    for (guint m = 0; m < cs->averages; m++) {
      g_autoptr (DsImage) f = test_make_frame (cs->type, w, h, 0, &pat, k, n, ld, lg, 50 * scale, 4 * scale, r);
      if (cs->nonfinite) {
        ((float *) ds_image_row (f, (k * 31) % h))[(k * 17) % w] = NAN;
        ((float *) ds_image_row (f, h - 1))[w - 1 - k] = INFINITY;
      }
      if (mixed_folds)
        ds_phase_set_set_fold_threads (set, (k * cs->averages + m) % 2 ? 0 : 1);
      g_assert_true (ds_phase_set_accumulate (set, k, f, &error));
    }
  g_rand_free (r);
  if (mixed_folds) /* and the finalize on one thread (descatterd's continuous mode) */
    ds_phase_set_set_finalize_threads (set, 1);
  DsSeparation *sep = ds_phase_set_finalize (set, &error);
  g_assert_no_error (error);
  return sep;
}

/* Every estimator and state layout: 1 thread against 2, 3 and 5, on a frame large enough to be
 * split (odd height: bands of unequal size), also with folds limited to one thread. */
static void
test_threads_bit_identical (void)
{
  const Case cases[] = {
    { "maxmin u16 (fast path)", DS_ESTIMATOR_MAXMIN, DS_SAMPLE_U16, 1, FALSE, FALSE, FALSE, FALSE },
    { "maxmin u16 dark extrema", DS_ESTIMATOR_MAXMIN, DS_SAMPLE_U16, 1, TRUE, FALSE, TRUE, FALSE },
    { "maxmin u8 model", DS_ESTIMATOR_MAXMIN, DS_SAMPLE_U8, 1, FALSE, TRUE, FALSE, FALSE },
    { "maxmin f32 nonfinite", DS_ESTIMATOR_MAXMIN, DS_SAMPLE_F32, 1, TRUE, FALSE, FALSE, TRUE },
    { "maxmin u16 averaging", DS_ESTIMATOR_MAXMIN, DS_SAMPLE_U16, 2, FALSE, TRUE, TRUE, FALSE },
    { "sine u16", DS_ESTIMATOR_SINE, DS_SAMPLE_U16, 1, TRUE, TRUE, FALSE, FALSE },
    { "sine f32 averaging", DS_ESTIMATOR_SINE, DS_SAMPLE_F32, 2, FALSE, FALSE, TRUE, TRUE },
    { "robust u16", DS_ESTIMATOR_ROBUST, DS_SAMPLE_U16, 1, TRUE, TRUE, TRUE, FALSE },
    { "robust u8 averaging", DS_ESTIMATOR_ROBUST, DS_SAMPLE_U8, 2, FALSE, FALSE, FALSE, FALSE },
    { "robust f32", DS_ESTIMATOR_ROBUST, DS_SAMPLE_F32, 1, FALSE, TRUE, FALSE, TRUE },
  };
  const guint w = 515, h = 257, n = 6; /* 132355 pixels: above the threading threshold */
  for (guint i = 0; i < G_N_ELEMENTS (cases); i++) {
    g_test_message ("%s", cases[i].name);
    g_autoptr (DsSeparation) one = run_case (&cases[i], 1, FALSE, w, h, n);
    /* the case must exercise something: some pixels measured, the flags it is about set */
    g_assert_cmpuint (one->meta.valid_pixels, >, (guint64) w * h / 2);
    if (cases[i].nonfinite)
      g_assert_cmpuint (one->meta.flagged[3], >, 0);
    /* the counts in meta are those of the mask plane, counted here pixel by pixel (the
     * library counts eight at a time; w = 515 leaves a tail of 3) */
    guint64 valid = 0, flagged[DS_MASK_N_BITS] = { 0 };
    for (guint y = 0; y < h; y++) {
      const guint8 *mk = ds_image_row (one->mask, y);
      for (guint x = 0; x < w; x++) {
        valid += mk[x] == 0;
        for (guint b = 0; b < DS_MASK_N_BITS; b++)
          flagged[b] += (mk[x] >> b) & 1;
      }
    }
    g_assert_cmpuint (one->meta.valid_pixels, ==, valid);
    for (guint b = 0; b < DS_MASK_N_BITS; b++)
      g_assert_cmpuint (one->meta.flagged[b], ==, flagged[b]);
    const guint threads[] = { 2, 3, 5 };
    for (guint t = 0; t < G_N_ELEMENTS (threads); t++) {
      g_autoptr (DsSeparation) many = run_case (&cases[i], threads[t], FALSE, w, h, n);
      assert_same_result (one, many);
      g_autoptr (DsSeparation) mixed = run_case (&cases[i], threads[t], TRUE, w, h, n);
      assert_same_result (one, mixed);
    }
  }
}

/* A Mono16 payload with padded rows, folded through views (no copy), gives exactly what the
 * unpacked copies give; so does Mono8. The payload is changed after each fold: the set keeps
 * nothing of it. */
static void
test_fold_from_views (void)
{
  const guint w = 37, h = 11, n = 4;
  const DsPixelFormat fmts[] = { DS_PIXFMT_MONO16, DS_PIXFMT_MONO8 };
  for (guint f = 0; f < G_N_ELEMENTS (fmts); f++) {
    DsPixelFormat fmt = fmts[f];
    gsize stride = ds_pixfmt_row_bytes (fmt, w) + 6;
    gsize size = ds_pixfmt_image_bytes (fmt, w, h, stride);
    guint8 *payload = g_malloc (size);
    DsSeparationParams p;
    ds_separation_params_init (&p, n);
    p.keep_extrema = TRUE;
    g_autoptr (DsPhaseSet) by_view = ds_phase_set_new (&p, w, h, NULL);
    g_autoptr (DsPhaseSet) by_copy = ds_phase_set_new (&p, w, h, NULL);
    GRand *r = g_rand_new_with_seed (5 + f);
    for (guint k = 0; k < n; k++) {
      for (gsize i = 0; i < size; i++)
        payload[i] = (guint8) g_rand_int (r);
      g_autoptr (GError) error = NULL;
      g_autoptr (DsImage) copy = ds_pixfmt_unpack (fmt, payload, size, w, h, stride, &error);
      g_assert_no_error (error);
      DsImage view;
      g_assert_true (ds_pixfmt_view (fmt, payload, size, w, h, stride, &view, &error));
      g_assert_true (ds_image_is_view (&view));
      g_assert_true (view.data == payload);
      g_assert_cmpuint (view.bit_depth, ==, ds_pixfmt_bit_depth (fmt));
      g_assert_true (ds_phase_set_accumulate (by_view, k, &view, &error));
      g_assert_true (ds_phase_set_accumulate (by_copy, k, copy, &error));
      memset (payload, 0xFF, size); /* a camera reusing its buffer */
    }
    g_rand_free (r);
    g_autoptr (DsSeparation) a = ds_phase_set_finalize (by_view, NULL);
    g_autoptr (DsSeparation) b = ds_phase_set_finalize (by_copy, NULL);
    assert_same_result (a, b);
    g_free (payload);
  }

  /* views refused: packed formats, misaligned Mono16, short payloads */
  guint8 buf[64] = { 0 };
  DsImage v;
  g_autoptr (GError) e1 = NULL, e2 = NULL, e3 = NULL, e4 = NULL;
  g_assert_false (ds_pixfmt_view (DS_PIXFMT_MONO12P, buf, sizeof buf, 4, 4, 0, &v, &e1));
  g_assert_error (e1, DS_PROC_ERROR, DS_PROC_ERROR_FORMAT);
  g_assert_false (ds_pixfmt_view (DS_PIXFMT_MONO16, buf + 1, sizeof buf - 1, 4, 4, 0, &v, &e2));
  g_assert_error (e2, DS_PROC_ERROR, DS_PROC_ERROR_FORMAT);
  g_assert_false (ds_pixfmt_view (DS_PIXFMT_MONO16, buf, 8, 4, 4, 0, &v, &e3));
  g_assert_error (e3, DS_PROC_ERROR, DS_PROC_ERROR_SIZE_MISMATCH);
  g_assert_false (ds_image_view_init (&v, DS_SAMPLE_U16, 17, 4, 4, 8, buf, sizeof buf, &e4));
  g_assert_error (e4, DS_PROC_ERROR, DS_PROC_ERROR_INVALID_ARGUMENT);
  g_assert_true (ds_pixfmt_viewable (DS_PIXFMT_MONO16, buf, 64));
  g_assert_false (ds_pixfmt_viewable (DS_PIXFMT_MONO16, buf, 63));
  g_assert_false (ds_pixfmt_viewable (DS_PIXFMT_MONO10P, buf, 0));
}

/* finalize_into writes into the caller's planes (here views over one block of caller memory),
 * allocates what is missing, frees what this configuration does not make, and refuses a plane
 * of the wrong shape without writing anything. */
static void
test_finalize_into (void)
{
  const guint w = 19, h = 7, n = 4;
  TestPattern pat = { DS_PATTERN_SQUARE, 8.0, 0.5, 0.0 };
  double ld[19 * 7], lg[19 * 7];
  for (guint i = 0; i < w * h; i++) {
    ld[i] = 100 + i;
    lg[i] = 300 + 2 * i;
  }
  DsSeparationParams p;
  ds_separation_params_init (&p, n);
  g_autoptr (DsPhaseSet) set = ds_phase_set_new (&p, w, h, NULL);
  for (guint k = 0; k < n; k++) {
    g_autoptr (DsImage) f = test_make_frame (DS_SAMPLE_U16, w, h, 0, &pat, k, n, ld, lg, 0, 0, NULL);
    g_assert_true (ds_phase_set_accumulate (set, k, f, NULL));
  }
  g_autoptr (DsSeparation) reference = ds_phase_set_finalize (set, NULL);

  /* caller memory: three planes with a padded stride, in one block */
  gsize fstride = 96, mstride = 32;
  gsize bytes = 2 * fstride * h + mstride * h;
  float *block = g_malloc (bytes);
  memset (block, 0x5A, bytes);
  guint8 *base = (guint8 *) block;
  g_autoptr (DsSeparation) pooled = ds_separation_new ();
  g_autoptr (GError) error = NULL;
  pooled->transmissive = ds_image_new_view (DS_SAMPLE_F32, 0, w, h, fstride, base, fstride * h, &error);
  pooled->scattered = ds_image_new_view (DS_SAMPLE_F32, 0, w, h, fstride, base + fstride * h, fstride * h, &error);
  pooled->mask = ds_image_new_view (DS_SAMPLE_U8, 0, w, h, mstride, base + 2 * fstride * h, mstride * h, &error);
  g_assert_no_error (error);
  /* a stale plane this configuration does not make */
  pooled->max = ds_image_new (DS_SAMPLE_F32, w, h, NULL);
  DsImage *t_before = pooled->transmissive;
  g_assert_true (ds_phase_set_finalize_into (set, pooled, &error));
  g_assert_no_error (error);
  g_assert_true (pooled->transmissive == t_before);
  g_assert_true (pooled->transmissive->data == base);
  g_assert_null (pooled->max);
  assert_same_result (reference, pooled);
  /* the padding of the caller's rows is untouched */
  for (guint y = 0; y < h; y++)
    g_assert_cmphex (base[y * fstride + w * sizeof (float)], ==, 0x5A);

  /* again into the same planes: the pool's steady state */
  g_assert_true (ds_phase_set_finalize_into (set, pooled, &error));
  assert_same_result (reference, pooled);

  /* a plane of another size: refused, named, nothing written */
  g_autoptr (DsSeparation) wrong = ds_separation_new ();
  wrong->transmissive = ds_image_new (DS_SAMPLE_F32, w + 1, h, NULL);
  wrong->scattered = ds_image_new (DS_SAMPLE_F32, w, h, NULL);
  g_assert_false (ds_phase_set_finalize_into (set, wrong, &error));
  g_assert_error (error, DS_PROC_ERROR, DS_PROC_ERROR_INVALID_ARGUMENT);
  g_assert_nonnull (strstr (error->message, "transmissive"));
  g_assert_null (wrong->mask);
  const float *s0 = ds_image_row (wrong->scattered, 0);
  g_assert_cmpfloat (s0[0], ==, 0.0f);

  /* ds_separation_free frees view planes without touching the caller's memory */
  g_clear_pointer (&pooled, ds_separation_free);
  g_free (block);
}

static void
test_mask_bit_names (void)
{
  const char *expect[] = { "saturated", "dark", "low_modulation", "nonfinite", "negative",
                           "dark_exceeds", "undersampled", "motion" };
  G_STATIC_ASSERT (G_N_ELEMENTS (expect) == DS_MASK_N_BITS);
  for (guint i = 0; i < DS_MASK_N_BITS; i++)
    g_assert_cmpstr (ds_mask_bit_name (i), ==, expect[i]);
  g_assert_null (ds_mask_bit_name (DS_MASK_N_BITS));
  g_assert_cmpint (DS_MASK_UNDERSAMPLED, ==, 64);
  g_assert_cmpint (DS_MASK_MOTION, ==, 128);
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  g_test_add_func ("/separation-api/threads-bit-identical", test_threads_bit_identical);
  g_test_add_func ("/separation-api/fold-from-views", test_fold_from_views);
  g_test_add_func ("/separation-api/finalize-into", test_finalize_into);
  g_test_add_func ("/separation-api/mask-bit-names", test_mask_bit_names);
  return g_test_run ();
}
