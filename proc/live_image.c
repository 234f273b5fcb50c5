#include "proc/live_image.h"

#include <math.h>

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
