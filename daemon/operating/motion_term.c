#include "daemon/operating/motion_term.h"

#include <gio/gio.h>
#include <math.h>
#include <string.h>

void
ds_motion_frame_times (const DsRigTiming *timing, guint width, guint height, guint n, guint m, double exposure_us,
                       double *times_s)
{
  /* The model's frame and settle times read off it as differences, so the two stay one model. */
  double one = ds_rig_timing_set_ms (timing, width, height, 1, 1, exposure_us, FALSE);
  double frame_ms = ds_rig_timing_set_ms (timing, width, height, 1, 2, exposure_us, FALSE) - one;
  double settle_ms = one - frame_ms;
  for (guint k = 0; k < n; k++)
    for (guint j = 0; j < m; j++)
      times_s[k * m + j] = (k * (settle_ms + m * frame_ms) + settle_ms + j * frame_ms) / 1e3 +
                           (timing->trigger_overhead_us + exposure_us / 2) / 1e6;
}

double
ds_motion_kappa (DsEstimator estimator)
{
  switch (estimator) {
  case DS_ESTIMATOR_SINE:
    /* (1/12 + 1/(2 pi^2)) / (1/4) */
    return 4.0 * (1.0 / 12.0 + 1.0 / (2.0 * G_PI * G_PI));
  case DS_ESTIMATOR_MAXMIN:
    /* (3/8) / (1/4) */
    return 1.5;
  default:
    return NAN;
  }
}

/* T at x - s along a row, linear between pixels, the edge pixel beyond the image. */
static inline double
shifted (const float *row, guint width, double x)
{
  if (x <= 0)
    return row[0];
  if (x >= width - 1)
    return row[width - 1];
  guint i = (guint) x;
  double f = x - i;
  return row[i] + f * ((double) row[i + 1] - row[i]);
}

gboolean
ds_motion_term (const DsImage *t, double speed, const double *times_s, guint n_times, DsEstimator estimator,
                double *term, GError **error)
{
  if (!t || t->type != DS_SAMPLE_F32 || !isfinite (speed) || n_times == 0) {
    g_set_error (error, G_IO_ERROR, G_IO_ERROR_INVALID_ARGUMENT,
                 "motion term: needs an f32 image, a finite speed and at least one frame time");
    return FALSE;
  }
  for (guint k = 0; k < n_times; k++)
    if (!isfinite (times_s[k])) {
      g_set_error (error, G_IO_ERROR, G_IO_ERROR_INVALID_ARGUMENT, "motion term: frame %u's time is not finite", k);
      return FALSE;
    }
  /* The middle between the first and the last frame: where the truth is taken. */
  double t_mid = (times_s[0] + times_s[n_times - 1]) / 2;
  double departure = 0, light = 0;
  for (guint y = 0; y < t->height; y++) {
    const float *row = ds_image_row (t, y);
    for (guint x = 0; x < t->width; x++) {
      double v = row[x], d = 0;
      for (guint k = 0; k < n_times; k++) {
        double e = shifted (row, t->width, x - speed * (times_s[k] - t_mid)) - v;
        d += e * e;
      }
      departure += d / n_times;
      light += v * v;
    }
  }
  if (!(light > 0)) {
    g_set_error (error, G_IO_ERROR, G_IO_ERROR_INVALID_ARGUMENT, "motion term: the image has no light");
    return FALSE;
  }
  *term = sqrt (ds_motion_kappa (estimator) * departure / light);
  return TRUE;
}

gboolean
ds_motion_apply (DsOperatingPoint *p, double speed_px_s, double term, guint64 motion_pixels, const char **why)
{
  const char *reason = NULL;
  if (isnan (speed_px_s)) {
    if (motion_pixels > 0)
      reason = "motion seen and no speed declared: the prediction assumes a still scene";
  } else if (isnan (term)) {
    reason = "a speed was declared, and this estimator's motion error has no model";
  } else {
    p->predicted_error = hypot (p->predicted_error, term);
    if (isfinite (p->predicted_error_upper))
      p->predicted_error_upper = hypot (p->predicted_error_upper, term);
  }
  if (why)
    *why = reason;
  if (!reason)
    return FALSE;
  /* Nothing bounds the motion's error from above: such a point never meets a target on its upper
   * end. */
  p->lower_bound = TRUE;
  p->predicted_error_upper = INFINITY;
  p->upper_bounded = FALSE;
  return TRUE;
}

struct DsMotionTable {
  guint width, n_rows;
  float *rows;      /* n_rows x width, the kept rows */
  float *var;       /* their noise variance; NULL: none */
  double light;     /* sum T^2 over the kept rows, less the noise */
  double *edge;     /* prefix sums over j of sum over rows of (T[j] - T[j - 1])^2 less its noise (edge[0] = 0) */
  double *at;       /* at[i + width]: D(i) for i in [-width, width], NAN until computed */
};

