#include "daemon/operating/stripe_model.h"

#include <math.h>
#include <string.h>

#include "proc/proc_error.h"

/* Antiderivative of the blurred unit step Phi(t / sigma): t Phi(t / sigma) + sigma phi(t / sigma). */
static double
step_antiderivative (double t, double sigma)
{
  double z = t / sigma;
  return t * 0.5 * erfc (-z / G_SQRT2) + sigma * exp (-0.5 * z * z) / sqrt (2 * G_PI);
}

/* Length of [x0, x1] lit by blurred square stripes (lit intervals centred on P (j + shift)). */
static double
lit_length (const DsStripeModel *g, double x0, double x1, double shift)
{
  double P = g->period_px, half = g->duty * P / 2, s = g->blur_px;
  double reach = s > 0 ? 8 * s : 0, lit = 0;
  double j0 = floor ((x0 - reach - half) / P - shift), j1 = ceil ((x1 + reach + half) / P - shift);
  for (double j = j0; j <= j1; j++) {
    double lo = P * (j + shift) - half, hi = P * (j + shift) + half;
    if (hi < x0 - reach || lo > x1 + reach)
      continue;
    if (!(s > 0) || (lo > x0 + reach && hi < x1 - reach)) {
      double a = MAX (x0, lo), b = MIN (x1, hi);
      lit += b > a ? b - a : 0;
      continue;
    }
    /* integral over [x0, x1] of Phi((x - lo)/s) - Phi((x - hi)/s) */
    lit += step_antiderivative (x1 - lo, s) - step_antiderivative (x0 - lo, s) -
           step_antiderivative (x1 - hi, s) + step_antiderivative (x0 - hi, s);
  }
  return CLAMP (lit, 0.0, x1 - x0);
}

static double
aperture (const DsStripeModel *g)
{
  return g->pixel_aperture > 0 ? MAX (g->pixel_aperture, DS_STRIPE_POINT_APERTURE) : 1.0;
}

double
ds_stripe_value (const DsStripeModel *g, double x, double shift)
{
  double b = g->black_level, p, w = aperture (g);
  if (g->kind == DS_PATTERN_SINE)
    p = 0.5 + ds_stripe_harmonic (g, 1) / (1.0 - b) * cos (2 * G_PI * (x / g->period_px - shift));
  else
    p = lit_length (g, x - w / 2, x + w / 2, shift) / w;
  return b + (1.0 - b) * p;
}

guint
ds_stripe_pair_sums_agree (const DsStripeModel *g, double shift_fine, double shift_coarse, double tol, guint width,
                           guint8 *columns)
{
  DsStripeModel coarse = *g;
  coarse.period_px = 2 * g->period_px;
  g_autofree guint8 *match = g_new0 (guint8, width);
  for (guint x = 0; x < width; x++) {
    double sf = ds_stripe_value (g, x, shift_fine) + ds_stripe_value (g, x, shift_fine + 0.5);
    double sc = ds_stripe_value (&coarse, x, shift_coarse) + ds_stripe_value (&coarse, x, shift_coarse + 0.5);
    match[x] = fabs (sf - sc) <= tol * (1 - g->black_level);
  }
  guint kept = 0;
  for (guint x = 0; x < width; x++) {
    columns[x] = x > 0 && x + 1 < width && match[x - 1] && match[x] && match[x + 1];
    kept += columns[x];
  }
  return kept;
}

double
ds_stripe_harmonic (const DsStripeModel *g, guint n)
{
  double f = (double) n / g->period_px, wf = aperture (g) * f;
  double blur = exp (-2 * G_PI * G_PI * g->blur_px * g->blur_px * f * f);
  double pixel = sin (G_PI * wf) / (G_PI * wf);
  double b = g->black_level;
  if (g->kind == DS_PATTERN_SINE)
    return n == 1 ? (1.0 - b) * 0.5 * blur * pixel : 0.0;
  return (1.0 - b) * 2.0 / (n * G_PI) * sin (n * G_PI * g->duty) * blur * pixel;
}

