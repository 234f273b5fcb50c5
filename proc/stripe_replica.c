/* A replica of a pilot pair (stripe_replica.h). */
#include "proc/stripe_replica.h"

#include <math.h>

double
ds_stripe_replica_normal (GRand *rng)
{
  double u = g_rand_double_range (rng, 1e-12, 1), v = g_rand_double (rng);
  return sqrt (-2 * log (u)) * cos (2 * G_PI * v);
}

static gboolean
float_like (const DsImage *f, const DsImage *ref)
{
  return f->type == DS_SAMPLE_F32 && f->width == ref->width && f->height == ref->height;
}

gboolean
ds_stripe_replica_render (const double *phase0, const double *phase1, double noise_dn, GRand *rng, DsImage *dark,
                          DsImage *l0, DsImage *l1)
{
  if (!float_like (dark, l0) || !float_like (l0, l0) || !float_like (l1, l0))
    return FALSE;
  guint w = l0->width;
  for (guint y = 0; y < l0->height; y++) {
    float *rd = ds_image_row (dark, y), *r0 = ds_image_row (l0, y), *r1 = ds_image_row (l1, y);
    for (guint x = 0; x < w; x++) {
      rd[x] = (float) (noise_dn * ds_stripe_replica_normal (rng));
      r0[x] = (float) (phase0[x] + noise_dn * ds_stripe_replica_normal (rng));
      r1[x] = (float) (phase1[x] + noise_dn * ds_stripe_replica_normal (rng));
    }
  }
  return TRUE;
}

double
ds_stripe_profile_lit_mean (const DsStripeProfile *profile, guint64 *n_lit)
{
  double level = 0;
  guint64 n = 0;
  for (gsize i = 0; i < (gsize) profile->width * profile->height; i++)
    if (profile->sum[i] > profile->threshold) {
      level += profile->sum[i];
      n++;
    }
  if (n_lit)
    *n_lit = n;
  return n ? level / (double) n : 0;
}
