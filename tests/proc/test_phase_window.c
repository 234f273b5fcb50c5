/* The sliding phase window against its definition: a fresh DsPhaseSet over the window's frames
 * in arrival order, compared bit for bit, for every estimator and sample type, across breaks. */
#include <math.h>
#include <string.h>

#include "proc/phase_window.h"
#include "proc/proc_error.h"

#define W 61
#define H 17

/* Frame t of a stripe sequence: phase t mod N over a scene whose transmission varies in x and
 * y, with pseudo-random noise, so that max, min and sums differ at every pixel. */
static DsImage *
make_frame (DsSampleType type, guint bits, guint n, guint64 t, GRand *r)
{
  DsImage *img = ds_image_new (type, W, H, NULL);
  img->bit_depth = bits;
  double full = (double) ((1u << bits) - 1);
  guint k = (guint) (t % n);
  for (guint y = 0; y < H; y++)
    for (guint x = 0; x < W; x++) {
      double ld = 0.5 + 0.4 * sin (0.3 * x + 0.7 * y);
      double lit = fmod (x / 8.0 + (double) k / n, 1.0) < 0.5 ? 1.0 : 0.05;
      double v = (0.2 + 0.5 * ld * lit) * full * 0.8 + g_rand_double_range (r, -3, 3);
      v = CLAMP (v, 0, full);
      void *row = ds_image_row (img, y);
      if (type == DS_SAMPLE_U8)
        ((guint8 *) row)[x] = (guint8) v;
      else if (type == DS_SAMPLE_U16)
        ((guint16 *) row)[x] = (guint16) v;
      else
        ((float *) row)[x] = (float) v;
    }
  return img;
}

static void
assert_same_plane (const DsImage *a, const DsImage *b, const char *what)
{
  if (!a && !b)
    return;
  g_assert_nonnull (a);
  g_assert_nonnull (b);
  g_assert_cmpuint (a->type, ==, b->type);
  gsize row = (gsize) a->width * ds_sample_size (a->type);
  for (guint y = 0; y < a->height; y++)
    if (memcmp (ds_image_row (a, y), ds_image_row (b, y), row) != 0)
      g_error ("%s differs from the fresh set's in row %u", what, y);
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
  for (guint bit = 0; bit < DS_MASK_N_BITS; bit++)
    g_assert_cmpuint (a->meta.flagged[bit], ==, b->meta.flagged[bit]);
}

typedef struct {
  DsEstimator estimator;
  DsSampleType type;
  guint bits;
  guint n;
  gboolean dark;
} Case;

/* Frames 0..T-1 in cyclic order, a lost frame (a break) at `lost`: each window result must
 * equal a fresh set over frames t-N+1..t, and no result may come before N frames follow the
 * break. */
static void
run_case (const Case *c)
{
  DsSeparationParams p;
  ds_separation_params_init (&p, c->n);
  p.estimator = c->estimator;
  p.pattern = DS_PATTERN_SQUARE;
  p.keep_extrema = TRUE;
  p.threads = 1;
  g_autoptr (GError) error = NULL;
  g_autoptr (DsPhaseWindow) win = ds_phase_window_new (&p, W, H, &error);
  g_assert_no_error (error);
  g_autoptr (GRand) r = g_rand_new_with_seed (7 + c->n + c->estimator);
  g_autoptr (DsImage) dark = NULL;
  if (c->dark) {
    dark = ds_image_new (c->type, W, H, NULL);
    dark->bit_depth = c->bits;
    for (guint y = 0; y < H; y++)
      for (guint x = 0; x < W; x++) {
        void *row = ds_image_row (dark, y);
        if (c->type == DS_SAMPLE_U8)
          ((guint8 *) row)[x] = (guint8) (x % 5);
        else if (c->type == DS_SAMPLE_U16)
          ((guint16 *) row)[x] = (guint16) (x % 5);
        else
          ((float *) row)[x] = (float) (x % 5);
      }
    g_assert_true (ds_phase_window_set_dark (win, dark, &error));
  }
  const guint64 total = 4 * c->n + 3, lost = 2 * c->n + 1;
  GPtrArray *frames = g_ptr_array_new_with_free_func ((GDestroyNotify) ds_image_free);
  guint64 good_since_break = 0;
  g_autoptr (DsSeparation) got = ds_separation_new ();
  for (guint64 t = 0; t < total; t++) {
    g_ptr_array_add (frames, make_frame (c->type, c->bits, c->n, t, r));
    if (t == lost) {
      ds_phase_window_break (win);
      good_since_break = 0;
      continue;
    }
    gboolean complete = FALSE;
    g_assert_true (ds_phase_window_push (win, (guint) (t % c->n), frames->pdata[t], &complete,
                                         &error));
    g_assert_no_error (error);
    good_since_break++;
    g_assert_cmpint (complete, ==, good_since_break >= c->n);
    g_assert_cmpuint (ds_phase_window_fill (win), ==, MIN (good_since_break, c->n));
    if (!complete) {
      g_assert_false (ds_phase_window_finalize_into (win, got, &error));
      g_assert_error (error, DS_PROC_ERROR, DS_PROC_ERROR_NOT_ENOUGH_PHASES);
      g_clear_error (&error);
      continue;
    }
    g_assert_cmpuint (ds_phase_window_span (win), ==, c->n);
    g_assert_true (ds_phase_window_finalize_into (win, got, &error));
    g_assert_no_error (error);
    g_autoptr (DsPhaseSet) fresh = ds_phase_set_new (&p, W, H, &error);
    if (dark)
      g_assert_true (ds_phase_set_set_dark (fresh, dark, &error));
    for (guint64 u = t + 1 - c->n; u <= t; u++)
      g_assert_true (ds_phase_set_accumulate (fresh, (guint) (u % c->n), frames->pdata[u], &error));
    g_autoptr (DsSeparation) want = ds_phase_set_finalize (fresh, &error);
    g_assert_no_error (error);
    assert_same_result (got, want);
  }
  g_ptr_array_unref (frames);
}

