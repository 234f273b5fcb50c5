/* Accuracy metrics against closed forms. */
#include <math.h>

#include "proc/metrics.h"

static DsImage *
filled (guint w, guint h, float (*f) (guint x, guint y))
{
  DsImage *img = ds_image_new (DS_SAMPLE_F32, w, h, NULL);
  for (guint y = 0; y < h; y++) {
    float *r = ds_image_row (img, y);
    for (guint x = 0; x < w; x++)
      r[x] = f (x, y);
  }
  return img;
}

static float ramp (guint x, guint y) { return 10.0f + x + 2.0f * y; }
static float ramp_5pct (guint x, guint y) { return 1.05f * ramp (x, y); }
static float rows_only (guint x, guint y) { (void) x; return 50.0f + 3.0f * y; }
static float stripes (guint x, guint y) { (void) y; return 100.0f + 7.0f * cosf (2.0f * (float) G_PI * x / 8.0f); }

/* est = 1.05 truth: relative RMSE exactly 0.05, bias = 0.05 mean(truth). */
static void
test_relative_rmse (void)
{
  g_autoptr (DsImage) t = filled (33, 7, ramp);
  g_autoptr (DsImage) e = filled (33, 7, ramp_5pct);
  DsErrorStats s;
  g_assert_true (ds_metrics_error (e, t, NULL, 0xff, &s, NULL));
  g_assert_cmpfloat_with_epsilon (s.relative_rmse, 0.05, 1e-6);
  double mean = 10.0 + 16.0 + 2.0 * 3.0; /* mean of x is 16, of y is 3 */
  g_assert_cmpfloat_with_epsilon (s.bias, 0.05 * mean, 1e-4);
  g_assert_cmpuint (s.valid, ==, 33 * 7);
}

/* Masked and non-finite pixels are left out: a huge error there changes nothing. */
static void
test_mask_and_nonfinite (void)
{
  g_autoptr (DsImage) t = filled (8, 2, ramp);
  g_autoptr (DsImage) e = filled (8, 2, ramp);
  g_autoptr (DsImage) m = ds_image_new (DS_SAMPLE_U8, 8, 2, NULL);
  ((float *) ds_image_row (e, 0))[3] = 1e9f;
  ((guint8 *) ds_image_row (m, 0))[3] = 1;
  ((float *) ds_image_row (e, 1))[5] = NAN;
  DsErrorStats s;
  g_assert_true (ds_metrics_error (e, t, m, 0xff, &s, NULL));
  g_assert_cmpfloat (s.rmse, ==, 0.0);
  g_assert_cmpuint (s.valid, ==, 14);
  g_assert_cmpuint (s.masked, ==, 2);
  /* With the bit not ignored, the error shows. */
  g_assert_true (ds_metrics_error (e, t, m, 0x2, &s, NULL));
  g_assert_cmpfloat (s.rmse, >, 1e7);
}

static void
test_size_mismatch_is_an_error (void)
{
  g_autoptr (DsImage) t = filled (8, 2, ramp);
  g_autoptr (DsImage) e = filled (9, 2, ramp);
  g_autoptr (GError) error = NULL;
  DsErrorStats s;
  g_assert_false (ds_metrics_error (e, t, NULL, 0, &s, &error));
  g_assert_nonnull (error);
}

/* 100 + 7 cos(2 pi x / 8): residue = 7 / 100. */
static void
test_stripe_residue (void)
{
  g_autoptr (DsImage) img = filled (64, 4, stripes);
  double r = 0;
  g_assert_true (ds_metrics_stripe_residue (img, 8.0, &r, NULL));
  g_assert_cmpfloat_with_epsilon (r, 0.07, 1e-4);
  /* Structure that does not vary along x carries no stripe. */
  g_autoptr (DsImage) flat = filled (64, 4, rows_only);
  g_assert_true (ds_metrics_stripe_residue (flat, 8.0, &r, NULL));
  g_assert_cmpfloat (r, <, 1e-3);
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  g_test_add_func ("/metrics/relative-rmse", test_relative_rmse);
  g_test_add_func ("/metrics/mask-and-nonfinite", test_mask_and_nonfinite);
  g_test_add_func ("/metrics/size-mismatch", test_size_mismatch_is_an_error);
  g_test_add_func ("/metrics/stripe-residue", test_stripe_residue);
  return g_test_run ();
}