double
ds_stripe_blur_from_gain (const DsStripeModel *g, double h)
{
  DsStripeModel t = *g;
  t.blur_px = 0;
  double sharp = ds_stripe_harmonic (&t, 1);
  if (!(h < sharp))
    return 0.0;
  t.blur_px = g->period_px / 2;
  if (ds_stripe_harmonic (&t, 1) > h)
    return -1.0;
  /* C_1 falls monotonically with sigma: bisect. */
  double lo = 0, hi = g->period_px / 2;
  for (int i = 0; i < 60; i++) {
    t.blur_px = 0.5 * (lo + hi);
    if (ds_stripe_harmonic (&t, 1) > h)
      lo = t.blur_px;
    else
      hi = t.blur_px;
  }
  return 0.5 * (lo + hi);
}

gboolean
ds_stripe_match_gain (DsStripeModel *g, double h)
{
  if (!(h > 0))
    return FALSE;
  g->pixel_aperture = 0;
  double sigma = ds_stripe_blur_from_gain (g, h);
  g->blur_px = sigma < 0 ? g->period_px / 2 : sigma;
  if (sigma != 0)
    return sigma > 0;
  /* At or above the sharp whole pixel's C_1: no blur, a narrower aperture. C_1 rises as the
   * aperture narrows (sinc falls on [0, 1], and w / P < 1 at every period the pilot uses):
   * bisect. */
  g->pixel_aperture = DS_STRIPE_POINT_APERTURE;
  if (ds_stripe_harmonic (g, 1) <= h)
    return TRUE;
  double lo = DS_STRIPE_POINT_APERTURE, hi = 1.0;
  for (int i = 0; i < 60; i++) {
    g->pixel_aperture = 0.5 * (lo + hi);
    if (ds_stripe_harmonic (g, 1) > h)
      lo = g->pixel_aperture;
    else
      hi = g->pixel_aperture;
  }
  g->pixel_aperture = 0.5 * (lo + hi);
  return TRUE;
}

#define MAX_UNKNOWNS (4 * DS_STRIPE_MAX_HARMONICS + 1)

/* Inverts the n x n matrix a in place (Gauss-Jordan, partial pivoting); FALSE when singular. */
static gboolean
invert (double *a, guint n)
{
  double inv[MAX_UNKNOWNS * MAX_UNKNOWNS] = { 0 };
  for (guint i = 0; i < n; i++)
    inv[i * n + i] = 1;
  double scale = 0;
  for (guint i = 0; i < n * n; i++)
    scale = MAX (scale, fabs (a[i]));
  for (guint c = 0; c < n; c++) {
    guint piv = c;
    for (guint r = c + 1; r < n; r++)
      if (fabs (a[r * n + c]) > fabs (a[piv * n + c]))
        piv = r;
    if (!(fabs (a[piv * n + c]) > 1e-12 * scale))
      return FALSE;
    for (guint k = 0; k < n && piv != c; k++) {
      double t = a[c * n + k];
      a[c * n + k] = a[piv * n + k];
      a[piv * n + k] = t;
      t = inv[c * n + k];
      inv[c * n + k] = inv[piv * n + k];
      inv[piv * n + k] = t;
    }
    double d = a[c * n + c];
    for (guint k = 0; k < n; k++) {
      a[c * n + k] /= d;
      inv[c * n + k] /= d;
    }
    for (guint r = 0; r < n; r++) {
      if (r == c)
        continue;
      double f = a[r * n + c];
      if (f == 0)
        continue;
      for (guint k = 0; k < n; k++) {
        a[r * n + k] -= f * a[c * n + k];
        inv[r * n + k] -= f * inv[c * n + k];
      }
    }
  }
  memcpy (a, inv, sizeof (double) * n * n);
  return TRUE;
}

/* The basis at column x: the mean, each harmonic's cosine and sine, and with an envelope e the
 * same harmonics times e(x) - 1 (the stripes on the scene's own variation across the columns). */
static void
basis_at (double x, double w0, guint nh, const double *envelope, guint i, double *basis)
{
  basis[0] = 1;
  for (guint h = 1; h <= nh; h++) {
    basis[2 * h - 1] = cos (w0 * h * x);
    basis[2 * h] = sin (w0 * h * x);
    if (envelope) {
      basis[2 * nh + 2 * h - 1] = basis[2 * h - 1] * (envelope[i] - 1);
      basis[2 * nh + 2 * h] = basis[2 * h] * (envelope[i] - 1);
    }
  }
}

