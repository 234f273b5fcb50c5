#include "proc/preview.h"

#include <math.h>

#include "proc/image_stats.h"
#include "proc/proc_error.h"

DsImage *
ds_preview_u8 (const DsImage *img, double lo_p, double hi_p, GError **error)
{
  if (!(lo_p >= 0 && hi_p <= 100 && lo_p < hi_p)) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_INVALID_ARGUMENT,
                 "preview: percentiles %g..%g must satisfy 0 <= lo < hi <= 100", lo_p, hi_p);
    return NULL;
  }
  /* Both percentiles come from a regular sample: a preview does not need every pixel. */
  double lo = ds_image_percentile (img, lo_p), hi = ds_image_percentile (img, hi_p);
  if (isnan (lo) || isnan (hi))
    lo = hi = 0;
  DsImage *out = ds_image_new (DS_SAMPLE_U8, img->width, img->height, error);
  if (!out)
    return NULL;
  for (guint y = 0; y < img->height; y++) {
    guint8 *o = ds_image_row (out, y);
    for (guint x = 0; x < img->width; x++) {
      const void *row = ds_image_row (img, y);
      double v = img->type == DS_SAMPLE_U8    ? ((const guint8 *) row)[x]
                 : img->type == DS_SAMPLE_U16 ? ((const guint16 *) row)[x]
                                              : ((const float *) row)[x];
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
