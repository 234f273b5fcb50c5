#include "proc/image_stats.h"

#include <math.h>
#include <stdlib.h>

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

static int
compare_double (const void *a, const void *b)
{
  double x = *(const double *) a, y = *(const double *) b;
  return (x > y) - (x < y);
}

double
ds_finite_quantile (const double *v, gsize n, double q, gsize min_count)
{
  g_autofree double *f = g_new (double, MAX (n, 1));
  gsize m = 0;
  for (gsize i = 0; i < n; i++)
    if (isfinite (v[i]))
      f[m++] = v[i];
  if (m == 0 || m < min_count)
    return NAN;
  qsort (f, m, sizeof (double), compare_double);
  double at = CLAMP (q, 0.0, 1.0) * (double) (m - 1);
  gsize k = (gsize) floor (at);
  return k + 1 < m ? f[k] + (at - (double) k) * (f[k + 1] - f[k]) : f[k];
}
