/* Whole-image statistics against values counted by hand. */
#include <math.h>

#include "proc/image_stats.h"

static void
test_mean_and_percentile (void)
{
  /* A u16 ramp 0..99 (10 x 10): mean 49.5, 50th percentile of the sorted values 0..99 at index
   * floor(0.5 * 99) = 49, 100th = 99, 0th = 0. */
  g_autoptr (DsImage) img = ds_image_new (DS_SAMPLE_U16, 10, 10, NULL);
  for (guint y = 0; y < 10; y++)
    for (guint x = 0; x < 10; x++)
      ((guint16 *) ds_image_row (img, y))[x] = (guint16) (y * 10 + x);
  g_assert_cmpfloat (ds_image_mean (img), ==, 49.5);
  g_assert_cmpfloat (ds_image_percentile (img, 50), ==, 49);
  g_assert_cmpfloat (ds_image_percentile (img, 100), ==, 99);
  g_assert_cmpfloat (ds_image_percentile (img, 0), ==, 0);
}

static void
test_nonfinite_left_out (void)
{
  g_autoptr (DsImage) img = ds_image_new (DS_SAMPLE_F32, 3, 1, NULL);
  float *r = ds_image_row (img, 0);
  r[0] = 2;
  r[1] = NAN;
  r[2] = 4;
  g_assert_cmpfloat (ds_image_mean (img), ==, 3);
  g_assert_cmpfloat (ds_image_percentile (img, 100), ==, 4);
  r[0] = r[2] = INFINITY;
  g_assert_true (isnan (ds_image_mean (img)));
}

/* ds_finite_quantile against values whose order statistics are known: the integers 1..n shuffled,
 * NaN and infinities among them. The q-quantile of 1..n, interpolated, is 1 + q (n - 1). */
static void
test_finite_quantile (void)
{
  double v[103];
  for (guint i = 0; i < 100; i++)
    v[i] = (double) ((i * 37) % 100 + 1); /* 37 is prime to 100: each of 1..100 once */
  v[100] = NAN;
  v[101] = INFINITY;
  v[102] = -INFINITY;
  g_assert_cmpfloat (ds_finite_quantile (v, 103, 0.5, 1), ==, 50.5);
  g_assert_cmpfloat (ds_finite_quantile (v, 103, 0.8, 1), ==, 1 + 0.8 * 99);
  g_assert_cmpfloat (ds_finite_quantile (v, 103, 0.0, 1), ==, 1);
  g_assert_cmpfloat (ds_finite_quantile (v, 103, 1.0, 1), ==, 100);
  g_assert_cmpfloat (ds_finite_quantile (v, 99, 0.5, 1), ==, 50); /* 99 values: the middle one */
  g_assert_true (isnan (ds_finite_quantile (v, 103, 0.5, 101)));
  g_assert_true (isnan (ds_finite_quantile (v + 100, 3, 0.5, 1)));
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  g_test_add_func ("/image-stats/mean-and-percentile", test_mean_and_percentile);
  g_test_add_func ("/image-stats/nonfinite", test_nonfinite_left_out);
  g_test_add_func ("/image-stats/finite-quantile", test_finite_quantile);
  return g_test_run ();
}
