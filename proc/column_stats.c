#include "proc/column_stats.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "proc/proc_error.h"

gboolean
ds_column_stats_compute (const DsImage *a, const DsImage *b, double ceiling, DsColumnStats *out,
                         GError **error)
{
  memset (out, 0, sizeof *out);
  if (b && (a->width != b->width || a->height != b->height)) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_INVALID_ARGUMENT,
                 "column statistics: frames of %ux%u and %ux%u", a->width, a->height, b->width, b->height);
    return FALSE;
  }
  guint w = a->width;
  out->width = w;
  out->mean_diff = g_new0 (double, w);
  out->mean_sq_diff = g_new0 (double, w);
  out->mean_sum = g_new0 (double, w);
  out->count = g_new0 (guint32, w);
  const double top = ceiling > 0 ? ceiling : INFINITY;
  for (guint y = 0; y < a->height; y++) {
    const void *ra = ds_image_row (a, y);
    const void *rb = b ? ds_image_row (b, y) : NULL;
    for (guint x = 0; x < w; x++) {
      double va = ds_image_sample (a, ra, x), vb = rb ? ds_image_sample (b, rb, x) : 0.0;
      if (!isfinite (va) || !isfinite (vb) || va >= top || vb >= top) {
        out->excluded++;
        continue;
      }
      double d = va - vb;
      out->mean_diff[x] += d;
      out->mean_sq_diff[x] += d * d;
      out->mean_sum[x] += va + vb;
      out->count[x]++;
    }
  }
  for (guint x = 0; x < w; x++)
    if (out->count[x]) {
      out->mean_diff[x] /= out->count[x];
      out->mean_sq_diff[x] /= out->count[x];
      out->mean_sum[x] /= out->count[x];
    }
  return TRUE;
}

void
ds_column_stats_clear (DsColumnStats *s)
{
  g_clear_pointer (&s->mean_diff, g_free);
  g_clear_pointer (&s->mean_sq_diff, g_free);
  g_clear_pointer (&s->mean_sum, g_free);
  g_clear_pointer (&s->count, g_free);
}

static int
compare_float (const void *x, const void *y)
{
  float a = *(const float *) x, b = *(const float *) y;
  return (a > b) - (a < b);
}

double
ds_column_stats_noise_dn (const DsImage *a, const DsImage *b, double ceiling)
{
  if (a->height < 3 || (b && (a->width != b->width || a->height != b->height)))
    return NAN;
  const double top = ceiling > 0 ? ceiling : INFINITY;
  gsize cap = (gsize) a->width * (a->height - 2);
  g_autofree float *d = g_new (float, cap);
  gsize n = 0;
  for (guint y = 1; y + 1 < a->height; y++) {
    const void *r[3] = { ds_image_row (a, y - 1), ds_image_row (a, y), ds_image_row (a, y + 1) };
    const void *q[3] = { NULL, NULL, NULL };
    if (b)
      for (int i = 0; i < 3; i++)
        q[i] = ds_image_row (b, y - 1 + (guint) i);
    for (guint x = 0; x < a->width; x++) {
      double v[3];
      gboolean ok = TRUE;
      for (int i = 0; i < 3 && ok; i++) {
        double va = ds_image_sample (a, r[i], x), vb = b ? ds_image_sample (b, q[i], x) : 0.0;
        ok = isfinite (va) && isfinite (vb) && va < top && vb < top;
        v[i] = va - vb;
      }
      if (ok)
        d[n++] = (float) (v[0] - 2.0 * v[1] + v[2]);
    }
  }
  if (n == 0)
    return NAN;
  /* Robust scale from the median of |d| (sorted copy), then the truncated second moment. */
  g_autofree float *abs_d = g_new (float, n);
  for (gsize i = 0; i < n; i++)
    abs_d[i] = fabsf (d[i]);
  qsort (abs_d, n, sizeof *abs_d, compare_float);
  double robust = abs_d[n / 2] / 0.6744897501960817;
  /* Wide enough that quantised integer samples (a median of 1 or 2 DN for a true 1.6) never
   * cut into the Gaussian core, narrow enough to drop scene edges. */
  double cut = 5.0 * MAX (robust, 1.5);
  double sum = 0;
  gsize used = 0;
  for (gsize i = 0; i < n; i++)
    if (fabs (d[i]) < cut) {
      sum += (double) d[i] * d[i];
      used++;
    }
  if (used == 0)
    return NAN;
  /* E[z^2 ; |z| < c] / P(|z| < c) = 1 - 2 c phi(c) / (2 Phi(c) - 1) for a unit normal. */
  double c = cut / MAX (robust, 1e-12);
  double phi = exp (-0.5 * c * c) / sqrt (2 * G_PI), inside = erf (c / G_SQRT2);
  double shrink = c > 8 ? 1.0 : 1.0 - 2 * c * phi / inside;
  return sqrt (sum / (double) used / shrink / 6.0);
}
