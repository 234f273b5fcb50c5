/* Motion: the per-set constants of the MOTION mask bit (docs/estimators.md, "MOTION").
 *
 * A still scene under phase k shows x_k = G + D f_k + noise at a pixel: G the light that does
 * not follow the stripes, D the direct light's modulation, f_k the pattern's lit fraction at
 * the pixel in phase k. By Parseval over the N-point DFT of the samples,
 *   sum x_k^2 = N mean^2 + (2/N) (C^2 + S^2) + E,
 * C, S the first harmonic's cosine and sine sums and E the energy in every other bin (the
 * Nyquist bin included when N is even: N - 3 dimensions for N >= 4). A still scene puts in E
 * only the pattern's own higher harmonics, D^2 times the pattern's E, and noise. The pattern's
 * E is bounded by kappa times its first-harmonic energy (kappa: ds_motion_pattern_ratio, the
 * largest over pixel positions), and the noise's E is at most sigma^2 chi^2 with N - 3 degrees
 * of freedom (sigma^2 the largest sample variance: a projection of noise of covariance at most
 * sigma^2 I onto N - 3 dimensions). By the triangle inequality on the residual vector,
 *   E > (sqrt (kappa H1) + sigma sqrt (q))^2,  q the chi-square quantile at 1e-3,
 * happens on a still scene with probability at most 1e-3: that is the bit. Motion puts energy
 * in the other bins (a step in time spreads over every frequency); what a step puts in the
 * first harmonic only raises the allowance. */
#include <math.h>

#include "proc/separation_internal.h"

/* P(chi-square of nu degrees of freedom > x), x > 0: the closed forms of the incomplete
 * gamma function for integer and half-integer shape, summed in logarithms (no overflow for
 * large nu). */
static double
chi2_upper_tail (guint nu, double x)
{
  double h = 0.5 * x, lh = log (h), q = 0;
  if (nu % 2 == 0) {
    double lt = -h; /* log of h^j / j! e^-h, j = 0 */
    for (guint j = 0; j < nu / 2; j++) {
      if (j > 0)
        lt += lh - log ((double) j);
      q += exp (lt);
    }
  } else {
    q = erfc (sqrt (h));
    double lt = 0.5 * lh - h - lgamma (1.5); /* j = 1: h^(1/2) / Gamma(3/2) e^-h */
    for (guint j = 1; j <= (nu - 1) / 2; j++) {
      if (j > 1)
        lt += lh - log (j - 0.5);
      q += exp (lt);
    }
  }
  return q;
}

double
ds_chi2_upper_quantile (guint nu, double p)
{
  g_return_val_if_fail (nu >= 1 && p > 0 && p < 1, NAN);
  double lo = 0, hi = nu + 20.0 * sqrt (2.0 * nu) + 60.0;
  while (chi2_upper_tail (nu, hi) > p)
    hi *= 2;
  for (int i = 0; i < 200 && hi - lo > 1e-12 * hi; i++) {
    double mid = 0.5 * (lo + hi);
    if (chi2_upper_tail (nu, mid) > p)
      lo = mid;
    else
      hi = mid;
  }
  return 0.5 * (lo + hi);
}

/* E / H1 of the pattern samples f (n of them); 0 when the pattern has no first harmonic (a
 * pixel never lit or always lit carries no stripes to mistake for motion). */
static double
residual_ratio (const double *f, guint n)
{
  double s = 0, s2 = 0, c = 0, sn = 0;
  for (guint k = 0; k < n; k++) {
    double t = 2 * G_PI * k / n;
    s += f[k];
    s2 += f[k] * f[k];
    c += f[k] * cos (t);
    sn += f[k] * sin (t);
  }
  double h1 = 2.0 / n * (c * c + sn * sn);
  double e = s2 - s * s / n - h1;
  return h1 > 1e-9 * n ? MAX (e, 0.0) / h1 : 0.0;
}

/* Pixel positions across one phase step: shifting a pixel by a step permutes its samples. */
#define MOTION_POSITIONS 64u
/* Above this N the sharp point-sampled bound is used (the geometric one would cost N x
 * positions profile evaluations per set's parameters). */
#define MOTION_GEOMETRY_MAX_N 512u

static double
geometry_ratio (const DsSeparationParams *p)
{
  guint n = p->n_phases;
  double period = p->geometry.period_px, worst = 0;
  g_autofree double *f = g_new (double, n);
  for (guint i = 0; i < MOTION_POSITIONS; i++) {
    double u = (i + 0.5) / (MOTION_POSITIONS * (double) n);
    for (guint k = 0; k < n; k++)
      f[k] = ds_sampling_profile (p, (u - (double) k / n) * period);
    worst = MAX (worst, residual_ratio (f, n));
  }
  return worst;
}

double
ds_motion_pattern_ratio (const DsSeparationParams *p)
{
  guint n = p->n_phases;
  /* Sine stripes have no higher harmonic, whatever blur and aperture do to their amplitude. */
  if (p->pattern == DS_PATTERN_SINE || n < 4)
    return 0;
  if (p->geometry.period_px > 0 && n <= MOTION_GEOMETRY_MAX_N) {
    double r = geometry_ratio (p);
    if (!p->geometry.edge_blur_known && p->geometry.edge_blur_px > 0) {
      /* an unknown blur may be anything down to sharp edges, whose harmonics are strongest */
      DsSeparationParams sharp = *p;
      sharp.geometry.edge_blur_px = 0;
      r = MAX (r, geometry_ratio (&sharp));
    }
    return r;
  }
  /* Without a period: sharp stripes sampled at points, L = floor (aN) or ceil (aN) of the N
   * samples lit; their first harmonic is (2/N) sin^2 (pi L/N) / sin^2 (pi/N) and all of their
   * variance L (N - L) / N beyond it is the residual. */
  double worst = 0, an = p->duty * n;
  for (double l = floor (an); l <= ceil (an); l++) {
    if (l < 1 || l > n - 1)
      continue;
    double s1 = sin (G_PI * l / n) / sin (G_PI / n);
    double h1 = 2.0 / n * s1 * s1;
    worst = MAX (worst, (l * (n - l) / n - h1) / h1);
  }
  return worst;
}
