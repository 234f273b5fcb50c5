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
