#include "drivers/sim/fresnel.h"

#include <math.h>

double
ds_fresnel_cos_transmitted (double n1, double n2, double cos_theta_i)
{
  double c = fabs (cos_theta_i);
  double sin_t = n1 / n2 * sqrt (MAX (0.0, 1.0 - c * c));
  if (sin_t >= 1.0)
    return 0.0;
  return sqrt (1.0 - sin_t * sin_t);
}

void
ds_fresnel_reflectance_sp (double n1, double n2, double cos_theta_i, double *rs, double *rp)
{
  double ci = MIN (fabs (cos_theta_i), 1.0);
  if (n1 == n2) {
    *rs = *rp = 0.0;
    return;
  }
  double sin_t = n1 / n2 * sqrt (MAX (0.0, 1.0 - ci * ci));
  if (sin_t >= 1.0) {
    *rs = *rp = 1.0;
    return;
  }
  double ct = sqrt (1.0 - sin_t * sin_t);
  double s = (n1 * ci - n2 * ct) / (n1 * ci + n2 * ct);
  double p = (n1 * ct - n2 * ci) / (n1 * ct + n2 * ci);
  *rs = s * s;
  *rp = p * p;
}

double
ds_fresnel_reflectance (double n1, double n2, double cos_theta_i)
{
  double rs, rp;
  ds_fresnel_reflectance_sp (n1, n2, cos_theta_i, &rs, &rp);
  return 0.5 * (rs + rp);
}

double
ds_fresnel_diffuse_reflectance (double n1, double n2)
{
  /* Midpoint rule in mu; R has a kink at the critical angle, so many points (cheap). */
  const int n = 20000;
  double sum = 0.0;
  for (int i = 0; i < n; i++) {
    double mu = (i + 0.5) / n;
    sum += 2.0 * mu * ds_fresnel_reflectance (n1, n2, mu);
  }
  return sum / n;
}
