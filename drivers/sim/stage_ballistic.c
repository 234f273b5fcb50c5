/* Ballistic attenuation stage (built when the medium has sigma_t > 0): Beer-Lambert,
 * the unscattered fraction exp(-sigma_t d) of a normally incident beam. */
#include <math.h>

#include "drivers/sim/stage.h"

typedef struct {
  double attenuation;
} BallisticData;

static gboolean
ballistic_apply (const DsStage *st, DsLight *l, const DsStageArgs *a, GError **error)
{
  (void) a;
  (void) error;
  const BallisticData *d = st->data;
  float t = (float) d->attenuation;
  for (guint y = 0; y < l->direct->height; y++) {
    float *dr = ds_image_row (l->direct, y);
    for (guint x = 0; x < l->direct->width; x++)
      dr[x] *= t;
  }
  return TRUE;
}

DsStage *
ds_stage_ballistic_new (double sigma_t, double thickness_mm)
{
  BallisticData *d = g_new0 (BallisticData, 1);
  d->attenuation = exp (-sigma_t * thickness_mm);
  DsStage *st = g_new0 (DsStage, 1);
  st->kind = DS_RENDER_STAGE_BALLISTIC;
  st->reason = g_strdup_printf ("medium sigma_t = %g /mm over %g mm: exp(-sigma_t d) = %.4g", sigma_t,
                                thickness_mm, d->attenuation);
  st->apply = ballistic_apply;
  st->data = d;
  st->free_data = g_free;
  return st;
}
