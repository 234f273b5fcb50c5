/* The stripes' profile across one period (stripe_profile.h). */
#include "proc/stripe_profile.h"

#include <math.h>
#include <stdlib.h>

#include "proc/proc_error.h"
#include "proc/stripe_phase.h"

static double
sample (const DsImage *img, guint x, guint y)
{
  return ds_image_sample (img, ds_image_row (img, y), x);
}

static int
compare_doubles (const void *a, const void *b)
{
  double x = *(const double *) a, y = *(const double *) b;
  return x < y ? -1 : x > y;
}

void
ds_stripe_profile_free (DsStripeProfile *p)
{
  if (!p)
    return;
  g_free (p->sum);
  g_free (p->r);
  g_free (p->u);
  g_free (p->t);
  g_free (p->n);
  g_free (p->nt);
  g_free (p);
}

gboolean
ds_stripe_profile_offset (const DsImage *l0, const DsImage *l1, double period, double *offset)
{
  if (!ds_image_same_shape (l0, l1))
    return FALSE;
  g_autoptr (DsImage) diff = ds_image_new (DS_SAMPLE_F32, l0->width, l0->height, NULL);
  if (!diff)
    return FALSE;
  for (guint y = 0; y < l0->height; y++) {
    float *row = ds_image_row (diff, y);
    for (guint x = 0; x < l0->width; x++)
      row[x] = (float) (sample (l0, x, y) - sample (l1, x, y));
  }
  DsStripePhase sp;
  if (!ds_stripe_phase_measure (diff, period, NULL, &sp, NULL) || !sp.reliable)
    return FALSE;
  *offset = sp.phase;
  return TRUE;
}

/* u = frac (x / P - offset) */
static double
position (double x, double period, double offset)
{
  double u = x / period - offset;
  return u - floor (u);
}

/* The mean of the usable sums over the box of `radius` around each pixel, by integral images. */
static double *
local_means (const DsStripeProfile *p, guint radius)
{
  guint w = p->width, h = p->height;
  g_autofree double *integral = g_new0 (double, (gsize) (w + 1) * (h + 1));
  g_autofree guint *counts = g_new0 (guint, (gsize) (w + 1) * (h + 1));
  for (guint y = 0; y < h; y++)
    for (guint x = 0; x < w; x++) {
      gsize i = (gsize) y * w + x, k = (gsize) (y + 1) * (w + 1) + x + 1;
      gboolean use = !isnan (p->sum[i]);
      integral[k] = (use ? p->sum[i] : 0) + integral[k - 1] + integral[k - (w + 1)] - integral[k - (w + 1) - 1];
      counts[k] = (use ? 1 : 0) + counts[k - 1] + counts[k - (w + 1)] - counts[k - (w + 1) - 1];
    }
  double *local = g_new (double, (gsize) w * h);
  for (guint y = 0; y < h; y++)
    for (guint x = 0; x < w; x++) {
      guint x0 = x > radius ? x - radius : 0, x1 = MIN (w, x + radius + 1);
      guint y0 = y > radius ? y - radius : 0, y1 = MIN (h, y + radius + 1);
      gsize a = (gsize) y0 * (w + 1) + x0, b = (gsize) y0 * (w + 1) + x1;
      gsize c = (gsize) y1 * (w + 1) + x0, e = (gsize) y1 * (w + 1) + x1;
      guint count = counts[e] - counts[b] - counts[c] + counts[a];
      local[(gsize) y * w + x] = count ? (integral[e] - integral[b] - integral[c] + integral[a]) / count : NAN;
    }
  return local;
}

