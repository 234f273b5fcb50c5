#include "daemon/operating/scene_probe_wide.h"

#include <math.h>
#include <string.h>

#include "daemon/operating/cone_kernel.h"

double
ds_probe_wide_rise_ratio (double x_lo, double p, double x_c)
{
  if (!(x_lo > 0 && p > x_lo && x_c > p))
    return 0;
  double best = (x_c - p) / (p - x_lo); /* the line's, and the cone's at periods short against R */
  for (double r = 0.02 * p; r <= 50 * p; r *= 1.02) {
    double lo = ds_cone_kernel_mtf (r, x_lo), mid = ds_cone_kernel_mtf (r, p), hi = ds_cone_kernel_mtf (r, x_c);
    if (mid - lo > 1e-9)
      best = MAX (best, (hi - mid) / (mid - lo));
  }
  return best;
}

guint
ds_probe_drop_wide_rise (const DsStripeModel *g, DsProbeEquation *eq, guint n_eq, double sigma, guint width,
                         double period, DsProbeWideRise *out)
{
  memset (out, 0, sizeof *out);
  double u[DS_PROBE_MAX_EQUATIONS], var[DS_PROBE_MAX_EQUATIONS], x[DS_PROBE_MAX_EQUATIONS];
  double s0 = 0, s1 = 0, s2 = 0, su = 0, sdu = 0, x_lo = INFINITY, q_lo = INFINITY, q_hi = 0;
  guint near = 0, far = 0;
  for (guint i = 0; i < n_eq && i < DS_PROBE_MAX_EQUATIONS; i++) {
    x[i] = eq[i].period / eq[i].n;
    double G = ds_probe_model_gain (g, eq[i].period, sigma, eq[i].offset, width, eq[i].n);
    double rel = eq[i].sigma / eq[i].amplitude;
    u[i] = G > 0 ? eq[i].amplitude / G : 0;
    /* The fit's weights (scene_probe_transfer.c): the harmonic's noise and the 2 % floor. */
    var[i] = G > 0 ? u[i] * u[i] * (rel * rel + 0.02 * 0.02) : 0;
    if (!(var[i] > 0))
      continue;
    if (x[i] > period * 1.001) {
      far++;
      continue;
    }
    double w = 1 / var[i], d = x[i] - period;
    s0 += w, s1 += w * d, s2 += w * d * d, su += w * u[i], sdu += w * d * u[i];
    x_lo = MIN (x_lo, x[i]);
    q_lo = MIN (q_lo, eq[i].period);
    q_hi = MAX (q_hi, eq[i].period);
    near++;
  }
  double det = s0 * s2 - s1 * s1;
  /* Two periods at and below P (alone, the slope and the blur's error are one), over a range of x. */
  if (far == 0 || near < 2 || !(q_hi > 1.01 * q_lo) || !(x_lo < period / 1.5) || !(det > 0))
    return n_eq;
  /* The weighted line u = a + b (x - P) through the harmonics at and below P. */
  double a = (s2 * su - s1 * sdu) / det, b = (s0 * sdu - s1 * su) / det;
  double var_a = s2 / det, var_b = s0 / det, cov = -s1 / det;
  if (!(a > 0) || !(fabs (b) <= DS_PROBE_WIDE_FLAT_Z * sqrt (var_b)))
    return n_eq;
  guint k = 0;
  for (guint i = 0; i < n_eq; i++) {
    gboolean drop = FALSE;
    if (i < DS_PROBE_MAX_EQUATIONS && var[i] > 0 && x[i] > period * 1.001) {
      double c = ds_probe_wide_rise_ratio (x_lo, period, x[i]) * (period - x_lo);
      double allowed = a + c * MAX (b, 0.0);
      double v = var[i] + var_a + (b > 0 ? c * c * var_b + 2 * c * cov : 0);
      double z = (u[i] - allowed) / sqrt (v);
      if (z > DS_PROBE_WIDE_RISE_Z) {
        drop = TRUE;
        out->dropped++;
        if (x[i] > out->coarse_x) {
          out->coarse_x = x[i];
          out->level = a;
          out->rise = u[i] / a - 1;
          out->allowed = allowed / a - 1;
          out->z = z;
        }
      }
    }
    if (!drop)
      eq[k++] = eq[i];
  }
  out->left_out = out->dropped > 0;
  if (out->left_out)
    g_snprintf (out->note, sizeof out->note,
                "; at %g px the stripes keep %.1f %% more than at and below %g px, where they are flat and allow %.1f %% "
                "(%.1f sigma): scattered light wide against %g px, left out of the fit",
                out->coarse_x, 100 * out->rise, period, 100 * out->allowed, out->z, period);
  return k;
}
