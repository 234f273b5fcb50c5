/* proc/live_image: box downscale against averages computed here directly, the mask's OR of
 * flags, and histogram counts against a known distribution. */
#include <glib.h>
#include <math.h>

#include "proc/live_image.h"

static void
test_downscale (void)
{
  /* 10 x 7 with factor 3 (max side 4): boxes of 3x3, partial ones at the right and bottom. */
  g_autoptr (DsImage) img = ds_image_new (DS_SAMPLE_F32, 10, 7, NULL);
  for (guint y = 0; y < 7; y++)
    for (guint x = 0; x < 10; x++)
      ((float *) ds_image_row (img, y))[x] = (float) (x + 10 * y);
  g_assert_cmpuint (ds_live_downscale_factor (10, 7, 4), ==, 3);
  g_autoptr (DsImage) out = ds_live_downscale_u8 (img, 4, 0.0, 255.0, NULL);
  g_assert_cmpuint (out->width, ==, 4);
  g_assert_cmpuint (out->height, ==, 3);
  for (guint by = 0; by < 3; by++)
    for (guint bx = 0; bx < 4; bx++) {
      double sum = 0;
      guint n = 0;
      for (guint y = by * 3; y < MIN (by * 3 + 3, 7u); y++)
        for (guint x = bx * 3; x < MIN (bx * 3 + 3, 10u); x++) {
          sum += x + 10 * y;
          n++;
        }
      g_assert_cmpuint (((guint8 *) ds_image_row (out, by))[bx], ==, (guint) floor (sum / n + 0.5));
    }
}

static void
test_mask_or (void)
{
  g_autoptr (DsImage) m = ds_image_new (DS_SAMPLE_U8, 4, 4, NULL);
  ((guint8 *) ds_image_row (m, 0))[0] = 1;
  ((guint8 *) ds_image_row (m, 1))[1] = 4;
  ((guint8 *) ds_image_row (m, 3))[3] = 32;
  g_autoptr (DsImage) out = ds_live_downscale_u8 (m, 2, NAN, NAN, NULL);
  g_assert_cmpuint (((guint8 *) ds_image_row (out, 0))[0], ==, 5);
  g_assert_cmpuint (((guint8 *) ds_image_row (out, 0))[1], ==, 0);
  g_assert_cmpuint (((guint8 *) ds_image_row (out, 1))[1], ==, 32);
}

static void
test_histogram (void)
{
  g_autoptr (DsImage) img = ds_image_new (DS_SAMPLE_U16, 256, 4, NULL);
  for (guint y = 0; y < 4; y++)
    for (guint x = 0; x < 256; x++)
      ((guint16 *) ds_image_row (img, y))[x] = (guint16) (x * 16); /* 0..4080 */
  guint32 bins[16];
  guint64 above = 0;
  ds_image_histogram (img, 2048, 16, bins, &above);
  /* Values 0..2047 spread evenly: 8 columns x 4 rows per bin; 128 columns at or above 2048. */
  for (guint i = 0; i < 15; i++)
    g_assert_cmpuint (bins[i], ==, 32);
  g_assert_cmpuint (bins[15], ==, 32 + 128 * 4);
  g_assert_cmpuint (above, ==, 128 * 4);
}

static void
test_weighted_sum (void)
{
  g_autoptr (DsImage) a = ds_image_new (DS_SAMPLE_F32, 3, 2, NULL);
  g_autoptr (DsImage) b = ds_image_new (DS_SAMPLE_F32, 3, 2, NULL);
  for (guint y = 0; y < 2; y++)
    for (guint x = 0; x < 3; x++) {
      ((float *) ds_image_row (a, y))[x] = (float) (x + 1);
      ((float *) ds_image_row (b, y))[x] = (float) (10 * y + 2);
    }
  g_autoptr (DsImage) s = ds_image_weighted_sum (a, 0.5, b, 0.25, NULL);
  for (guint y = 0; y < 2; y++)
    for (guint x = 0; x < 3; x++)
      g_assert_cmpfloat (((float *) ds_image_row (s, y))[x], ==, 0.5 * (x + 1) + 0.25 * (10 * y + 2));
}

/* Levels of a uniform ramp are its percentiles, within the sampling step. */
static void
test_levels (void)
{
  g_autoptr (DsImage) img = ds_image_new (DS_SAMPLE_F32, 1000, 100, NULL);
  for (guint y = 0; y < 100; y++)
    for (guint x = 0; x < 1000; x++)
      ((float *) ds_image_row (img, y))[x] = (float) (y * 1000 + x);
  ((float *) ds_image_row (img, 0))[0] = NAN;
  double lo, hi;
  ds_image_levels (img, 1, 99, &lo, &hi);
  g_assert_cmpfloat (fabs (lo - 1000), <, 100);
  g_assert_cmpfloat (fabs (hi - 99000), <, 100);
  /* Integer images: exact. 0..9999 once each: the 10th percentile is 999.9 -> index 999. */
  g_autoptr (DsImage) u = ds_image_new (DS_SAMPLE_U16, 100, 100, NULL);
  for (guint y = 0; y < 100; y++)
    for (guint x = 0; x < 100; x++)
      ((guint16 *) ds_image_row (u, y))[x] = (guint16) (9999 - (y * 100 + x));
  ds_image_levels (u, 10, 90, &lo, &hi);
  g_assert_cmpfloat (lo, ==, 999);
  g_assert_cmpfloat (hi, ==, 8999);
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  g_test_add_func ("/live-image/downscale", test_downscale);
  g_test_add_func ("/live-image/mask-or", test_mask_or);
  g_test_add_func ("/live-image/histogram", test_histogram);
  g_test_add_func ("/live-image/weighted-sum", test_weighted_sum);
  g_test_add_func ("/live-image/levels", test_levels);
  return g_test_run ();
}
