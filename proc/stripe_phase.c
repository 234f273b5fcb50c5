#include "proc/stripe_phase.h"

#include "proc/proc_error.h"
#include "proc/simd.h"

#include <math.h>
#include <string.h>

/* Column sums of integer rows in 32 bits, for the vector units (proc/simd.h): exact, so the
 * profile is the same as summed in doubles, at a fraction of the cost. descatterd measures
 * every frame before folding it (proc/phase_check.c sums its rows here too), and 256 rows of
 * a 1 MP frame summed in doubles were the largest part of that check. At most ROWS_PER_U32
 * rows go into one 32-bit sum: 65536 x 65535 < 2^32. */
#define ROWS_PER_U32 65536u

DS_CLONES static void
add_row_u16 (const guint16 *restrict in, guint32 *restrict acc, guint n)
{
  for (guint i = 0; i < n; i++)
    acc[i] += in[i];
}

DS_CLONES static void
add_row_u8 (const guint8 *restrict in, guint32 *restrict acc, guint n)
{
  for (guint i = 0; i < n; i++)
    acc[i] += in[i];
}

double
ds_stripe_phase_diff (double a, double b)
{
  double d = a - b;
  d -= floor (d + 0.5);
  return d;
}

void
ds_stripe_phase_column_sums (const DsImage *frame, guint x, guint y, guint cols, guint rows, double *sum,
                             guint32 *count)
{
  memset (sum, 0, sizeof *sum * cols);
  memset (count, 0, sizeof *count * cols);
  if (frame->type == DS_SAMPLE_F32) {
    for (guint j = y; j < y + rows; j++) {
      const float *p = ds_image_row (frame, j);
      for (guint i = 0; i < cols; i++)
        if (isfinite (p[x + i])) {
          sum[i] += p[x + i];
          count[i]++;
        }
    }
    return;
  }
  guint32 *acc = count; /* integer samples need no count until the end: every one is finite */
  for (guint y0 = y; y0 < y + rows; y0 += ROWS_PER_U32) {
    guint y1 = y0 + MIN (ROWS_PER_U32, y + rows - y0);
    for (guint j = y0; j < y1; j++) {
      const guint8 *row = ds_image_row (frame, j);
      if (frame->type == DS_SAMPLE_U16)
        add_row_u16 ((const guint16 *) row + x, acc, cols);
      else
        add_row_u8 (row + x, acc, cols);
    }
    for (guint i = 0; i < cols; i++)
      sum[i] += acc[i];
    memset (acc, 0, sizeof *acc * cols);
  }
  for (guint i = 0; i < cols; i++)
    count[i] = rows;
}

/* Solves the symmetric 3x3 system n * p = r and returns the inverse's diagonal in inv_diag.
 * FALSE when singular (e.g. a period of exactly 2 px: sin is zero at every pixel). */
static gboolean
solve3 (const double n[3][3], const double r[3], double p[3], double inv_diag[3])
{
  double a = n[0][0], b = n[0][1], c = n[0][2], d = n[1][1], e = n[1][2], f = n[2][2];
  /* Cofactors of a symmetric matrix. */
  double c00 = d * f - e * e, c01 = -(b * f - c * e), c02 = b * e - c * d;
  double c11 = a * f - c * c, c12 = -(a * e - b * c), c22 = a * d - b * b;
  double det = a * c00 + b * c01 + c * c02;
  double scale = fabs (a) * fabs (d) * fabs (f);
  if (!(fabs (det) > 1e-12 * scale) || !isfinite (det))
    return FALSE;
  double inv[3][3] = { { c00, c01, c02 }, { c01, c11, c12 }, { c02, c12, c22 } };
  for (int i = 0; i < 3; i++) {
    p[i] = (inv[i][0] * r[0] + inv[i][1] * r[1] + inv[i][2] * r[2]) / det;
    inv_diag[i] = inv[i][i] / det;
  }
  return TRUE;
}

