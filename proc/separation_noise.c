/* Noise helpers of the separation: a data-derived noise estimate of one frame and the
 * distribution of the range of N normals (the max/min estimators' modulation test). */
#include <math.h>

#include "proc/separation_internal.h"
#include "proc/simd.h"

/* k-th smallest of d[0..n) (Hoare's selection; reorders d). O(n) on average. */
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

/* |a - 2b + c| of one run of columns; a non-finite difference becomes +INFINITY, above every
 * finite value, so the median of the finite ones is still a k-th smallest (no compaction). */
#define DEFINE_SECOND_DIFF(T, NAME)                                                               \
  DS_KERNEL void second_diff_##NAME (const T *restrict a, const T *restrict b,                    \
                                     const T *restrict c, float *restrict out, gsize n)           \
  {                                                                                               \
    for (gsize x = 0; x < n; x++) {                                                               \
      float d = (float) a[x] - 2.0f * (float) b[x] + (float) c[x];                                \
      out[x] = isfinite (d) ? fabsf (d) : INFINITY;                                               \
    }                                                                                             \
  }
DEFINE_SECOND_DIFF (guint8, u8)
DEFINE_SECOND_DIFF (guint16, u16)
DEFINE_SECOND_DIFF (float, f32)

DS_CLONES static void
second_diff (const DsImage *f, guint y, gsize x0, gsize n, float *out)
{
  const guint8 *a = ds_image_row (f, y - 1), *b = ds_image_row (f, y), *c = ds_image_row (f, y + 1);
  gsize ss = ds_sample_size (f->type);
  a += x0 * ss;
  b += x0 * ss;
  c += x0 * ss;
  switch (f->type) {
  case DS_SAMPLE_U8:
    second_diff_u8 (a, b, c, out, n);
    break;
  case DS_SAMPLE_U16:
    second_diff_u16 ((const guint16 *) a, (const guint16 *) b, (const guint16 *) c, out, n);
    break;
  default:
    second_diff_f32 ((const float *) a, (const float *) b, (const float *) c, out, n);
    break;
  }
}

double
ds_separation_frame_noise (const DsImage *frame)
{
  if (frame->height < 3)
    return NAN;
  /* A sample of DS_NOISE_SAMPLES differences: runs of up to RUN contiguous columns (vector
   * loads) on evenly spaced row triples, the runs spread evenly across the width. The median's
   * relative precision is then about 1 %, at a cost far below folding the frame. */
  const gsize target = DS_NOISE_SAMPLES, run_max = 256;
  gsize w = frame->width, rows = frame->height - 2;
  gsize run = MIN (w, run_max);
  gsize runs_per_row_max = w / run;
  gsize n_rows = MIN (rows, MAX ((gsize) 1, target / (run * MIN (runs_per_row_max, (gsize) 4))));
  gsize runs_per_row = MAX ((gsize) 1, MIN (runs_per_row_max, target / (run * n_rows)));
  g_autofree float *d = g_new (float, n_rows * runs_per_row * run);
  gsize n = 0;
  for (gsize r = 0; r < n_rows; r++) {
    guint y = (guint) (1 + r * rows / n_rows);
    for (gsize k = 0; k < runs_per_row; k++) {
      /* runs at evenly spaced places, shifted from row to row so that columns vary too */
      gsize span = w - run;
      gsize x0 = runs_per_row > 1 ? (k * span) / (runs_per_row - 1) : (r * 131) % (span + 1);
      second_diff (frame, y, x0, run, d + n);
      n += run;
    }
  }
  gsize finite = 0;
  for (gsize i = 0; i < n; i++)
    finite += d[i] < INFINITY;
  if (finite == 0)
    return NAN;
  gsize k = finite / 2;
  double med = select_kth (d, n, k);
  if (frame->type != DS_SAMPLE_F32) {
    /* Integer samples give integer differences: the median of a few DN of noise would jump
     * between whole numbers. Read each integer v as the interval [v - 1/2, v + 1/2) ([0, 1/2)
     * for 0, since these are absolute values) and interpolate within it. */
    gsize below = 0, at = 0;
    for (gsize i = 0; i < n; i++) {
      below += d[i] < med;
      at += d[i] == med;
    }
    double lo = med > 0 ? med - 0.5 : 0.0, width = med > 0 ? 1.0 : 0.5;
    med = lo + width * ((double) k + 0.5 - (double) below) / (double) at;
  }
  /* |N(0, 6 sigma^2)| has median 0.6745 * sqrt(6) sigma. */
  double sigma = med / (0.6744897501960817 * sqrt (6.0));
  /* Integer samples carry at least the quantisation noise 1/sqrt(12) of a continuous scene. */
  if (frame->type != DS_SAMPLE_F32)
    sigma = MAX (sigma, sqrt (1.0 / 12.0));
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

double
ds_separation_normal_upper_quantile (double p)
{
  double lo = 0, hi = 40;
  for (int i = 0; i < 60; i++) {
    double mid = 0.5 * (lo + hi);
    if (normal_cdf (-mid) > p)
      lo = mid;
    else
      hi = mid;
  }
  return 0.5 * (lo + hi);
}
