#include "proc/stripe_period.h"

#include <math.h>
#include <stdlib.h>

#include "proc/proc_error.h"

static double
sample (const DsImage *img, guint x, guint y)
{
  const void *row = ds_image_row (img, y);
  return img->type == DS_SAMPLE_U8    ? ((const guint8 *) row)[x]
         : img->type == DS_SAMPLE_U16 ? ((const guint16 *) row)[x]
                                      : ((const float *) row)[x];
}

/* |sum_x w[x] e^(-2 pi i f x)|, the exponential advanced by one rotation per sample (no
 * trigonometry in the loop; in double the rounding drift over a frame's width is negligible). */
static double
magnitude (const double *w, guint n, double f)
{
  double re = 0, im = 0, cr = 1, ci = 0, rr = cos (2 * G_PI * f), ri = -sin (2 * G_PI * f);
  for (guint x = 0; x < n; x++) {
    re += w[x] * cr;
    im += w[x] * ci;
    double t = cr * rr - ci * ri;
    ci = cr * ri + ci * rr;
    cr = t;
  }
  return hypot (re, im);
}

static int
compare_doubles (gconstpointer a, gconstpointer b)
{
  double x = *(const double *) a, y = *(const double *) b;
  return x < y ? -1 : x > y;
}

gboolean
ds_stripe_period_measure (const DsImage *frame, double min_px, double max_px, DsStripePeriod *out, GError **error)
{
  *out = (DsStripePeriod){ .period_px = NAN };
  if (frame->type != DS_SAMPLE_U8 && frame->type != DS_SAMPLE_U16 && frame->type != DS_SAMPLE_F32) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_FORMAT, "stripe period: unsupported sample type %d",
                 (int) frame->type);
    return FALSE;
  }
  guint w = frame->width;
  if (!(min_px > 2.0) || !(max_px > min_px) || !(max_px <= w / 2.0)) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_INVALID_ARGUMENT,
                 "stripe period: range %g..%g px must satisfy 2 < min < max <= %g (half the width)", min_px,
                 max_px, w / 2.0);
    return FALSE;
  }
  g_autofree double *p = g_new0 (double, w);
  g_autofree guint *count = g_new0 (guint, w);
  for (guint y = 0; y < frame->height; y++)
    for (guint x = 0; x < w; x++) {
      double v = sample (frame, x, y);
      if (isfinite (v)) {
        p[x] += v;
        count[x]++;
      }
    }
  double mean = 0;
  guint used = 0;
  for (guint x = 0; x < w; x++)
    if (count[x]) {
      p[x] /= count[x];
      mean += p[x];
      used++;
    }
  if (used < 8)
    return TRUE;
  mean /= used;
  /* Hann window: leakage of the strong mean-free profile's edges would otherwise bury a weak
   * peak. Columns without samples count as the mean. */
  for (guint x = 0; x < w; x++) {
    double hann = 0.5 - 0.5 * cos (2 * G_PI * (x + 0.5) / w);
    p[x] = count[x] ? (p[x] - mean) * hann : 0.0;
  }
  double f_lo = 1.0 / max_px, f_hi = 1.0 / min_px, df = 0.25 / w;
  guint n = (guint) ceil ((f_hi - f_lo) / df) + 1;
  g_autofree double *mag = g_new (double, n);
  guint best = 0;
  for (guint i = 0; i < n; i++) {
    mag[i] = magnitude (p, w, f_lo + i * df);
    if (mag[i] > mag[best])
      best = i;
  }
  double f = f_lo + best * df;
  if (best > 0 && best + 1 < n) {
    /* Vertex of the parabola through the peak and its neighbours. */
    double a = mag[best - 1], b = mag[best], c = mag[best + 1];
    double denom = a - 2 * b + c;
    if (denom < 0)
      f += 0.5 * (a - c) / denom * df;
  }
  g_autofree double *sorted = g_memdup2 (mag, n * sizeof (double));
  qsort (sorted, n, sizeof (double), compare_doubles);
  double median = sorted[n / 2];
  out->peak_ratio = median > 0 ? mag[best] / median : (mag[best] > 0 ? INFINITY : 0);
  out->reliable = out->peak_ratio >= DS_STRIPE_PERIOD_MIN_RATIO;
  out->period_px = out->reliable ? 1.0 / f : NAN;
  return TRUE;
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
      double v = sample (a, x, y) - (b ? sample (b, x, y) : 0.0);
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
  g_autofree double *centred = g_new (double, w);
  for (guint x = 0; x < w; x++)
    centred[x] = isfinite (p[x]) ? p[x] - mean : 0.0;
  g_autofree double *mag = g_new0 (double, j_max + 1);
  for (guint j = 2; j <= j_max; j++)
    mag[j] = magnitude (centred, w, (double) j / w);
  guint best = 2;
  for (guint j = 3; j <= j_max; j++)
    if (mag[j] > mag[best])
      best = j;
  /* The noise: the median magnitude, Rayleigh-distributed (median 1.1774 sigma). */
  g_autofree double *sorted = g_memdup2 (mag + 2, (j_max - 1) * sizeof (double));
  qsort (sorted, j_max - 1, sizeof (double), compare_doubles);
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
