/* Phase order of a set from the stripes measured in its frames, and the stripe period
 * (phase_order.h). */
#include <math.h>

#include "proc/phase_order.h"
#include "proc/proc_error.h"
#include "proc/stripe_phase.h"

DsPhaseOrderVerdict
ds_phase_order_check (DsPhaseOrderFrame *fr, guint n, guint n_phases, double tol, gboolean offset_known,
                      double *offset)
{
  double step = 1.0 / n_phases;
  guint measured = 0;
  for (guint i = 0; i < n; i++) {
    fr[i].found = -1;
    fr[i].residual = NAN;
    measured += fr[i].measured;
  }
  if (measured == 0) {
    if (!offset_known)
      *offset = NAN;
    return DS_PHASE_ORDER_UNKNOWN;
  }
  if (!offset_known) {
    /* The candidate offset (one per measured frame) that most frames agree with; on a tie the
     * one they agree with most closely. Then the mean residual of those frames refines it. */
    guint best_count = 0;
    double best_spread = INFINITY, best = 0;
    for (guint i = 0; i < n; i++) {
      if (!fr[i].measured)
        continue;
      double cand = fr[i].phase - fr[i].given * step;
      guint count = 0;
      double spread = 0;
      for (guint j = 0; j < n; j++) {
        if (!fr[j].measured)
          continue;
        double r = ds_stripe_phase_diff (fr[j].phase - fr[j].given * step, cand);
        if (fabs (r) <= tol) {
          count++;
          spread += fabs (r);
        }
      }
      if (count > best_count || (count == best_count && spread < best_spread)) {
        best_count = count;
        best_spread = spread;
        best = cand;
      }
    }
    double sum = 0;
    guint used = 0;
    for (guint j = 0; j < n; j++)
      if (fr[j].measured) {
        double r = ds_stripe_phase_diff (fr[j].phase - fr[j].given * step, best);
        if (fabs (r) <= tol) {
          sum += r;
          used++;
        }
      }
    best += used ? sum / used : 0;
    *offset = best - floor (best);
  }
  gboolean between = FALSE, moved = FALSE;
  g_autofree guint *count = g_new0 (guint, n_phases);
  for (guint i = 0; i < n; i++) {
    guint effective = fr[i].given;
    if (fr[i].measured) {
      double x = ds_stripe_phase_diff (fr[i].phase, *offset); /* [-1/2, 1/2) cycles */
      double k = round (x / step);
      fr[i].residual = x - k * step;
      if (fabs (fr[i].residual) <= tol) {
        long kk = ((long) k % (long) n_phases + (long) n_phases) % (long) n_phases;
        fr[i].found = (int) kk;
        effective = (guint) kk;
      } else {
        between = TRUE;
      }
    }
    moved |= effective != fr[i].given;
    count[effective]++;
  }
  if (between)
    return DS_PHASE_ORDER_BROKEN;
  for (guint k = 0; k < n_phases; k++)
    if (count[k] == 0)
      return DS_PHASE_ORDER_BROKEN;
  return moved ? DS_PHASE_ORDER_REORDERED : DS_PHASE_ORDER_OK;
}

/* Mean of the finite samples of each column over all rows (of a - b when b is given). */
static double *
column_profile (const DsImage *a, const DsImage *b)
{
  guint w = a->width;
  double *p = g_new0 (double, w);
  g_autofree guint32 *count = g_new0 (guint32, w);
  for (guint y = 0; y < a->height; y++)
    for (guint x = 0; x < w; x++) {
      double v = 0;
      for (guint t = 0; t < (b ? 2u : 1u); t++) {
        const DsImage *img = t == 0 ? a : b;
        const void *row = ds_image_row (img, y);
        double s = img->type == DS_SAMPLE_U8    ? ((const guint8 *) row)[x]
                   : img->type == DS_SAMPLE_U16 ? ((const guint16 *) row)[x]
                                                : ((const float *) row)[x];
        v += t == 0 ? s : -s;
      }
      if (isfinite (v)) {
        p[x] += v;
        count[x]++;
      }
    }
  for (guint x = 0; x < w; x++)
    p[x] = count[x] ? p[x] / count[x] : NAN;
  return p;
}

/* Residual sum of squares of the least-squares fit of a mean and the first `harmonics`
 * harmonics of period P to the finite columns: smallest at the true period, whatever the
 * stripes' profile (square stripes have strong harmonics that a single sinusoid would leave in
 * the residual, pulling the period). */
