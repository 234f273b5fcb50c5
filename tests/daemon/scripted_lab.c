#include "scripted_lab.h"

gboolean
scripted_fault_now (guint *counter)
{
  if (*counter == 0)
    return FALSE;
  return --(*counter) == 0;
}

double
scripted_stripe_lit (guint x, int phase, guint n_phases)
{
  return stripe_scene_lit (x, phase, n_phases, SCRIPTED_PERIOD);
}

void
scripted_assert_scene_recovered (const DsResult *r)
{
  const DsSeparation *sep = ds_result_separation (r);
  for (guint y = 0; y < sep->transmissive->height; y++) {
    const float *t = ds_image_row (sep->transmissive, y);
    const float *g = ds_image_row (sep->scattered, y);
    for (guint x = 0; x < sep->transmissive->width; x++) {
      g_assert_cmpfloat_with_epsilon (t[x], STRIPE_SCENE_DIRECT_DN, 1e-3);
      g_assert_cmpfloat_with_epsilon (g[x], STRIPE_SCENE_SCATTERED_DN, 1e-3);
    }
  }
}

DsDevices *
scripted_devices_new (const DsCameraOps *camera, const DsIlluminatorOps *illuminator, gpointer backend,
                      const char *description)
{
  DsDevices *d = g_new0 (DsDevices, 1);
  d->camera = g_new0 (DsCamera, 1);
  d->camera->ops = camera;
  d->camera->backend = backend;
  d->illuminator = g_new0 (DsIlluminator, 1);
  d->illuminator->ops = illuminator;
  d->illuminator->backend = backend;
  d->trigger = ds_software_trigger_new (d->camera);
  d->pattern = (DsStripePattern) { .kind = DS_STRIPES_SQUARE, .period_px = SCRIPTED_PERIOD, .duty = 0.5,
                                   .black_level = 0, .intensity = 1, .n_phases = 8 };
  d->grab_timeout_ms = 100;
  d->settle_timeout_ms = 100;
  d->description = g_strdup (description);
  return d;
}
