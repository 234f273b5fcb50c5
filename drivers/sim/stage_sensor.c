/* Sensor stage (always built: a scene declares its sensor): EMVA 1288 model (sensor.c). */
#include "drivers/sim/stage.h"

static gboolean
sensor_apply (const DsStage *st, DsLight *l, const DsStageArgs *a, GError **error)
{
  const DsSensorModel *m = st->data;
  guint w = l->direct->width, h = l->direct->height;
  /* Photons at the pixel: direct + scattered + ambient (uniform), kept in l->direct. */
  ds_stage_sensor_photons (l);
  if (a->expected) {
    l->frame = ds_image_new (DS_SAMPLE_F32, w, h, error);
    if (!l->frame)
      return FALSE;
    for (guint y = 0; y < h; y++) {
      const float *p = ds_image_row (l->direct, y);
      float *o = ds_image_row (l->frame, y);
      for (guint x = 0; x < w; x++)
        o[x] = (float) ds_sensor_mean_dn (m, p[x], a->exposure_us, a->gain_db);
    }
    return TRUE;
  }
  l->frame = ds_image_new (DS_SAMPLE_U16, w, h, error);
  return l->frame && ds_sensor_expose (m, l->direct, 0.0, a->exposure_us, a->gain_db, a->seed, l->frame, error);
}

void
ds_stage_sensor_photons (DsLight *l)
{
  for (guint y = 0; y < l->direct->height; y++) {
    float *dr = ds_image_row (l->direct, y);
    const float *sc = ds_image_row (l->scattered, y);
    for (guint x = 0; x < l->direct->width; x++)
      dr[x] = (float) ((double) (dr[x] + sc[x]) + l->ambient);
  }
  l->ambient = 0;
}

DsStage *
ds_stage_sensor_new (const DsSensorModel *m)
{
  DsSensorModel *d = g_memdup2 (m, sizeof *m);
  DsStage *st = g_new0 (DsStage, 1);
  st->kind = DS_RENDER_STAGE_SENSOR;
  st->reason = g_strdup_printf ("[sensor]: %u bit, QE %g, K %g DN/e-, read noise %g e-, dark %g e-/s, full well %g e-",
                                m->bit_depth, m->quantum_efficiency, m->system_gain, m->read_noise_e,
                                m->dark_current_e_s, m->full_well_e);
  st->apply = sensor_apply;
  st->data = d;
  st->free_data = g_free;
  return st;
}