gboolean
ds_stripe_phase_measure (const DsImage *frame, double period_px, const DsRegion *region,
                         DsStripePhase *out, GError **error)
{
  if (frame->type != DS_SAMPLE_U8 && frame->type != DS_SAMPLE_U16 && frame->type != DS_SAMPLE_F32) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_FORMAT, "stripe phase: unsupported sample type %d",
                 (int) frame->type);
    return FALSE;
  }
  DsRegion r = region ? *region : (DsRegion) { 0, 0, 0, 0 };
  if (r.x >= frame->width || r.y >= frame->height) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_INVALID_ARGUMENT,
                 "stripe phase: region origin (%u, %u) outside the %ux%u frame", r.x, r.y, frame->width,
                 frame->height);
    return FALSE;
  }
  if (r.width == 0)
    r.width = frame->width - r.x;
  if (r.height == 0)
    r.height = frame->height - r.y;
  if (r.width > frame->width - r.x || r.height > frame->height - r.y) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_INVALID_ARGUMENT,
                 "stripe phase: region %ux%u at (%u, %u) exceeds the %ux%u frame", r.width, r.height, r.x,
                 r.y, frame->width, frame->height);
    return FALSE;
  }
  if (!(period_px > 2.0) || !(period_px <= (double) r.width)) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_INVALID_ARGUMENT,
                 "stripe phase: period %g px must be > 2 and <= the region width %u", period_px, r.width);
    return FALSE;
  }
  guint periods = (guint) floor ((double) r.width / period_px);
  guint cols = (guint) lround ((double) periods * period_px);
  if (cols > r.width)
    cols = r.width;
  if (cols < 4) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_INVALID_ARGUMENT,
                 "stripe phase: only %u columns in whole periods of %g px; need at least 4", cols,
                 period_px);
    return FALSE;
  }

  g_autofree double *sum = g_new (double, cols);
  g_autofree guint32 *count = g_new (guint32, cols);
  ds_stripe_phase_column_sums (frame, r.x, r.y, cols, r.height, sum, count);
  /* The basis at each column, computed once for the fit and its residuals. */
  g_autofree double *cw = g_new (double, 2 * (gsize) cols);
  double *sw = cw + cols;

  /* Normal equations of profile(x) = m + c cos(wx) + s sin(wx). */
  double n[3][3] = { { 0 } }, rhs[3] = { 0 };
  guint used = 0;
  const double w = 2.0 * G_PI / period_px;
  for (guint i = 0; i < cols; i++) {
    guint32 k = count[i];
    if (k == 0)
      continue;
    double v = sum[i] / k;
    sum[i] = v; /* now the profile */
    double x = (double) (r.x + i);
    cw[i] = cos (w * x);
    sw[i] = sin (w * x);
    double basis[3] = { 1.0, cw[i], sw[i] };
    for (int a = 0; a < 3; a++) {
      rhs[a] += basis[a] * v;
      for (int b = 0; b < 3; b++)
        n[a][b] += basis[a] * basis[b];
    }
    used++;
  }
  double p[3], inv_diag[3];
  if (used < 4 || !solve3 (n, rhs, p, inv_diag)) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_INVALID_ARGUMENT,
                 "stripe phase: %u usable columns at period %g px do not determine a phase", used,
                 period_px);
    return FALSE;
  }
  /* Residuals in a second pass: sum v^2 - p.rhs would cancel catastrophically when the
   * (scattered) mean dwarfs the modulation. */
  double rss = 0;
  for (guint i = 0; i < cols; i++) {
    if (count[i] == 0)
      continue;
    double e = sum[i] - (p[0] + p[1] * cw[i] + p[2] * sw[i]);
    rss += e * e;
  }
  double sigma2 = rss / (double) (used - 3);
  double var_a = 0.5 * sigma2 * (inv_diag[1] + inv_diag[2]);
  /* Rounding error is the floor of the noise: a flat frame's amplitude of 1e-13 is not signal. */
  double floor_a = 1e-12 * (fabs (p[0]) + hypot (p[1], p[2]));
  var_a = MAX (var_a, floor_a * floor_a);

  DsStripePhase m = { 0 };
  m.mean = p[0];
  m.amplitude = hypot (p[1], p[2]);
  m.phase = atan2 (p[2], p[1]) / (2.0 * G_PI);
  m.phase -= floor (m.phase);
  if (m.phase >= 1.0)
    m.phase = 0.0;
  m.modulation = m.mean > 0 ? m.amplitude / m.mean : 0.0;
  /* Capped so that a noiseless synthetic frame still gives finite numbers (JSON-safe). */
  const double snr_cap = 1e6;
  m.snr = var_a > 0 ? MIN (m.amplitude / sqrt (var_a), snr_cap) : 0.0;
  m.phase_sigma = m.snr > 0 ? 1.0 / (2.0 * G_PI * m.snr) : 0.5;
  m.confidence = 1.0 - exp (-0.5 * m.snr * m.snr);
  m.reliable = m.snr >= DS_STRIPE_PHASE_MIN_SNR;
  m.columns_used = used;
  m.periods_used = periods;
  *out = m;
  return TRUE;
}
