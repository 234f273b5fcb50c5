#include "proc/image_stats.h"

#include <math.h>

double
ds_image_mean (const DsImage *img)
{
  double total = 0;
  guint64 n = 0;
  for (guint y = 0; y < img->height; y++) {
    const void *row = ds_image_row (img, y);
    for (guint x = 0; x < img->width; x++) {
      double v = ds_image_sample (img, row, x);
      if (isfinite (v)) {
        total += v;
        n++;
      }
    }
  }
  return n ? total / (double) n : NAN;
}

static gint
compare_float (gconstpointer a, gconstpointer b)
{
  float x = *(const float *) a, y = *(const float *) b;
  return (x > y) - (x < y);
}

double
ds_image_percentile (const DsImage *img, double p)
{
  gsize n_px = (gsize) img->width * img->height;
  gsize step = n_px > 1000000 ? n_px / 1000000 : 1;
  GArray *v = g_array_sized_new (FALSE, FALSE, sizeof (float), (guint) (n_px / step + 1));
  gsize i = 0;
  for (guint y = 0; y < img->height; y++) {
    const void *row = ds_image_row (img, y);
    for (guint x = 0; x < img->width; x++, i++)
      if (i % step == 0) {
        float f = (float) ds_image_sample (img, row, x);
        if (isfinite (f))
          g_array_append_val (v, f);
      }
  }
  double r = NAN;
  if (v->len) {
    g_array_sort (v, compare_float);
    r = g_array_index (v, float, (guint) (CLAMP (p, 0, 100) / 100.0 * (v->len - 1)));
  }
  g_array_unref (v);
  return r;
}
