/* Each pixel's lit level from a pair of opposite phases (lit_level.h). */
#include "proc/lit_level.h"

#include <math.h>

gsize
ds_lit_level_samples (const DsImage *l0, const DsImage *l1, const DsImage *dark, const double *expected,
                      double clip, guint row_step, double *levels, double *expected_mean)
{
  guint w = l0->width;
  double mean = 0;
  for (guint x = 0; x < w; x++)
    mean += expected[x] / w;
  double used = 0, cols = 0;
  for (guint x = 0; x < w; x++)
    if (expected[x] >= 0.5 * mean) {
      used += expected[x];
      cols++;
    }
  if (expected_mean)
    *expected_mean = cols > 0 ? used / cols : 0;
  if (!(clip > 0))
    clip = INFINITY;
  gsize n = 0;
  for (guint y = 0; y < l0->height; y += MAX (1u, row_step)) {
    const void *ra = ds_image_row (l0, y), *rb = ds_image_row (l1, y), *rd = ds_image_row (dark, y);
    for (guint x = 0; x < w; x++) {
      if (!(expected[x] >= 0.5 * mean))
        continue;
      double va = ds_image_sample (l0, ra, x), vb = ds_image_sample (l1, rb, x);
      if (va >= clip || vb >= clip || !isfinite (va) || !isfinite (vb))
        continue;
      levels[n++] = (va + vb - 2 * ds_image_sample (dark, rd, x)) / expected[x];
    }
  }
  return n;
}
