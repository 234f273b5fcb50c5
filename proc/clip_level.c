/* Where a sensor's frames clip (clip_level.h). */
#include "proc/clip_level.h"

#include <math.h>

#include "proc/column_stats.h"
#include "proc/image_stats.h"

/* Below this a frame's noise does not spread its values over several codes. */
#define NOISE_MIN_DN 0.5

gboolean
ds_clip_level_pile_top (const DsImage *f, double pile_percentile, gboolean need_own_noise, double *top)
{
  if (f->type == DS_SAMPLE_F32)
    return FALSE;
  *top = ds_image_percentile (f, 100);
  double near = ds_image_percentile (f, pile_percentile);
  return near >= *top && (!need_own_noise || ds_column_stats_noise_dn (f, NULL, *top) >= NOISE_MIN_DN);
}

void
ds_clip_level_find (const DsImage *dark, const DsImage *const *lit, guint n_lit, double saturation, DsClipLevel *out)
{
  double clip = saturation > 0 ? saturation : INFINITY, dark_dn = ds_image_mean (dark);
  double dark_noise = ds_column_stats_noise_dn (dark, NULL, 0);
  gboolean dark_noisy = isfinite (dark_noise) && dark_noise >= NOISE_MIN_DN;
  out->piled = FALSE;
  for (guint i = 0; i < n_lit; i++) {
    double top;
    if (ds_clip_level_pile_top (lit[i], DS_CLIP_PILE_PERCENTILE, !dark_noisy, &top) && top > dark_dn && top <= clip) {
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
