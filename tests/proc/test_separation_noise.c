/* The data-derived noise estimate (meta.noise_dn without a noise model): sampled from the
 * first frame, it must stay within a few percent of the known sigma on frames of every shape
 * (wide, tall, one column), with integer quantisation, and with most samples not finite. */
#include <glib.h>
#include <math.h>

#include "proc/separation.h"
#include "tests/proc/separation_scene.h"

static double
estimate (DsSampleType type, guint w, guint h, double sigma, double nan_fraction, guint seed)
{
  const guint n = 4;
  DsSeparationParams p;
  ds_separation_params_init (&p, n);
  g_autoptr (DsPhaseSet) set = ds_phase_set_new (&p, w, h, NULL);
  TestPattern pat = { DS_PATTERN_SQUARE, 10.0, 0.5, 0.0 };
  GRand *r = g_rand_new_with_seed (seed);
  g_autofree double *ld = g_new (double, (gsize) w * h);
  g_autofree double *lg = g_new (double, (gsize) w * h);
  double scale = type == DS_SAMPLE_U8 ? 0.1 : 1.0; /* u8 frames stay below 255 */
  for (gsize i = 0; i < (gsize) w * h; i++) {
    ld[i] = scale * (400 + (i % w) * 0.05); /* varies along x only, like the stripes */
    lg[i] = scale * 1000;
  }
  for (guint k = 0; k < n; k++) {
    g_autoptr (DsImage) f = test_make_frame (type, w, h, 0, &pat, k, n, ld, lg, 100 * scale, sigma, r);
    if (nan_fraction > 0)
      for (guint y = 0; y < h; y++)
        for (guint x = 0; x < w; x++)
          if (g_rand_double (r) < nan_fraction)
            ((float *) ds_image_row (f, y))[x] = NAN;
    g_assert_true (ds_phase_set_accumulate (set, k, f, NULL));
  }
  g_rand_free (r);
  g_autoptr (DsSeparation) sep = ds_phase_set_finalize (set, NULL);
  return sep->meta.noise_dn;
}

static void
test_shapes (void)
{
  const struct {
    DsSampleType type;
    guint w, h;
    double sigma, nan_fraction, tol;
  } cases[] = {
    { DS_SAMPLE_U16, 4096, 40, 6.0, 0, 0.05 },  /* wide: runs spread across the row */
    { DS_SAMPLE_U16, 64, 3000, 6.0, 0, 0.05 },  /* tall */
    { DS_SAMPLE_F32, 1, 20000, 2.0, 0, 0.05 },  /* one column */
    { DS_SAMPLE_F32, 700, 300, 2.0, 0.6, 0.05 }, /* most second differences touch a NaN */
    { DS_SAMPLE_U8, 500, 200, 1.5, 0, 0.05 },   /* a few DN: whole-number differences */
    { DS_SAMPLE_U16, 500, 200, 0.7, 0, 0.05 },  /* below 1 DN */
  };
  for (guint i = 0; i < G_N_ELEMENTS (cases); i++) {
    double got = estimate (cases[i].type, cases[i].w, cases[i].h, cases[i].sigma, cases[i].nan_fraction, 10 + i);
    /* integer frames: rounding to whole DN adds 1/12 DN^2 to what a frame carries */
    double want = cases[i].type == DS_SAMPLE_F32 ? cases[i].sigma : sqrt (cases[i].sigma * cases[i].sigma + 1.0 / 12.0);
    g_test_message ("case %u: %.4f, expected %.4f", i, got, want);
    g_assert_cmpfloat (fabs (got / want - 1), <, cases[i].tol);
  }
  /* every sample NaN: no estimate, and no noise test */
  double none = estimate (DS_SAMPLE_F32, 50, 50, 1.0, 1.0, 3);
  g_assert_true (isnan (none));
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  g_test_add_func ("/separation-noise/shapes", test_shapes);
  return g_test_run ();
}
