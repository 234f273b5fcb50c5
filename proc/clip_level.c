/* Where a sensor's frames clip (clip_level.h). */
#include "proc/clip_level.h"

#include <math.h>

#include "proc/column_stats.h"
#include "proc/image_stats.h"

/* Below this a frame's noise does not spread its values over several codes. */
#define NOISE_MIN_DN 0.5

void
ds_clip_level_find (const DsImage *dark, const DsImage *const *lit, guint n_lit, double saturation, DsClipLevel *out)
{
  double clip = saturation > 0 ? saturation : INFINITY, dark_dn = ds_image_mean (dark);
  double dark_noise = ds_column_stats_noise_dn (dark, NULL, 0);
  gboolean dark_noisy = isfinite (dark_noise) && dark_noise >= NOISE_MIN_DN;
  out->piled = FALSE;
  for (guint i = 0; i < n_lit; i++) {
    const DsImage *f = lit[i];
    if (f->type == DS_SAMPLE_F32)
      continue;
    double top = ds_image_percentile (f, 100), near = ds_image_percentile (f, DS_CLIP_PILE_PERCENTILE);
    double noise = dark_noisy ? INFINITY : ds_column_stats_noise_dn (f, NULL, top);
    if (top > dark_dn && near >= top && top <= clip && noise >= NOISE_MIN_DN) {
      clip = top;
      out->piled = TRUE;
    }
  }
  out->level = isfinite (clip) ? clip : 0;
}

guint64
ds_clip_count (const DsImage *a, const DsImage *b, double level)
{
  guint64 n = 0;
  if (!(level > 0))
    return 0;
  for (guint y = 0; y < a->height; y++) {
    const void *ra = ds_image_row (a, y), *rb = b ? ds_image_row (b, y) : NULL;
    for (guint x = 0; x < a->width; x++)
      n += ds_image_sample (a, ra, x) >= level || (rb && ds_image_sample (b, rb, x) >= level);
  }
  return n;
}
