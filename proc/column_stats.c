#include "proc/column_stats.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "proc/proc_error.h"

/* Noise strata (ds_column_stats_noise_dn): at most this many, of at least this many samples; and
 * the floor of the robust scale of a second difference (DN). */
#define DS_NOISE_STRATA 16u
#define DS_NOISE_STRATUM_MIN 500u
#define DS_NOISE_SCALE_FLOOR 1.5
#define DS_NOISE_MAX_FRAMES 4u

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

/* One second difference d at its level (what sorts it into a stratum), with, for a weighted
 * combination, its weights' sum of squares w2 and its shot weight (sum_i w_i^2 (f_i - dark)). */
typedef struct {
  float level, d, w2, shot;
} LevelSample;

static int
compare_double (const void *x, const void *y)
{
  double a = *(const double *) x, b = *(const double *) y;
  return (a > b) - (a < b);
}

/* The median of v[0..n) (sorted in place); 0 for none. */
static double
median_of (double *v, guint n)
{
  if (n == 0)
    return 0;
  qsort (v, n, sizeof *v, compare_double);
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

static int
compare_level (const void *x, const void *y)
{
  float a = ((const LevelSample *) x)->level, b = ((const LevelSample *) y)->level;
  return (a > b) - (a < b);
}

/* The level of a sample of the second difference at (x, y): the sum of the frames in the same
 * row, in the columns on either side. Not the sample's own column: its noise is in d, and a level
 * read from the same samples would select d's size or sign when sorted by (for a single frame,
 * a(y) is in both); the neighbours' noise is independent of d. And in the same row, so that a
 * sample on a scene edge along y is sorted with the side of the edge it is on, not into a stratum
 * between the two sides that only edges would fill. Stripes vary along x, by little over two
 * columns. */
static double
level_beside (const DsImage *const *f, const void *const *rows, guint n_f, guint x)
{
  double sum = 0;
  guint k = 0;
  for (int dx = -1; dx <= 1; dx += 2) {
    if ((dx < 0 && x == 0) || (dx > 0 && x + 1 >= f[0]->width))
      continue;
    guint xx = (guint) ((int) x + dx);
    double v = 0;
    for (guint i = 0; i < n_f; i++)
      v += ds_image_sample (f[i], rows[i], xx);
    if (isfinite (v)) {
      sum += v;
      k++;
    }
  }
  return k ? sum / k : 0.0;
}

/* The robust mean square of the second differences d[0..n) (sorted in place by level), over 6:
 * the variance of the combination they were taken of. The means of level, w2 and shot over the
 * samples kept go to *kept (may be NULL). */
typedef struct {
  double level, w2, shot;
} KeptMeans;

static double
robust_variance (LevelSample *d, gsize n, guint max_strata, KeptMeans *kept)
{
  if (n == 0)
    return NAN;
  /* Shot noise makes the variance grow with the signal: where dim places (objects' shadows) are
   * most of the samples, one robust scale for all is theirs, and a cut at 5 of it falls inside
   * the bright places' Gaussian core (and the shot noise reads at a fraction of the sensor's).
   * So, with max_strata > 1, the scale is a line in the level (read noise plus shot noise): the samples sorted by level
   * (level_beside (): why it is read in the neighbouring columns), a robust scale from the median
   * of |d| per stratum of equal count, a robust line through their squares against the strata's
   * mean levels; then each sample is cut at 5 of its own level's scale, and the variance is the
   * truncated mean square of the samples kept, corrected for the truncation. A line, not the
   * strata's own scales: a stratum at the step between dim and bright places holds both, and its
   * median is the majority's. */
  qsort (d, n, sizeof *d, compare_level);
  guint strata = (guint) CLAMP (n / DS_NOISE_STRATUM_MIN, 1, max_strata);
  g_autofree float *scratch = g_new (float, n / strata + 1);
  double strata_level[DS_NOISE_STRATA], strata_r2[DS_NOISE_STRATA];
  for (guint k = 0; k < strata; k++) {
    gsize lo = n * k / strata, hi = n * (k + 1) / strata;
    double level = 0;
    for (gsize i = lo; i < hi; i++) {
      scratch[i - lo] = fabsf (d[i].d);
      level += d[i].level;
    }
    strata_level[k] = level / (double) (hi - lo);
    qsort (scratch, hi - lo, sizeof *scratch, compare_float);
    /* The floor: quantised integer samples (a median of 1 or 2 DN for a true 1.6) must never be
     * cut into their Gaussian core. */
    double robust = MAX (scratch[(hi - lo) / 2] / 0.6744897501960817, DS_NOISE_SCALE_FLOOR);
    strata_r2[k] = robust * robust;
  }
  /* The line by Theil-Sen (the median of the slopes between strata, then the median intercept):
   * a few strata of what is left of the scene would tilt a least-squares line until the cut let
   * it in (and the gain read orders of magnitude above the sensor's). */
  g_autofree double *slopes = g_new (double, (gsize) strata * strata / 2 + 1);
  guint n_slopes = 0;
  for (guint i = 0; i < strata; i++)
    for (guint j = i + 1; j < strata; j++)
      if (strata_level[j] > strata_level[i] * (1 + 1e-9) + 1e-9)
        slopes[n_slopes++] = (strata_r2[j] - strata_r2[i]) / (strata_level[j] - strata_level[i]);
  double slope = MAX (median_of (slopes, n_slopes), 0.0);
  for (guint k = 0; k < strata; k++)
    slopes[k] = strata_r2[k] - slope * strata_level[k];
  double intercept = median_of (slopes, strata);
  /* Cut at 5 sigma: narrow enough to drop sharp scene edges. */
  const double c = 5.0;
  double sum = 0, sum_level = 0, sum_w2 = 0, sum_shot = 0;
  gsize used = 0;
  for (gsize i = 0; i < n; i++) {
    double scale = sqrt (MAX (intercept + slope * d[i].level, DS_NOISE_SCALE_FLOOR * DS_NOISE_SCALE_FLOOR));
    if (fabs (d[i].d) < c * scale) {
      sum += (double) d[i].d * d[i].d;
      sum_level += d[i].level;
      sum_w2 += d[i].w2;
      sum_shot += d[i].shot;
      used++;
    }
  }
  if (used == 0)
    return NAN;
  /* E[z^2 ; |z| < c] / P(|z| < c) = 1 - 2 c phi(c) / (2 Phi(c) - 1) for a unit normal. */
  double phi = exp (-0.5 * c * c) / sqrt (2 * G_PI), inside = erf (c / G_SQRT2);
  double shrink = 1.0 - 2 * c * phi / inside;
  if (kept)
    *kept = (KeptMeans){ sum_level / (double) used, sum_w2 / (double) used, sum_shot / (double) used };
  return sum / (double) used / shrink / 6.0;
}

/* The noise (1 sigma, DN) of sum_i sign[i] f[i], from its second difference along y. */
static double
noise_of_combination (const DsImage *const *f, const double *sign, guint n_f, const guint8 *columns, double ceiling,
                      guint max_strata, double *mean_level)
{
  const DsImage *a = f[0];
  if (a->height < 3)
    return NAN;
  for (guint i = 1; i < n_f; i++)
    if (f[i]->width != a->width || f[i]->height != a->height)
      return NAN;
  const double top = ceiling > 0 ? ceiling : INFINITY;
  gsize cap = (gsize) a->width * (a->height - 2);
  g_autofree LevelSample *d = g_new (LevelSample, cap);
  gsize n = 0;
  const void *rows[3][DS_NOISE_MAX_FRAMES];
  for (guint y = 1; y + 1 < a->height; y++) {
    for (guint j = 0; j < 3; j++)
      for (guint i = 0; i < n_f; i++)
        rows[j][i] = ds_image_row (f[i], y - 1 + j);
    for (guint x = 0; x < a->width; x++) {
      if (columns && !columns[x])
        continue;
      double v[3] = { 0, 0, 0 };
      gboolean ok = TRUE;
      for (guint j = 0; j < 3 && ok; j++)
        for (guint i = 0; i < n_f && ok; i++) {
          double s = ds_image_sample (f[i], rows[j][i], x);
          ok = isfinite (s) && s < top;
          v[j] += sign[i] * s;
        }
      if (ok)
        d[n++] = (LevelSample){ (float) level_beside (f, rows[1], n_f, x), (float) (v[0] - 2.0 * v[1] + v[2]), 0, 0 };
    }
  }
  KeptMeans kept;
  double var = robust_variance (d, n, max_strata, &kept);
  if (mean_level && isfinite (var))
    *mean_level = kept.level;
  return sqrt (var);
}


double
ds_column_stats_noise_dn (const DsImage *a, const DsImage *b, double ceiling)
{
  const DsImage *f[2] = { a, b };
  const double sign[2] = { 1, -1 };
  /* One stratum: a single frame or pair holds the scene, whose structure can fill whole strata
   * (a few strata at tens of times the others' scale tilt even a robust line, and the shot noise
   * reads above the sensor's gain); one scale for all keeps it out. */
  return noise_of_combination (f, sign, b ? 2 : 1, NULL, ceiling, 1, NULL);
}

double
ds_column_stats_noise_sets_dn (const DsImage *const set_a[2], const DsImage *const set_b[2], const guint8 *columns,
                               double ceiling, double *mean_level)
{
  const DsImage *f[4] = { set_a[0], set_a[1], set_b[0], set_b[1] };
  const double sign[4] = { 1, 1, -1, -1 };
  if (mean_level)
    *mean_level = NAN;
  return noise_of_combination (f, sign, 4, columns, ceiling, DS_NOISE_STRATA, mean_level);
}

/* The shot weight of one sample of a weighted pair: sum_i w_i^2 (f_i - dark). */
static double
pair_shot (const DsImage *const f[2], const void *const rows[2], const double w[2], double dark_dn, guint x)
{
  double s = 0;
  for (guint i = 0; i < 2; i++)
    s += w[i] * w[i] * (ds_image_sample (f[i], rows[i], x) - dark_dn);
  return s;
}

double
ds_column_stats_noise_pair_dn (const DsImage *a, const DsImage *b, const double *rho, double dark_dn, double ceiling,
                               double *mean_w2, double *mean_shot)
{
  const DsImage *f[2] = { a, b };
  if (mean_w2)
    *mean_w2 = NAN;
  if (mean_shot)
    *mean_shot = NAN;
  if (a->height < 3 || b->width != a->width || b->height != a->height)
    return NAN;
  const double top = ceiling > 0 ? ceiling : INFINITY;
  guint w = a->width, h = a->height;
  g_autofree LevelSample *d = g_new (LevelSample, (gsize) w * (h - 2));
  gsize n = 0;
  for (guint y = 1; y + 1 < h; y++) {
    const void *rows[3][2], *level_rows[2][2];
    for (guint i = 0; i < 2; i++) {
      for (guint j = 0; j < 3; j++)
        rows[j][i] = ds_image_row (f[i], y - 1 + j);
      /* The level is read two rows away, outside the second difference, so that sorting by it
       * does not select d's size (level_beside (): the same reason); the scene is cancelled in d,
       * so a level across an edge only places the sample in a neighbouring stratum. */
      guint above = y >= 2 ? y - 2 : MIN (y + 2, h - 1), below = y + 2 < h ? y + 2 : (y >= 2 ? y - 2 : 0);
      level_rows[0][i] = ds_image_row (f[i], above);
      level_rows[1][i] = ds_image_row (f[i], below);
    }
    for (guint x = 0; x < w; x++) {
      double r = rho[x];
      if (!isfinite (r))
        continue;
      r = CLAMP (r, -1.0, 1.0);
      const double wt[2] = { 1 - r, -(1 + r) };
      double v[3] = { 0, 0, 0 };
      gboolean ok = TRUE;
      for (guint j = 0; j < 3 && ok; j++)
        for (guint i = 0; i < 2 && ok; i++) {
          double s = ds_image_sample (f[i], rows[j][i], x);
          ok = isfinite (s) && s < top;
          v[j] += wt[i] * s;
        }
      double level = 0.5 * (pair_shot (f, level_rows[0], wt, dark_dn, x) + pair_shot (f, level_rows[1], wt, dark_dn, x));
      if (ok && isfinite (level))
        d[n++] = (LevelSample){ (float) level, (float) (v[0] - 2.0 * v[1] + v[2]), (float) (wt[0] * wt[0] + wt[1] * wt[1]),
                                (float) pair_shot (f, rows[1], wt, dark_dn, x) };
    }
  }
  KeptMeans kept;
  double var = robust_variance (d, n, DS_NOISE_STRATA, &kept);
  if (isfinite (var)) {
    if (mean_w2)
      *mean_w2 = kept.w2;
    if (mean_shot)
      *mean_shot = kept.shot;
  }
  return sqrt (var);
}