DsStripeProfile *
ds_stripe_profile_bin (const DsImage *dark, const DsImage *l0, const DsImage *l1, double period, double offset,
                       double saturation, guint n_bins, GError **error)
{
  if (!dark || !l0 || !l1 || !ds_image_same_shape (l0, l1) || !ds_image_same_shape (l0, dark) || !(period > 0) ||
      n_bins == 0) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_INVALID_ARGUMENT,
                 "stripe profile: a dark frame and two phases of one size, a period > 0 and bins are needed");
    return NULL;
  }
  DsStripeProfile *p = g_new0 (DsStripeProfile, 1);
  guint w = p->width = l0->width, h = p->height = l0->height;
  p->period_px = period;
  p->offset_cycles = offset;
  p->n_bins = n_bins;
  p->r = g_new0 (double, n_bins);
  p->u = g_new0 (double, n_bins);
  p->t = g_new0 (double, n_bins);
  p->n = g_new0 (guint64, n_bins);
  p->nt = g_new0 (guint64, n_bins);
  gsize npix = (gsize) w * h;
  p->sum = g_new (double, npix);
  g_autofree double *sorted = g_new (double, npix);
  gsize n_ok = 0;
  double clip = saturation > 0 ? saturation : INFINITY;
  for (guint y = 0; y < h; y++)
    for (guint x = 0; x < w; x++) {
      double a = sample (l0, x, y), b = sample (l1, x, y), d = sample (dark, x, y);
      gsize i = (gsize) y * w + x;
      p->sum[i] = a < clip && b < clip && isfinite (a + b + d) ? a + b - 2 * d : NAN;
      if (!isnan (p->sum[i]))
        sorted[n_ok++] = p->sum[i];
    }
  for (guint j = 0; j < n_bins; j++)
    p->u[j] = (j + 0.5) / n_bins;
  if (n_ok < 64)
    return p;
  qsort (sorted, n_ok, sizeof (double), compare_doubles);
  double threshold = 0.25 * sorted[(gsize) (0.9 * (double) (n_ok - 1))];
  if (!(threshold > 0))
    return p;
  p->threshold = threshold;
  g_autofree double *local = local_means (p, (guint) MAX (4.0, ceil (period)));
  g_autofree double *u_sum = g_new0 (double, n_bins);
  for (guint y = 0; y < h; y++)
    for (guint x = 0; x < w; x++) {
      gsize i = (gsize) y * w + x;
      double u = position (x, period, offset);
      guint j = MIN ((guint) (u * n_bins), n_bins - 1);
      if (!isnan (p->sum[i]) && local[i] > threshold) {
        p->t[j] += p->sum[i] / local[i];
        p->nt[j]++;
      }
      if (!(p->sum[i] > threshold))
        continue;
      p->r[j] += (sample (l0, x, y) - sample (dark, x, y)) / p->sum[i];
      u_sum[j] += u;
      p->n[j]++;
      p->pixels++;
    }
  for (guint j = 0; j < n_bins; j++) {
    if (p->nt[j])
      p->t[j] /= (double) p->nt[j];
    p->bins_used += p->nt[j] || p->n[j];
    if (p->n[j]) {
      p->r[j] /= (double) p->n[j];
      p->u[j] = u_sum[j] / (double) p->n[j];
    }
  }
  return p;
}

void
ds_stripe_profile_centres (const DsStripeProfile *p, const DsImage *dark, const DsImage *l0, const DsImage *l1,
                           double duty, double *brightness, double *off)
{
  double window = 0.25 * MIN (duty, 1 - duty);
  for (guint y = 0; y < p->height; y++)
    for (guint x = 0; x < p->width; x++) {
      gsize i = (gsize) y * p->width + x;
      brightness[i] = p->sum[i];
      off[i] = NAN;
      if (!(p->sum[i] > p->threshold) || p->threshold <= 0)
        continue;
      double u = position (x, p->period_px, p->offset_cycles);
      gboolean centre0 = fabs (u - (u > 0.5 ? 1 : 0)) < window, centre1 = fabs (u - 0.5) < window;
      if (!centre0 && !centre1)
        continue;
      double d = sample (dark, x, y);
      double lit = (centre0 ? sample (l0, x, y) : sample (l1, x, y)) - d;
      double o = (centre0 ? sample (l1, x, y) : sample (l0, x, y)) - d;
      if (lit > 0)
        off[i] = o / lit;
    }
}