static double
fit_residual (const double *p, guint w, double period, guint harmonics)
{
  enum { MAXP = 1 + 2 * 6 };
  guint np = 1 + 2 * harmonics;
  double a[MAXP][MAXP + 1] = { { 0 } };
  double basis[MAXP];
  double omega = 2 * G_PI / period, yy = 0;
  for (guint x = 0; x < w; x++) {
    if (!isfinite (p[x]))
      continue;
    basis[0] = 1;
    for (guint h = 1; h <= harmonics; h++) {
      basis[2 * h - 1] = cos (h * omega * x);
      basis[2 * h] = sin (h * omega * x);
    }
    for (guint i = 0; i < np; i++) {
      a[i][np] += basis[i] * p[x];
      for (guint j = 0; j < np; j++)
        a[i][j] += basis[i] * basis[j];
    }
    yy += p[x] * p[x];
  }
  /* Gaussian elimination with partial pivoting; RSS = y.y - beta . (X^T y) */
  double rhs[MAXP];
  for (guint i = 0; i < np; i++)
    rhs[i] = a[i][np];
  for (guint c = 0; c < np; c++) {
    guint piv = c;
    for (guint r = c + 1; r < np; r++)
      if (fabs (a[r][c]) > fabs (a[piv][c]))
        piv = r;
    if (!(fabs (a[piv][c]) > 1e-12))
      return INFINITY;
    for (guint k = 0; k <= np; k++) {
      double t = a[c][k];
      a[c][k] = a[piv][k];
      a[piv][k] = t;
    }
    for (guint r = 0; r < np; r++)
      if (r != c) {
        double f = a[r][c] / a[c][c];
        for (guint k = c; k <= np; k++)
          a[r][k] -= f * a[c][k];
      }
  }
  double explained = 0;
  /* the rows were permuted together with their right-hand sides: beta_i = a[i][np] / a[i][i] */
  double beta[MAXP];
  for (guint i = 0; i < np; i++)
    beta[i] = a[i][np] / a[i][i];
  for (guint i = 0; i < np; i++)
    explained += beta[i] * rhs[i];
  return yy - explained;
}

gboolean
ds_stripe_period_detect (const DsImage *a, const DsImage *b, double *period_px, double *snr, GError **error)
{
  if (!a || (b && (b->width != a->width || b->height != a->height))) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_INVALID_ARGUMENT,
                 "stripe period: %s", a ? "the two frames differ in size" : "no frame");
    return FALSE;
  }
  guint w = a->width;
  *period_px = NAN;
  *snr = 0;
  guint j_max = (guint) floor (w / 2.5);
  if (j_max < 2)
    return FALSE;
  g_autofree double *p = column_profile (a, b);
  double mean = 0;
  guint finite = 0;
  for (guint x = 0; x < w; x++)
    if (isfinite (p[x])) {
      mean += p[x];
      finite++;
    }
  if (finite < 8)
    return FALSE;
  mean /= finite;
  /* |DFT| at whole numbers of cycles across the width, 2 .. w / 2.5 */
  g_autofree double *mag = g_new0 (double, j_max + 1);
  for (guint j = 2; j <= j_max; j++) {
    double re = 0, im = 0;
    for (guint x = 0; x < w; x++)
      if (isfinite (p[x])) {
        double t = 2 * G_PI * (double) j * x / w;
        re += (p[x] - mean) * cos (t);
        im -= (p[x] - mean) * sin (t);
      }
    mag[j] = hypot (re, im);
  }
  guint best = 2;
  for (guint j = 3; j <= j_max; j++)
    if (mag[j] > mag[best])
      best = j;
  /* The noise: the median magnitude, Rayleigh-distributed (median 1.1774 sigma). */
  g_autofree double *sorted = g_memdup2 (mag + 2, (j_max - 1) * sizeof (double));
  for (guint i = 1; i < j_max - 1; i++)
    for (guint k = i; k > 0 && sorted[k - 1] > sorted[k]; k--) {
      double t = sorted[k];
      sorted[k] = sorted[k - 1];
      sorted[k - 1] = t;
    }
  double sigma = sorted[(j_max - 1) / 2] / 1.1774100225154747;
  *snr = sigma > 0 ? mag[best] / sigma : INFINITY;
  if (*snr < 8)
    return FALSE;
  /* A harmonic is not the fundamental: a strong line at a whole fraction of the peak's
   * frequency is (the lowest such). */
  for (guint d = 5; d >= 2; d--) {
    guint j = (guint) lround ((double) best / d);
    if (j < 2 || fabs ((double) best / d - j) > 0.5)
      continue;
    double m = MAX (mag[j], MAX (j > 2 ? mag[j - 1] : 0, j < j_max ? mag[j + 1] : 0));
    if (m >= 0.5 * mag[best]) {
      best = j;
      break;
    }
  }
  /* Golden-section search of the fit's residual between the neighbouring whole-cycle periods,
   * with the harmonics the sampling resolves (up to 6). */
  double lo = (double) w / (best + 1), hi = (double) w / MAX (best - 1, 1u);
  guint harmonics = (guint) CLAMP (floor ((double) w / best / 2.5), 1.0, 6.0);
  const double g = 0.6180339887498949;
  double x1 = hi - g * (hi - lo), x2 = lo + g * (hi - lo);
  double f1 = fit_residual (p, w, x1, harmonics), f2 = fit_residual (p, w, x2, harmonics);
  for (int it = 0; it < 60 && hi - lo > 1e-7 * hi; it++) {
    if (f1 < f2) {
      hi = x2;
      x2 = x1;
      f2 = f1;
      x1 = hi - g * (hi - lo);
      f1 = fit_residual (p, w, x1, harmonics);
    } else {
      lo = x1;
      x1 = x2;
      f1 = f2;
      x2 = lo + g * (hi - lo);
      f2 = fit_residual (p, w, x2, harmonics);
    }
  }
  *period_px = 0.5 * (lo + hi);
  return TRUE;
}