static void
test_fresh_set_equality (void)
{
  const Case cases[] = {
    { DS_ESTIMATOR_MAXMIN, DS_SAMPLE_U16, 12, 4, FALSE },
    { DS_ESTIMATOR_MAXMIN, DS_SAMPLE_U8, 8, 8, TRUE },
    { DS_ESTIMATOR_SINE, DS_SAMPLE_U16, 16, 8, FALSE },
    { DS_ESTIMATOR_SINE, DS_SAMPLE_U16, 12, 5, TRUE },
    { DS_ESTIMATOR_SINE, DS_SAMPLE_F32, 32, 6, FALSE },
    { DS_ESTIMATOR_ROBUST, DS_SAMPLE_U16, 12, 16, FALSE },
    { DS_ESTIMATOR_ROBUST, DS_SAMPLE_U8, 8, 8, TRUE },
  };
  for (guint i = 0; i < G_N_ELEMENTS (cases); i++)
    run_case (&cases[i]);
}

/* A phase repeated out of turn replaces that phase's frame: the window then spans more pushes
 * than N, and its result is the fresh set over the newest frame of each phase. */
static void
test_repeated_phase (void)
{
  DsSeparationParams p;
  ds_separation_params_init (&p, 4);
  p.threads = 1;
  g_autoptr (DsPhaseWindow) win = ds_phase_window_new (&p, W, H, NULL);
  g_autoptr (GRand) r = g_rand_new_with_seed (3);
  const guint phases[] = { 0, 1, 2, 1, 3 };
  DsImage *f[5];
  for (guint i = 0; i < 5; i++) {
    f[i] = make_frame (DS_SAMPLE_U16, 12, 4, phases[i], r);
    gboolean complete;
    g_assert_true (ds_phase_window_push (win, phases[i], f[i], &complete, NULL));
    g_assert_cmpint (complete, ==, i == 4);
  }
  g_assert_cmpuint (ds_phase_window_span (win), ==, 5);
  g_autoptr (DsSeparation) got = ds_separation_new ();
  g_assert_true (ds_phase_window_finalize_into (win, got, NULL));
  g_autoptr (DsPhaseSet) fresh = ds_phase_set_new (&p, W, H, NULL);
  const guint used[] = { 0, 2, 3, 4 }; /* arrival order of the newest frame of each phase */
  for (guint i = 0; i < 4; i++)
    g_assert_true (ds_phase_set_accumulate (fresh, phases[used[i]], f[used[i]], NULL));
  g_autoptr (DsSeparation) want = ds_phase_set_finalize (fresh, NULL);
  assert_same_result (got, want);
  for (guint i = 0; i < 5; i++)
    ds_image_free (f[i]);
}

/* Bad frames are refused with an error that names them, and leave the window as it was. */
static void
test_bad_frames (void)
{
  DsSeparationParams p;
  ds_separation_params_init (&p, 4);
  g_autoptr (DsPhaseWindow) win = ds_phase_window_new (&p, W, H, NULL);
  g_autoptr (GRand) r = g_rand_new_with_seed (5);
  g_autoptr (DsImage) a = make_frame (DS_SAMPLE_U16, 12, 4, 0, r);
  g_autoptr (DsImage) b8 = make_frame (DS_SAMPLE_U8, 8, 4, 1, r);
  g_autoptr (DsImage) small = ds_image_new (DS_SAMPLE_U16, W - 1, H, NULL);
  g_autoptr (GError) error = NULL;
  g_assert_true (ds_phase_window_push (win, 0, a, NULL, &error));
  g_assert_false (ds_phase_window_push (win, 1, b8, NULL, &error));
  g_assert_error (error, DS_PROC_ERROR, DS_PROC_ERROR_SIZE_MISMATCH);
  g_assert_nonnull (strstr (error->message, "phase 1"));
  g_clear_error (&error);
  g_assert_false (ds_phase_window_push (win, 2, small, NULL, &error));
  g_assert_error (error, DS_PROC_ERROR, DS_PROC_ERROR_SIZE_MISMATCH);
  g_clear_error (&error);
  g_assert_false (ds_phase_window_push (win, 4, a, NULL, &error));
  g_assert_error (error, DS_PROC_ERROR, DS_PROC_ERROR_INVALID_ARGUMENT);
  g_clear_error (&error);
  g_assert_cmpuint (ds_phase_window_fill (win), ==, 1);
  g_assert_cmpuint (ds_phase_window_frames_since_break (win), ==, 1);
  /* After a break the sample type may change: the old frames are gone. */
  ds_phase_window_break (win);
  g_assert_true (ds_phase_window_push (win, 1, b8, NULL, &error));
  g_assert_cmpuint (ds_phase_window_fill (win), ==, 1);
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  g_test_add_func ("/phase-window/fresh-set-equality", test_fresh_set_equality);
  g_test_add_func ("/phase-window/repeated-phase", test_repeated_phase);
  g_test_add_func ("/phase-window/bad-frames", test_bad_frames);
  return g_test_run ();
}
