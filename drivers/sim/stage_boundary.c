/* Boundary stage (built when the medium's index differs from the outside): Fresnel
 * transmittance of the ballistic beam entering and leaving the slab at normal incidence
 * (telecentric illumination and lens). Scattered light's boundary losses are inside the
 * transport kernels. */
#include "drivers/sim/stage.h"

typedef struct {
  double t_in, t_out;
} BoundaryData;

double
ds_stage_boundary_normal_reflectance (double n1, double n2)
{
  double r = (n1 - n2) / (n1 + n2);
  return r * r;
}

static gboolean
boundary_apply (const DsStage *st, DsLight *l, const DsStageArgs *a, GError **error)
{
  (void) a;
  (void) error;
  const BoundaryData *d = st->data;
  float t = (float) (d->t_in * d->t_out);
  for (guint y = 0; y < l->direct->height; y++) {
    float *dr = ds_image_row (l->direct, y);
    for (guint x = 0; x < l->direct->width; x++)
      dr[x] *= t;
  }
  return TRUE;
}

DsStage *
ds_stage_boundary_new (double n_outside, double n_medium)
{
  BoundaryData *d = g_new0 (BoundaryData, 1);
  d->t_in = 1.0 - ds_stage_boundary_normal_reflectance (n_outside, n_medium);
  d->t_out = 1.0 - ds_stage_boundary_normal_reflectance (n_medium, n_outside);
  DsStage *st = g_new0 (DsStage, 1);
  st->kind = DS_RENDER_STAGE_BOUNDARY;
  st->reason = g_strdup_printf ("medium index %g against %g outside: Fresnel transmittance %.4f per face "
                                "at normal incidence", n_medium, n_outside, d->t_in);
  st->apply = boundary_apply;
  st->data = d;
  st->free_data = g_free;
  return st;
}
