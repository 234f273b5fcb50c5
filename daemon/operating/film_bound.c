#include "daemon/operating/film_bound.h"

#include <math.h>

#include "daemon/operating/scene_probe_loss.h"

double
ds_film_cone_fraction (double g, double theta_rad)
{
  double c = cos (theta_rad);
  /* Below this g the closed form loses its digits to cancellation; the isotropic share differs
   * from it by O(g) (1 - c^2) / 4 there. */
  if (fabs (g) < 1e-6)
    return (1 - c) / 2;
  return (1 + g) / (2 * g) - (1 - g * g) / (2 * g) / sqrt (1 + g * g - 2 * g * c);
}

double
ds_film_inner_cone (double cone_half_angle_deg, double n)
{
  return asin (MIN (1.0, sin (cone_half_angle_deg * G_PI / 180) / n));
}

double
ds_film_bias_upper (double transmittance_low, double cone_half_angle_deg)
{
  double f = ds_film_cone_fraction (DS_FILM_MAX_G, ds_film_inner_cone (cone_half_angle_deg, DS_FILM_MIN_INDEX));
  double t = MIN (1.0, MAX (0.0, transmittance_low) / ds_probe_fresnel_transmittance (DS_FILM_MIN_INDEX));
  double s_in = f * (1 - t) / (1 - f);
  double d = t - s_in;
  return d > 0 ? s_in / d : INFINITY;
}
