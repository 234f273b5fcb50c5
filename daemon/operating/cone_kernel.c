#include "daemon/operating/cone_kernel.h"

#include <math.h>
#include <string.h>

/* integral_0^q J1 (t) / t dt by Simpson's rule (steps of at most 0.2, where J1 changes by under 2 %
 * of its range); for q beyond 200 the integral's asymptote, 1 - J0 (q) / q (by parts; the next
 * term is O (q^-5/2)). */
static double
j1_over_t_integral (double q)
{
  if (q > 200)
    return 1 - j0 (q) / q;
  guint steps = MAX (16u, 2 * (guint) ceil (q / 0.4));
  double h = q / steps, sum = 0.5 /* J1 (t) / t at 0 */;
  for (guint i = 1; i <= steps; i++) {
    double t = i * h, f = j1 (t) / t;
    sum += i == steps ? f : (i % 2 ? 4 : 2) * f;
  }
  return sum * h / 3;
}

double
ds_cone_kernel_mtf (double radius_px, double x_px)
{
  if (!(x_px > 0))
    return 0.0;
  double q = 2 * G_PI * MAX (radius_px, 0.0) / x_px;
  if (q < 1e-4)
    return 1 - q * q / 24;
  return 2 * j1_over_t_integral (q) / q;
}

#define MAX_EQ 32
#define R_MIN 0.05
#define R_MAX 200.0
#define R_STEP 1.04
#define S_MIN 1e-4
#define S_STEP 1.02

/* The weighted squared residuals at one point (the blur's error t solved for, its prior counted
 * in *objective, not in the return value). */
static double
residuals (const double *y, const double *w, const double *shift, const double *T, guint n, double ld, double total,
           double *t_out, double *objective)
{
  double r[MAX_EQ], num = 0, den = 1; /* 1: the unit normal prior on t */
  for (guint i = 0; i < n; i++) {
    r[i] = w[i] > 0 ? y[i] - log (ld + (total - ld) * T[i]) : 0;
    if (shift) {
      num += w[i] * shift[i] * r[i];
      den += w[i] * shift[i] * shift[i];
    }
  }
  double t = num / den, chi2 = 0;
  for (guint i = 0; i < n; i++) {
    double e = r[i] - (shift ? t * shift[i] : 0);
    chi2 += w[i] * e * e;
  }
  *t_out = t;
  *objective = chi2 + t * t;
  return chi2;
}

/* The grid point with the most direct light within DS_CONE_SEEN_CHI2 of the best (the least
 * objective among equal Ld), refitted for the blur's error: cone_kernel.h, open_above. */
static void
take_least_scattered (const double *y, const double *w, const double *shift, const double *x, guint n, double total,
                      double period_px, const double *objective, const double *ld_at, guint n_r, guint n_s, double best,
                      DsConeFit *out)
{
  gsize pick = G_MAXSIZE;
  for (gsize k = 0; k < (gsize) n_r * n_s; k++) {
    if (!(objective[k] <= best + DS_CONE_SEEN_CHI2))
      continue;
    if (pick == G_MAXSIZE || ld_at[k] > ld_at[pick] || (ld_at[k] == ld_at[pick] && objective[k] < objective[pick]))
      pick = k;
  }
  if (pick == G_MAXSIZE)
    return;
  double R = R_MIN * pow (R_STEP, (double) (pick / n_s)), T[MAX_EQ], t, obj;
  for (guint i = 0; i < n; i++)
    T[i] = w[i] > 0 ? ds_cone_kernel_mtf (R, x[i]) : 0;
  out->ld = ld_at[pick];
  out->radius_px = R;
  out->chi2 = residuals (y, w, shift, T, n, out->ld, total, &t, &obj);
  out->blur_t = t;
  out->leak = (total - out->ld) / out->ld * ds_cone_kernel_mtf (R, period_px);
}