gboolean
ds_stripe_harmonics_fit (const double *profile, const guint32 *weight, guint x0, guint count,
                         double period_px, guint n_harmonics, DsStripeHarmonics *out, GError **error)
{
  return ds_stripe_harmonics_fit_envelope (profile, weight, NULL, x0, count, period_px, n_harmonics, out, error);
}

gboolean
ds_stripe_harmonics_fit_envelope (const double *profile, const guint32 *weight, const double *envelope, guint x0,
                                  guint count, double period_px, guint n_harmonics, DsStripeHarmonics *out,
                                  GError **error)
{
  memset (out, 0, sizeof *out);
  guint nh = MIN (n_harmonics, DS_STRIPE_MAX_HARMONICS);
  while (nh > 0 && !(period_px / nh > 2.0))
    nh--;
  guint periods = period_px > 0 ? (guint) floor ((double) count / period_px) : 0;
  guint cols = MIN (count, (guint) lround (periods * period_px));
  guint n = (envelope ? 4 : 2) * nh + 1;
  if (nh == 0 || periods == 0 || cols < n + 2) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_INVALID_ARGUMENT,
                 "stripe harmonics: %u columns at period %g px do not hold a whole period and %u unknowns",
                 count, period_px, n);
    return FALSE;
  }
  double ata[MAX_UNKNOWNS * MAX_UNKNOWNS] = { 0 }, atb[MAX_UNKNOWNS] = { 0 };
  double w0 = 2 * G_PI / period_px;
  guint used = 0;
  for (guint i = 0; i < cols; i++) {
    if (weight && weight[i] == 0)
      continue;
    double x = (double) (x0 + i), basis[MAX_UNKNOWNS];
    basis_at (x, w0, nh, envelope, i, basis);
    for (guint a = 0; a < n; a++) {
      atb[a] += basis[a] * profile[i];
      for (guint b = 0; b < n; b++)
        ata[a * n + b] += basis[a] * basis[b];
    }
    used++;
  }
  if (used < n + 2 || !invert (ata, n)) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_INVALID_ARGUMENT,
                 "stripe harmonics: %u usable columns at period %g px do not determine %u harmonics",
                 used, period_px, nh);
    return FALSE;
  }
  double p[MAX_UNKNOWNS] = { 0 };
  for (guint a = 0; a < n; a++)
    for (guint b = 0; b < n; b++)
      p[a] += ata[a * n + b] * atb[b];
  double rss = 0;
  for (guint i = 0; i < cols; i++) {
    if (weight && weight[i] == 0)
      continue;
    double x = (double) (x0 + i), basis[MAX_UNKNOWNS], model = 0;
    basis_at (x, w0, nh, envelope, i, basis);
    for (guint a = 0; a < n; a++)
      model += p[a] * basis[a];
    rss += (profile[i] - model) * (profile[i] - model);
  }
  double sigma2 = rss / (double) (used - n);
  out->n_harmonics = nh;
  out->mean = p[0];
  out->columns_used = used;
  double mean_inv = 0;
  for (guint h = 1; h <= nh; h++) {
    double c = p[2 * h - 1], s = p[2 * h];
    out->amplitude[h] = hypot (c, s);
    /* A cos (2 pi n (x/P - phase)) = A cos (n w x) cos (2 pi n phase) + A sin (n w x) sin (...) */
    double ph = atan2 (s, c) / (2 * G_PI * h);
    out->phase[h] = ph - floor (ph);
    mean_inv += 0.5 * (ata[(2 * h - 1) * n + 2 * h - 1] + ata[2 * h * n + 2 * h]);
  }
  out->sigma_amplitude = sqrt (sigma2 * mean_inv / nh);
  return TRUE;
}

double
ds_stripe_harmonics_eval (const DsStripeHarmonics *h, double period_px, double x)
{
  double v = h->mean;
  for (guint n = 1; n <= h->n_harmonics; n++)
    v += h->amplitude[n] * cos (2 * G_PI * n * (x / period_px - h->phase[n]));
  return v;
}
