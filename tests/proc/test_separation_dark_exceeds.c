/* DARK_EXCEEDS against read noise: on a clear scene (no scattered light, no black level) the
 * unlit phases sit at the dark level, so a test without a noise margin flags about half the
 * pixels. The bit must keep to its false-alarm rate (1e-3 per pixel, docs/estimators.md) on
 * such a scene, for every estimator and path, and still flag every pixel whose dark frame is
 * truly brighter than the signal. */
#include <glib.h>
#include <math.h>

#include "proc/separation.h"
#include "tests/proc/separation_scene.h"

enum { W = 256, H = 128, N = 8 };
static const double PEDESTAL = 1000, SIGMA = 3, LD = 400;

typedef struct {
  DsEstimator estimator;
  guint m_frames;
  gboolean model, extrema;
} Case;

/* Fraction of pixels flagged DARK_EXCEEDS when the dark frame is the pedestal + excess, with
 * Gaussian read noise SIGMA in every frame, the dark frame included. */
static double
flagged_fraction (const Case *c, double excess, guint seed)
{
  DsSeparationParams p;
  ds_separation_params_init (&p, N);
  p.estimator = c->estimator;
  p.keep_extrema = c->extrema;
  if (c->model) {
    p.system_gain = 0.01;
    p.read_noise_dn = SIGMA;
  }
  g_autoptr (GError) error = NULL;
  g_autoptr (DsPhaseSet) set = ds_phase_set_new (&p, W, H, &error);
  g_assert_no_error (error);
  TestPattern pat = { DS_PATTERN_SQUARE, 8.0, 0.5, 0.0 };
  GRand *r = g_rand_new_with_seed (seed);
  g_autofree double *ld = g_new (double, (gsize) W * H);
  for (gsize i = 0; i < (gsize) W * H; i++)
    ld[i] = LD;
  for (guint k = 0; k < N; k++)
    for (guint j = 0; j < c->m_frames; j++) {
      g_autoptr (DsImage) f = test_make_frame (DS_SAMPLE_U16, W, H, 0, &pat, k, N, ld, NULL, PEDESTAL, SIGMA, r);
      g_assert_true (ds_phase_set_accumulate (set, k, f, &error));
    }
  g_autoptr (DsImage) dark = test_make_frame (DS_SAMPLE_U16, W, H, 0, &pat, 0, N, NULL, NULL, PEDESTAL + excess, SIGMA, r);
  g_rand_free (r);
  g_assert_true (ds_phase_set_set_dark (set, dark, &error));
  g_autoptr (DsSeparation) sep = ds_phase_set_finalize (set, &error);
  g_assert_no_error (error);
  guint64 count = 0;
  for (guint y = 0; y < H; y++)
    for (guint x = 0; x < W; x++)
      count += (test_pixel_u8 (sep->mask, x, y) & DS_MASK_DARK_EXCEEDS) != 0;
  g_assert_cmpuint (count, ==, sep->meta.flagged[5]);
  return (double) count / (W * H);
}

static const Case cases[] = {
  { DS_ESTIMATOR_MAXMIN, 1, FALSE, FALSE }, /* the integer fast path */
  { DS_ESTIMATOR_MAXMIN, 1, FALSE, TRUE },  /* the general path, data-derived noise */
  { DS_ESTIMATOR_MAXMIN, 1, TRUE, FALSE },  /* the general path, noise model */
  { DS_ESTIMATOR_MAXMIN, 4, FALSE, FALSE }, /* averaging */
  { DS_ESTIMATOR_MAXMIN, 4, TRUE, FALSE },
  { DS_ESTIMATOR_SINE, 1, FALSE, FALSE },
  { DS_ESTIMATOR_SINE, 1, TRUE, FALSE },
  { DS_ESTIMATOR_SINE, 4, FALSE, FALSE },
  { DS_ESTIMATOR_ROBUST, 1, FALSE, FALSE },
  { DS_ESTIMATOR_ROBUST, 1, TRUE, FALSE },
  { DS_ESTIMATOR_ROBUST, 4, FALSE, FALSE },
};

/* Dark at the unlit level: at most 1e-3 of the pixels in expectation; over W*H = 32768
 * pixels, 33 +- 6, so 0.5 % (164) is far above any honest count, and far below the ~50-80 %
 * an unguarded d > min gives. */
static void
test_clear_scene (void)
{
  for (guint i = 0; i < G_N_ELEMENTS (cases); i++) {
    double f = flagged_fraction (&cases[i], 0, 100 + i);
    g_test_message ("case %u (%s, M %u, model %d): %.5f flagged", i, ds_estimator_name (cases[i].estimator),
                    cases[i].m_frames, cases[i].model, f);
    g_assert_cmpfloat (f, <, 0.005);
  }
}

/* Dark 10 sigma of (dark - phase) above the unlit level: every pixel is flagged. The
 * threshold is at most q sigma with q = the (1 - 1e-3/N) normal quantile, 3.66 for N = 8, so
 * a pixel escapes only if every unlit phase lies 6 sigma high. */
static void
test_dark_above_signal (void)
{
  for (guint i = 0; i < G_N_ELEMENTS (cases); i++) {
    double excess = 10 * SIGMA * sqrt (1.0 / cases[i].m_frames + 1.0);
    double f = flagged_fraction (&cases[i], excess, 200 + i);
    g_test_message ("case %u: %.5f flagged", i, f);
    g_assert_cmpfloat (f, ==, 1.0);
  }
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  g_test_add_func ("/separation-dark-exceeds/clear-scene", test_clear_scene);
  g_test_add_func ("/separation-dark-exceeds/dark-above-signal", test_dark_above_signal);
  return g_test_run ();
}