gboolean
ds_cone_kernel_fit (const double *x, const double *y, const double *w, const double *shift, guint n, double total,
                    double period_px, DsConeFit *out)
{
  memset (out, 0, sizeof *out);
  guint used = 0;
  for (guint i = 0; i < MIN (n, (guint) MAX_EQ); i++)
    used += w[i] > 0 && x[i] > 0 && isfinite (y[i]);
  if (n > MAX_EQ || used < 2 || !(total > 0) || !(period_px > 0))
    return FALSE;
  double ww[MAX_EQ];
  for (guint i = 0; i < n; i++)
    ww[i] = w[i] > 0 && x[i] > 0 && isfinite (y[i]) ? w[i] : 0;

  /* The grid: R from a fraction of a pixel (the stripes kept at every period) to 200 px (lost at
   * every period the sensor resolves), the scattered share s = 1 - Ld / M from 0 to nearly all. */
  guint n_r = (guint) ceil (log (R_MAX / R_MIN) / log (R_STEP)) + 1;
  guint n_s = (guint) ceil (log (0.995 / S_MIN) / log (S_STEP)) + 2;
  g_autofree double *objective = g_new (double, (gsize) n_r * n_s);
  g_autofree double *leak_at = g_new (double, (gsize) n_r * n_s);
  g_autofree double *ld_at = g_new (double, (gsize) n_r * n_s);
  double best = INFINITY, all_scattered = INFINITY;
  out->objective_narrow = out->objective_wide = INFINITY;
  for (guint ir = 0; ir < n_r; ir++) {
    double R = R_MIN * pow (R_STEP, ir), T[MAX_EQ];
    for (guint i = 0; i < n; i++)
      T[i] = ww[i] > 0 ? ds_cone_kernel_mtf (R, x[i]) : 0;
    double t_p = ds_cone_kernel_mtf (R, period_px);
    for (guint is = 0; is < n_s; is++) {
      double s = is == 0 ? 0 : MIN (0.995, S_MIN * pow (S_STEP, is - 1)), ld = total * (1 - s), t, obj;
      double chi2 = residuals (y, ww, shift, T, n, ld, total, &t, &obj);
      gsize k = (gsize) ir * n_s + is;
      objective[k] = obj;
      ld_at[k] = ld;
      leak_at[k] = s / (1 - s) * t_p;
      if (ir == 0)
        out->objective_narrow = MIN (out->objective_narrow, obj);
      if (ir == n_r - 1)
        out->objective_wide = MIN (out->objective_wide, obj);
      if (is == n_s - 1)
        all_scattered = MIN (all_scattered, obj);
      if (obj < best) {
        best = obj;
        out->ld = ld;
        out->radius_px = R;
        out->blur_t = t;
        out->chi2 = chi2;
        out->leak = leak_at[k];
      }
    }
  }
  if (!isfinite (best))
    return FALSE;
  out->ld_low = out->ld_high = out->ld;
  out->leak_low = out->leak_high = out->leak;
  for (gsize k = 0; k < (gsize) n_r * n_s; k++) {
    if (!(objective[k] <= best + DS_CONE_CHI2_RANGE))
      continue;
    out->ld_low = MIN (out->ld_low, ld_at[k]);
    out->ld_high = MAX (out->ld_high, ld_at[k]);
    out->leak_low = MIN (out->leak_low, leak_at[k]);
    out->leak_high = MAX (out->leak_high, leak_at[k]);
  }
  out->objective = best;
  out->seen = best + DS_CONE_SEEN_CHI2 <= MIN (out->objective_narrow, out->objective_wide);
  out->told = out->seen && out->leak > 0 && out->leak_low * DS_CONE_TOLD_FACTOR >= out->leak &&
              out->leak_high <= DS_CONE_TOLD_FACTOR * out->leak;
  out->open_above = all_scattered <= best + DS_CONE_SEEN_CHI2;
  if (out->open_above)
    take_least_scattered (y, ww, shift, x, n, total, period_px, objective, ld_at, n_r, n_s, best, out);
  out->ok = TRUE;
  return TRUE;
}