DsMotionTable *
ds_motion_table_new (const DsImage *t, const DsImage *noise_var, GError **error)
{
  if (!t || t->type != DS_SAMPLE_F32 || t->width < 2 ||
      (noise_var && (noise_var->type != DS_SAMPLE_F32 || noise_var->width != t->width ||
                     noise_var->height != t->height))) {
    g_set_error (error, G_IO_ERROR, G_IO_ERROR_INVALID_ARGUMENT,
                 "motion term: needs an f32 image at least 2 px wide and, if any, an f32 noise variance of its size");
    return NULL;
  }
  g_autoptr (DsMotionTable) m = g_new0 (DsMotionTable, 1);
  m->width = t->width;
  m->n_rows = MIN (t->height, DS_MOTION_TABLE_ROWS);
  m->rows = g_new (float, (gsize) m->n_rows * m->width);
  m->var = noise_var ? g_new (float, (gsize) m->n_rows * m->width) : NULL;
  m->edge = g_new0 (double, m->width);
  m->at = g_new (double, 2 * (gsize) m->width + 1);
  for (guint i = 0; i <= 2 * m->width; i++)
    m->at[i] = NAN;
  for (guint r = 0; r < m->n_rows; r++) {
    /* Evenly spaced: the middle row of each band. */
    guint y = (guint) (((guint64) 2 * r + 1) * t->height / (2 * m->n_rows));
    const float *src = ds_image_row (t, y);
    float *dst = m->rows + (gsize) r * m->width;
    memcpy (dst, src, m->width * sizeof (float));
    float *var = m->var ? m->var + (gsize) r * m->width : NULL;
    if (var)
      memcpy (var, ds_image_row (noise_var, y), m->width * sizeof (float));
    for (guint x = 0; x < m->width; x++) {
      /* E[T^2] = T_true^2 + var: the noise is taken out of the light and of every difference. */
      m->light += (double) src[x] * src[x] - (var ? var[x] : 0);
      if (x > 0) {
        double d = (double) src[x] - src[x - 1];
        m->edge[x] += d * d - (var ? (double) var[x] + var[x - 1] : 0);
      }
    }
  }
  if (!(m->light > 0)) {
    g_set_error (error, G_IO_ERROR, G_IO_ERROR_INVALID_ARGUMENT, "motion term: the image has no light beyond its noise");
    return NULL;
  }
  for (guint j = 1; j < m->width; j++)
    m->edge[j] += m->edge[j - 1];
  return g_steal_pointer (&m);
}

void
ds_motion_table_free (DsMotionTable *m)
{
  if (!m)
    return;
  g_free (m->rows);
  g_free (m->var);
  g_free (m->edge);
  g_free (m->at);
  g_free (m);
}

/* D(i), a whole-pixel shift, less its noise's expectation: a pixel compared with another carries
 * both their variances; one the border clamps onto itself, none. */
static double
departure_at (DsMotionTable *m, gint i)
{
  gint w = (gint) m->width;
  i = CLAMP (i, -w, w);
  double *slot = &m->at[i + w];
  if (!isnan (*slot))
    return *slot;
  double d = 0;
  for (guint r = 0; r < m->n_rows; r++) {
    const float *row = m->rows + (gsize) r * m->width;
    const float *var = m->var ? m->var + (gsize) r * m->width : NULL;
    for (gint x = 0; x < w; x++) {
      gint j = CLAMP (x - i, 0, w - 1);
      double e = (double) row[j] - row[x];
      d += e * e;
      if (var && j != x)
        d -= (double) var[j] + var[x];
    }
  }
  *slot = d;
  return d;
}

/* E(i): the sum over rows and x of (T[clamp (x - i)] - T[clamp (x - i - 1)])^2, the neighbour
 * differences of the columns j = x - i in [max (1, -i), min (w - 1, w - 1 - i)] (elsewhere both
 * clamp onto the same pixel). */
static double
edge_between (const DsMotionTable *m, gint i)
{
  gint w = (gint) m->width;
  gint lo = MAX (1, -i), hi = MIN (w - 1, w - 1 - i);
  return hi < lo ? 0 : m->edge[hi] - m->edge[lo - 1];
}

double
ds_motion_table_term (DsMotionTable *m, double speed, const double *times_s, guint n_times, DsEstimator estimator)
{
  double kappa = ds_motion_kappa (estimator);
  if (isnan (kappa) || n_times == 0 || !isfinite (speed))
    return NAN;
  double t_mid = (times_s[0] + times_s[n_times - 1]) / 2, sum = 0;
  for (guint k = 0; k < n_times; k++) {
    double s = speed * (times_s[k] - t_mid);
    double fl = floor (s), f = s - fl;
    gint i = (gint) CLAMP (fl, -(double) m->width, (double) m->width);
    /* Beyond the width every pixel is clamped onto the border's: D no longer changes. */
    double d = departure_at (m, i);
    if (f > 0 && ABS (i) < (gint) m->width)
      d = (1 - f) * d + f * departure_at (m, i + 1) - f * (1 - f) * edge_between (m, i);
    sum += MAX (0.0, d);
  }
  return sqrt (kappa * sum / n_times / m->light);
}
