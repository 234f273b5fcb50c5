/* Noise helpers of the separation: a data-derived noise estimate of one frame and the
 * distribution of the range of N normals (the max/min estimators' modulation test). */
#include <math.h>

#include "proc/separation_internal.h"

/* k-th smallest of d[0..n) (Hoare's selection; reorders d). O(n) on average: the estimate is
 * taken on the first frame of every set, so it must cost far less than folding that frame. */
static float
select_kth (float *d, gsize n, gsize k)
{
  gsize lo = 0, hi = n - 1;
  while (lo < hi) {
    float pivot = d[lo + (hi - lo) / 2];
    gsize i = lo, j = hi;
    while (i <= j) {
      while (d[i] < pivot)
        i++;
      while (d[j] > pivot)
        j--;
      if (i <= j) {
        float t = d[i];
        d[i] = d[j];
        d[j] = t;
        i++;
        if (j == 0)
          break;
        j--;
      }
    }
    if (k <= j)
      hi = j;
    else if (k >= i)
      lo = i;
    else
      return d[k];
  }
  return d[k];
}

static double
sample_at (const DsImage *f, guint y, guint x)
{
  const void *row = ds_image_row (f, y);
  switch (f->type) {
  case DS_SAMPLE_U8:
    return ((const guint8 *) row)[x];
  case DS_SAMPLE_U16:
    return ((const guint16 *) row)[x];
  default:
    return ((const float *) row)[x];
  }
}

double
ds_separation_frame_noise (const DsImage *frame)
{
  if (frame->height < 3)
    return NAN;
  /* Up to 64K samples from whole, evenly spaced row triples: contiguous reads, so the
   * estimate costs a small fraction of folding the frame. */
  const gsize target = 65536;
  gsize w = frame->width, rows = frame->height - 2;
  gsize n_rows = MIN (rows, MAX ((gsize) 1, target / w));
  gsize col_step = w > target ? (w + target - 1) / target : 1;
  g_autofree float *d = g_new (float, n_rows * (w / col_step + 1));
  gsize n = 0;
  for (gsize r = 0; r < n_rows; r++) {
    guint y = (guint) (1 + r * rows / n_rows);
    for (gsize x = 0; x < w; x += col_step) {
      double v = sample_at (frame, y - 1, (guint) x) - 2.0 * sample_at (frame, y, (guint) x) +
                 sample_at (frame, y + 1, (guint) x);
      if (isfinite (v))
        d[n++] = (float) fabs (v);
    }
  }
  if (n == 0)
    return NAN;
  double med = select_kth (d, n, n / 2);
  /* |N(0, 6 sigma^2)| has median 0.6745 * sqrt(6) sigma. Integer samples carry at least the
   * quantisation noise 1/sqrt(12), which the median of integer differences cannot see. */
  double sigma = med / (0.6744897501960817 * sqrt (6.0));
  if (frame->type != DS_SAMPLE_F32)
    sigma = sqrt (sigma * sigma + 1.0 / 12.0);
  return sigma;
}

static double
normal_cdf (double z)
{
  return 0.5 * erfc (-z / G_SQRT2);
}

/* P(range of n unit normals <= t) = n * integral phi(z) (Phi(z+t) - Phi(z))^(n-1) dz. */
static double
range_cdf (guint n, double t)
{
  const double lo = -9, hi = 9, dz = 0.02;
  double acc = 0;
  for (double z = lo; z <= hi; z += dz) {
    double phi = exp (-0.5 * z * z) / sqrt (2 * G_PI);
    double in = normal_cdf (z + t) - normal_cdf (z);
    if (in > 0)
      acc += phi * pow (in, (double) n - 1.0);
  }
  return n * acc * dz;
}

double
ds_separation_range_quantile (guint n, double p)
{
  if (n < 2)
    return 0;
  double lo = 0, hi = 20;
  for (int i = 0; i < 40; i++) {
    double mid = 0.5 * (lo + hi);
    if (range_cdf (n, mid) < p)
      lo = mid;
    else
      hi = mid;
  }
  return 0.5 * (lo + hi);
}
