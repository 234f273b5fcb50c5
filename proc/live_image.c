#include "proc/live_image.h"

#include <math.h>
#include <stdlib.h>

static double
sample (const DsImage *img, guint x, guint y)
{
  const void *row = ds_image_row (img, y);
  return img->type == DS_SAMPLE_U8    ? ((const guint8 *) row)[x]
         : img->type == DS_SAMPLE_U16 ? ((const guint16 *) row)[x]
                                      : ((const float *) row)[x];
}

guint
ds_live_downscale_factor (guint width, guint height, guint max_side)
{
  guint side = MAX (width, height), m = MAX (max_side, 1u);
  return MAX (1u, (side + m - 1) / m);
}

DsImage *
ds_live_downscale_u8 (const DsImage *img, guint max_side, double lo, double hi, GError **error)
{
  guint f = ds_live_downscale_factor (img->width, img->height, max_side);
  guint w = (img->width + f - 1) / f, h = (img->height + f - 1) / f;
  DsImage *out = ds_image_new (DS_SAMPLE_U8, w, h, error);
  if (!out)
    return NULL;
  gboolean flags = isnan (lo) && isnan (hi);
  double span = hi - lo;
  for (guint by = 0; by < h; by++) {
    guint8 *o = ds_image_row (out, by);
    for (guint bx = 0; bx < w; bx++) {
      double sum = 0;
      guint n = 0, or = 0;
      for (guint y = by * f; y < MIN ((by + 1) * f, img->height); y++)
        for (guint x = bx * f; x < MIN ((bx + 1) * f, img->width); x++) {
          double v = sample (img, x, y);
          if (flags)
            or |= (guint) v;
          else if (isfinite (v)) {
            sum += v;
            n++;
          }
        }
      if (flags)
        o[bx] = (guint8) or;
      else if (!n || !(span > 0))
        o[bx] = n && span == 0 ? 128 : 0;
      else {
        double t = (sum / n - lo) / span * 255.0;
        o[bx] = (guint8) (t <= 0 ? 0 : t >= 255 ? 255 : t + 0.5);
      }
    }
  }
  return out;
}

void
ds_image_histogram (const DsImage *img, double top, guint n_bins, guint32 *bins, guint64 *at_or_above)
{
  for (guint i = 0; i < n_bins; i++)
    bins[i] = 0;
  guint64 above = 0;
  for (guint y = 0; y < img->height; y++)
    for (guint x = 0; x < img->width; x++) {
      double v = sample (img, x, y);
      if (!isfinite (v))
        continue;
      if (v >= top) {
        above++;
        bins[n_bins - 1]++;
        continue;
      }
      guint b = v <= 0 ? 0 : (guint) (v / top * n_bins);
      bins[MIN (b, n_bins - 1)]++;
    }
  if (at_or_above)
    *at_or_above = above;
}

DsImage *
ds_image_weighted_sum (const DsImage *a, double wa, const DsImage *b, double wb, GError **error)
{
  g_return_val_if_fail (a->type == DS_SAMPLE_F32 && ds_image_same_shape (a, b), NULL);
  DsImage *out = ds_image_new (DS_SAMPLE_F32, a->width, a->height, error);
  if (!out)
    return NULL;
  for (guint y = 0; y < a->height; y++) {
    const float *pa = ds_image_row (a, y), *pb = ds_image_row (b, y);
    float *o = ds_image_row (out, y);
    for (guint x = 0; x < a->width; x++)
      o[x] = (float) (pa[x] * wa + pb[x] * wb);
  }
  return out;
}

static int
compare_floats (const void *a, const void *b)
{
  float x = *(const float *) a, y = *(const float *) b;
  return (x > y) - (x < y);
}

/* Integer images: exact, from a histogram of every pixel (one pass, no sort). */
static void
levels_integer (const DsImage *img, double lo_p, double hi_p, double *lo, double *hi)
{
  guint n_values = img->type == DS_SAMPLE_U8 ? 256 : 65536;
  g_autofree guint32 *count = g_new0 (guint32, n_values);
  for (guint y = 0; y < img->height; y++) {
    const void *row = ds_image_row (img, y);
    if (img->type == DS_SAMPLE_U8)
      for (guint x = 0; x < img->width; x++)
        count[((const guint8 *) row)[x]]++;
    else
      for (guint x = 0; x < img->width; x++)
        count[((const guint16 *) row)[x]]++;
  }
  guint64 n = (guint64) img->width * img->height;
  guint64 want_lo = (guint64) (CLAMP (lo_p, 0, 100) / 100.0 * (double) (n - 1));
  guint64 want_hi = (guint64) (CLAMP (hi_p, 0, 100) / 100.0 * (double) (n - 1));
  guint64 seen = 0;
  *lo = *hi = NAN;
  for (guint v = 0; v < n_values; v++) {
    seen += count[v];
    if (isnan (*lo) && seen > want_lo)
      *lo = v;
    if (seen > want_hi) {
      *hi = v;
      return;
    }
  }
}

void
ds_image_levels (const DsImage *img, double lo_p, double hi_p, double *lo, double *hi)
{
  if (img->type != DS_SAMPLE_F32) {
    levels_integer (img, lo_p, hi_p, lo, hi);
    return;
  }
  gsize n_px = (gsize) img->width * img->height;
  gsize step = MAX ((gsize) 1, n_px / 16384);
  g_autofree float *v = g_new (float, n_px / step + 1);
  gsize n = 0;
  for (guint y = 0; y < img->height; y++) {
    const float *row = ds_image_row (img, y);
    gsize i0 = (gsize) y * img->width;
    /* The first x of this row on the sampling grid. */
    for (guint x = (guint) ((step - i0 % step) % step); x < img->width; x += (guint) step)
      if (isfinite (row[x]))
        v[n++] = row[x];
  }
  if (!n) {
    *lo = *hi = NAN;
    return;
  }
  qsort (v, n, sizeof *v, compare_floats);
  *lo = v[(gsize) (CLAMP (lo_p, 0, 100) / 100.0 * (double) (n - 1))];
  *hi = v[(gsize) (CLAMP (hi_p, 0, 100) / 100.0 * (double) (n - 1))];
}
