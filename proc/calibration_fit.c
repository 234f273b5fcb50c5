/* The calibrator's models of the period profile (calibration_fit.h). */
#include <math.h>
#include <string.h>

#include "proc/calibration_fit.h"
#include "proc/separation_internal.h"
#include "proc/stripe_phase.h"

#define N_BINS DS_CALIBRATION_BINS
typedef DsCalibrationFit FitData;

/* Sum of squared differences between the binned profile and the model at (a, b, sigma). */
static double
fit_cost (const FitData *f, const double x[3])
{
  DsSeparationParams p = f->p;
  p.duty = x[0];
  p.black_level = x[1];
  p.geometry.edge_blur_px = x[2];
  if (!(x[0] > 0.02 && x[0] < 0.98 && x[1] >= 0 && x[1] < 0.95 && x[2] >= 0 && x[2] < p.geometry.period_px))
    return INFINITY;
  double period = p.geometry.period_px, cost = 0, b = x[1];
  g_autofree double *model = g_new (double, f->n);
  for (guint j = 0; j < N_BINS; j++) {
    if (!f->filled[j])
      continue;
    double pos = f->position[j], mean = 0;
    for (guint k = 0; k < f->n; k++) {
      /* distance of the bin's pixels from the centre of phase k's stripe */
      double d = ds_stripe_phase_diff (pos, (double) k / f->n + f->offset) * period;
      model[k] = b + (1 - b) * ds_sampling_profile (&p, d);
      mean += model[k] / f->n;
    }
    for (guint k = 0; k < f->n; k++) {
      double r = f->profile[j * f->n + k] - model[k] / mean;
      cost += r * r;
    }
  }
  return cost;
}

/* Nelder-Mead over (a, b, sigma) from x; fixed[i] keeps coordinate i. */
static void
fit_minimise (const FitData *f, double x[3], const gboolean fixed[3])
{
  double simplex[4][3], cost[4];
  const double step[3] = { 0.05, 0.03, 0.3 };
  for (int v = 0; v < 4; v++) {
    for (int i = 0; i < 3; i++)
      simplex[v][i] = x[i] + (v == i + 1 && !fixed[i] ? step[i] : 0);
    cost[v] = fit_cost (f, simplex[v]);
  }
  for (int it = 0; it < 400; it++) {
    int hi = 0, lo = 0;
    for (int v = 1; v < 4; v++) {
      if (cost[v] > cost[hi])
        hi = v;
      if (cost[v] < cost[lo])
        lo = v;
    }
    int second = lo;
    for (int v = 0; v < 4; v++)
      if (v != hi && cost[v] > cost[second])
        second = v;
    if (cost[hi] - cost[lo] < 1e-14 * (1 + cost[lo]))
      break;
    double centre[3] = { 0, 0, 0 }, trial[3], expand[3];
    for (int v = 0; v < 4; v++)
      if (v != hi)
        for (int i = 0; i < 3; i++)
          centre[i] += simplex[v][i] / 3;
    for (int i = 0; i < 3; i++)
      trial[i] = fixed[i] ? x[i] : centre[i] + (centre[i] - simplex[hi][i]);
    double ct = fit_cost (f, trial);
    if (ct < cost[lo]) {
      for (int i = 0; i < 3; i++)
        expand[i] = fixed[i] ? x[i] : centre[i] + 2 * (centre[i] - simplex[hi][i]);
      double ce = fit_cost (f, expand);
      memcpy (simplex[hi], ce < ct ? expand : trial, sizeof trial);
      cost[hi] = MIN (ce, ct);
    } else if (ct < cost[second]) {
      memcpy (simplex[hi], trial, sizeof trial);
      cost[hi] = ct;
    } else {
      for (int i = 0; i < 3; i++)
        trial[i] = fixed[i] ? x[i] : centre[i] + 0.5 * (simplex[hi][i] - centre[i]);
      ct = fit_cost (f, trial);
      if (ct < cost[hi]) {
        memcpy (simplex[hi], trial, sizeof trial);
        cost[hi] = ct;
      } else {
        for (int v = 0; v < 4; v++)
          if (v != lo) {
            for (int i = 0; i < 3; i++)
              simplex[v][i] = fixed[i] ? x[i] : 0.5 * (simplex[v][i] + simplex[lo][i]);
            cost[v] = fit_cost (f, simplex[v]);
          }
      }
    }
  }
  int lo = 0;
  for (int v = 1; v < 4; v++)
    if (cost[v] < cost[lo])
      lo = v;
  memcpy (x, simplex[lo], 3 * sizeof (double));
}

void
ds_calibration_fit_residual (const FitData *f, const double x[3], double *residual, double *noise)
{
  double lo = INFINITY, hi = -INFINITY, se2 = 0;
  guint entries = 0;
  *residual = *noise = 0;
  for (guint j = 0; j < N_BINS; j++) {
    if (!f->filled[j])
      continue;
    for (guint k = 0; k < f->n; k++) {
      double m = f->profile[j * f->n + k];
      lo = MIN (lo, m);
      hi = MAX (hi, m);
      se2 += MAX (0.0, f->profile_sq[j * f->n + k] - m * m) / f->filled[j];
      entries++;
    }
  }
  if (!entries || !(hi > lo))
    return;
  *residual = sqrt (fit_cost (f, x) / entries) / (hi - lo);
  *noise = sqrt (se2 / entries) / (hi - lo);
}

double
ds_calibration_fit_sine_residual (const FitData *f)
{
  double num = 0, den = 0, lo = INFINITY, hi = -INFINITY, ss = 0;
  guint entries = 0;
  for (int pass = 0; pass < 2; pass++)
    for (guint j = 0; j < N_BINS; j++) {
      if (!f->filled[j])
        continue;
      for (guint k = 0; k < f->n; k++) {
        double u = ds_stripe_phase_diff (f->position[j], (double) k / f->n + f->offset);
        double cs = cos (2 * G_PI * u), m = f->profile[j * f->n + k] - 1;
        if (pass == 0) {
          num += m * cs;
          den += cs * cs;
          lo = MIN (lo, m);
          hi = MAX (hi, m);
          entries++;
        } else {
          double r = m - num / den * cs;
          ss += r * r;
        }
      }
    }
  return entries && den > 0 && hi > lo ? sqrt (ss / entries) / (hi - lo) : 0;
}

void
ds_calibration_fit_square (FitData *f, double a0, double b0, double x[3])
{
  f->p.pattern = DS_PATTERN_SQUARE;
  const gboolean fixed[3] = { FALSE, FALSE, FALSE };
  x[0] = a0;
  x[1] = b0;
  x[2] = 0.1;
  fit_minimise (f, x, fixed);
}
