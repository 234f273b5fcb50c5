/* Ambient stage (built when the scene has an [ambient] group): room light reaching the lens
 * whatever the illuminator does, so it is in every frame, the black frame included. */
#include "drivers/sim/stage.h"

typedef struct {
  double photons_per_px_per_ms;
} AmbientData;

static gboolean
ambient_apply (const DsStage *st, DsLight *l, const DsStageArgs *a, GError **error)
{
  (void) error;
  const AmbientData *d = st->data;
  l->ambient += d->photons_per_px_per_ms * a->exposure_us / 1000.0;
  return TRUE;
}

DsStage *
ds_stage_ambient_new (double photons_per_px_per_ms)
{
  AmbientData *d = g_new0 (AmbientData, 1);
  d->photons_per_px_per_ms = photons_per_px_per_ms;
  DsStage *st = g_new0 (DsStage, 1);
  st->kind = DS_RENDER_STAGE_AMBIENT;
  st->reason = g_strdup_printf ("[ambient] declared: %.4g photons/px/ms in every frame, pattern-independent",
                                photons_per_px_per_ms);
  st->apply = ambient_apply;
  st->data = d;
  st->free_data = g_free;
  return st;
}
