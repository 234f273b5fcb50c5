#include "drivers/sim/henyey_greenstein.h"

#include <math.h>

/* Below this |g| the closed forms lose digits to cancellation; the isotropic limit is exact
 * to O(g) there, which is far below Monte Carlo noise. */
#define DS_HG_ISOTROPIC 1e-6

double
ds_hg_pdf (double g, double mu)
{
  return (1.0 - g * g) / (2.0 * pow (1.0 + g * g - 2.0 * g * mu, 1.5));
}

double
ds_hg_cdf (double g, double mu)
{
  mu = CLAMP (mu, -1.0, 1.0);
  if (fabs (g) < DS_HG_ISOTROPIC)
    return 0.5 * (mu + 1.0);
  /* Antiderivative (1 - g^2) / (2g sqrt(1 + g^2 - 2 g mu)), taken from mu = -1. */
  return (1.0 - g * g) / (2.0 * g) * (1.0 / sqrt (1.0 + g * g - 2.0 * g * mu) - 1.0 / (1.0 + g));
}

double
ds_hg_sample_cos (double g, double xi)
{
  if (fabs (g) < DS_HG_ISOTROPIC)
    return 2.0 * xi - 1.0;
  double t = (1.0 - g * g) / (1.0 - g + 2.0 * g * xi);
  return CLAMP ((1.0 + g * g - t * t) / (2.0 * g), -1.0, 1.0);
}

double
ds_hg_forward_fraction (double g)
{
  return 1.0 - ds_hg_cdf (g, 0.0);
}
