#include "proc/preview.h"

#include <math.h>

#include "proc/proc_error.h"

static double
sample_at (const DsImage *img, guint x, guint y)
{
  const guint8 *row = ds_image_row (img, y);
  switch (img->type) {
  case DS_SAMPLE_U8:
    return row[x];
  case DS_SAMPLE_U16:
    return ((const guint16 *) row)[x];
  default:
    return ((const float *) row)[x];
  }
}

static int
compare_float (const void *a, const void *b)
{
  float fa = *(const float *) a, fb = *(const float *) b;
  return (fa > fb) - (fa < fb);
}

DsImage *
ds_preview_u8 (const DsImage *img, double lo_p, double hi_p, GError **error)
{
  if (!(lo_p >= 0 && hi_p <= 100 && lo_p < hi_p)) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_INVALID_ARGUMENT,
                 "preview: percentiles %g..%g must satisfy 0 <= lo < hi <= 100", lo_p, hi_p);
    return NULL;
  }
  /* Percentiles from a strided sample: a preview does not need every pixel. */
  gsize n_px = (gsize) img->width * img->height;
  guint step = n_px > 1000000 ? (guint) (n_px / 1000000) : 1;
  GArray *vals = g_array_sized_new (FALSE, FALSE, sizeof (float), (guint) (n_px / step + 1));
  gsize i = 0;
  for (guint y = 0; y < img->height; y++)
    for (guint x = 0; x < img->width; x++, i++)
      if (i % step == 0) {
        float v = (float) sample_at (img, x, y);
        if (isfinite (v))
          g_array_append_val (vals, v);
      }
  double lo = 0, hi = 0;
  if (vals->len) {
    qsort (vals->data, vals->len, sizeof (float), compare_float);
    lo = g_array_index (vals, float, (guint) (lo_p / 100.0 * (vals->len - 1)));
    hi = g_array_index (vals, float, (guint) (hi_p / 100.0 * (vals->len - 1)));
  }
  g_array_unref (vals);
  DsImage *out = ds_image_new (DS_SAMPLE_U8, img->width, img->height, error);
  if (!out)
    return NULL;
  for (guint y = 0; y < img->height; y++) {
    guint8 *o = ds_image_row (out, y);
    for (guint x = 0; x < img->width; x++) {
      double v = sample_at (img, x, y);
      if (!isfinite (v))
        o[x] = 0;
      else if (hi <= lo)
        o[x] = 128;
      else {
        double t = (v - lo) / (hi - lo) * 255.0;
        o[x] = (guint8) (t < 0 ? 0 : t > 255 ? 255 : t + 0.5);
      }
    }
  }
  return out;
}
