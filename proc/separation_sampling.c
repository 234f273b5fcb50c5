/* The sampling precondition and the estimators' systematic error from the stripe geometry
 * (docs/estimators.md, "Sampling precondition"): a noise-free model of what each pixel sees in
 * each phase, the pattern blurred by a Gaussian and integrated over the pixel's aperture, fed
 * through the estimators' own formulas. */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "proc/harmonic_gain.h"
#include "proc/proc_error.h"
#include "proc/separation_internal.h"

/* The blurred edge is within DS_SAMPLING_TOLERANCE / 2 of its level at z sigma: Phi(-z) = 0.005. */
#define EDGE_Z 2.5758293035489004
/* Pixel positions across one period for the statistics. */
#define N_POSITIONS 512u

static double
normal_cdf (double z)
{
  return 0.5 * erfc (-z / G_SQRT2);
}

/* Integral of Phi(t / sigma) dt from -inf to x; a step (max (x, 0)) when sigma = 0. */
static double
cdf_integral (double x, double sigma)
{
  if (sigma <= 0)
    return x > 0 ? x : 0;
  double z = x / sigma;
  return sigma * (z * normal_cdf (z) + exp (-0.5 * z * z) / sqrt (2 * G_PI));
}

/* Lit fraction (0..1, black level aside) seen by a pixel whose centre is d pixels from the
 * centre of a lit stripe: the square pattern blurred and integrated over the aperture. */
static double
square_profile (double d, double period, double duty, double sigma, double aperture)
{
  double half = 0.5 * duty * period, hw = 0.5 * aperture;
  double reach = half + hw + 9 * sigma;
  d -= period * floor (d / period + 0.5);
  long jmax = (long) ceil (reach / period) + 1;
  double s = 0;
  for (long j = -jmax; j <= jmax; j++) {
    double c = d - (double) j * period;
    if (fabs (c) > reach)
      continue;
    if (hw < 1e-9) {
      if (sigma <= 0)
        s += fabs (c) < half ? 1.0 : fabs (c) == half ? 0.5 : 0.0;
      else
        s += normal_cdf ((c + half) / sigma) - normal_cdf ((c - half) / sigma);
    } else {
      s += (cdf_integral (c + hw + half, sigma) - cdf_integral (c - hw + half, sigma) -
            cdf_integral (c + hw - half, sigma) + cdf_integral (c - hw - half, sigma)) /
           aperture;
    }
  }
  return CLAMP (s, 0.0, 1.0);
}

static double
sinc (double x)
{
  return fabs (x) < 1e-12 ? 1.0 : sin (G_PI * x) / (G_PI * x);
}

double
ds_sampling_profile (const DsSeparationParams *p, double d)
{
  const DsStripeGeometry *g = &p->geometry;
  double period = g->period_px;
  if (p->pattern == DS_PATTERN_SINE) {
    double gain = exp (-2 * G_PI * G_PI * g->edge_blur_px * g->edge_blur_px / (period * period)) *
                  sinc (g->pixel_aperture / period);
    return 0.5 * (1 + gain * cos (2 * G_PI * d / period));
  }
  return square_profile (d, period, p->duty, g->edge_blur_px, g->pixel_aperture);
}

void
ds_robust_windows (const DsSeparationParams *p, guint *len_hi, guint *len_lo)
{
  guint n = p->n_phases;
  double duty = p->pattern == DS_PATTERN_SINE ? 0.5 : p->duty;
  const DsStripeGeometry *g = &p->geometry;
  /* Without the geometry: a margin of one phase on each side for blurred edges. */
  double step_hi = ceil (duty * n - 1e-9) - 2, step_lo = ceil ((1 - duty) * n - 1e-9) - 2;
  double hi = step_hi, lo = step_lo;
  if (g->period_px > 0) {
    /* Windows centred on the lit (unlit) run reach L/2 phase steps from its centre; the run
     * of fully lit phases reaches (aP - e)/2 pixels, e the edge's extent over the pixel. The
     * edge is fixed in pixels while a phase step shrinks as P/N, so only this margin keeps
     * robust off the edges at every N. */
    double e = g->pixel_aperture + 2 * EDGE_Z * g->edge_blur_px;
    hi = floor ((duty - e / g->period_px) * n + 1e-9);
    lo = floor ((1 - duty - e / g->period_px) * n + 1e-9);
    /* An unknown blur is not a sharp edge: keep the one-phase margin as well. */
    if (!g->edge_blur_known) {
      hi = MIN (hi, step_hi);
      lo = MIN (lo, step_lo);
    }
  }
  *len_hi = (guint) MAX (1.0, hi);
  *len_lo = (guint) MAX (1.0, lo);
}

void
ds_robust_tables (guint n, guint len_hi, guint len_lo, double *c_hi, double *s_hi, double *c_lo,
                  double *s_lo)
{
  /* Window j of the lit level covers phases j .. j + L - 1, centred at j + (L - 1)/2; the one
   * nearest the pixel's harmonic phase k_c maximises cs cos + sn sin at that centre. The unlit
   * window is centred half a period away. */
  double o_hi = (len_hi - 1) / 2.0, o_lo = (len_lo - 1) / 2.0;
  for (guint j = 0; j < n; j++) {
    double t_hi = 2 * G_PI * (j + o_hi) / n, t_lo = 2 * G_PI * (j + o_lo) / n - G_PI;
    c_hi[j] = cos (t_hi);
    s_hi[j] = sin (t_hi);
    c_lo[j] = cos (t_lo);
    s_lo[j] = sin (t_lo);
  }
}

guint
ds_robust_start (double cs, double sn, const double *c_tab, const double *s_tab, guint n)
{
  guint best = 0;
  double best_v = -INFINITY;
  for (guint j = 0; j < n; j++) {
    double v = cs * c_tab[j] + sn * s_tab[j];
    if (v > best_v) {
      best_v = v;
      best = j;
    }
  }
  return best;
}

typedef struct {
  guint n, len_hi, len_lo;
  double m, h;
  double *v, *cos_k, *sin_k, *c_hi, *s_hi, *c_lo, *s_lo;
} Model;

static void
model_init (Model *mo, const DsSeparationParams *p)
{
  guint n = p->n_phases;
  mo->n = n;
  mo->m = ds_pattern_mean (p->pattern, p->duty, p->black_level);
  mo->h = p->harmonic_gain > 0 ? p->harmonic_gain
                               : ds_harmonic_gain_theory (p->pattern, p->duty, p->black_level);
  ds_robust_windows (p, &mo->len_hi, &mo->len_lo);
  mo->v = g_new (double, 7 * (gsize) n);
  mo->cos_k = mo->v + n;
  mo->sin_k = mo->v + 2 * n;
  mo->c_hi = mo->v + 3 * n;
  mo->s_hi = mo->v + 4 * n;
  mo->c_lo = mo->v + 5 * n;
  mo->s_lo = mo->v + 6 * n;
  for (guint k = 0; k < n; k++) {
    mo->cos_k[k] = cos (2 * G_PI * k / n);
    mo->sin_k[k] = sin (2 * G_PI * k / n);
  }
  ds_robust_tables (n, mo->len_hi, mo->len_lo, mo->c_hi, mo->s_hi, mo->c_lo, mo->s_lo);
}

static void
model_clear (Model *mo)
{
  g_free (mo->v);
}

/* One pixel whose centre lies d0 pixels from the centre of a phase-0 stripe, Ld = 1, Lg = 0:
 * the estimator's Ld and Lg, and whether the levels it uses were fully lit and fully dark. */
static void
model_pixel (const Model *mo, const DsSeparationParams *p, double d0, double *ld, double *lg,
             gboolean *undersampled)
{
  guint n = mo->n;
  double b = p->black_level, period = p->geometry.period_px;
  double s_max = -INFINITY, s_min = INFINITY, cs = 0, sn = 0, sum = 0;
  for (guint k = 0; k < n; k++) {
    double s = ds_sampling_profile (p, d0 - (double) k * period / n);
    mo->v[k] = s;
    s_max = MAX (s_max, s);
    s_min = MIN (s_min, s);
    cs += s * mo->cos_k[k];
    sn += s * mo->sin_k[k];
    sum += s;
  }
  double hi = s_max, lo = s_min;
  switch (p->estimator) {
  case DS_ESTIMATOR_SINE: {
    double amp = 2.0 / n * sqrt (cs * cs + sn * sn) * (1 - b);
    *ld = amp / mo->h;
    *lg = (b + (1 - b) * sum / n) / mo->m - *ld;
    *undersampled = FALSE;
    return;
  }
  case DS_ESTIMATOR_ROBUST: {
    guint j_hi = ds_robust_start (cs, sn, mo->c_hi, mo->s_hi, n);
    guint j_lo = ds_robust_start (cs, sn, mo->c_lo, mo->s_lo, n);
    hi = lo = 0;
    for (guint j = 0; j < mo->len_hi; j++)
      hi += mo->v[(j_hi + j) % n];
    for (guint j = 0; j < mo->len_lo; j++)
      lo += mo->v[(j_lo + j) % n];
    hi /= mo->len_hi;
    lo /= mo->len_lo;
    break;
  }
  default:
    break;
  }
  /* values with the black level: b + (1 - b) s */
  double ld_est = (1 - b) * (hi - lo) / (1 - b);
  *ld = ld_est;
  *lg = (b + (1 - b) * lo - b * ld_est) / mo->m;
  *undersampled = hi < 1 - DS_SAMPLING_TOLERANCE || lo > DS_SAMPLING_TOLERANCE;
}

gboolean
ds_separation_check_sampling (const DsSeparationParams *p, DsSamplingCheck *out, GError **error)
{
  memset (out, 0, sizeof *out);
  guint n = p->n_phases;
  const DsStripeGeometry *g = &p->geometry;
  gboolean square = p->pattern == DS_PATTERN_SQUARE;
  gboolean extremes = p->estimator == DS_ESTIMATOR_MAXMIN || p->estimator == DS_ESTIMATOR_ROBUST;
  out->applies = square && extremes;
  ds_robust_windows (p, &out->robust_lit_window, &out->robust_unlit_window);
  if (!square && extremes)
    g_snprintf (out->warning, sizeof out->warning,
                "%s assumes square stripes; on sine stripes it sees a sampled cosine and "
                "underestimates Ld (use the sine estimator)",
                ds_estimator_name (p->estimator));
  double e = g->period_px > 0 ? g->pixel_aperture + 2 * EDGE_Z * g->edge_blur_px : 0;
  double duty = square ? p->duty : 0.5;
  out->lit_phases = (duty - (g->period_px > 0 ? e / g->period_px : 0)) * n;
  out->unlit_phases = (1 - duty - (g->period_px > 0 ? e / g->period_px : 0)) * n;
  out->affected_fraction = out->ld_error_mean = out->ld_error_worst = NAN;
  out->lg_error_mean = out->lg_error_worst = NAN;

  if (!(g->period_px > 0)) {
    double lit = duty * n, unlit = (1 - duty) * n;
    if (out->applies && (lit < 1 - 1e-9 || unlit < 1 - 1e-9)) {
      g_snprintf (out->refusal, sizeof out->refusal,
                  "%s needs every pixel fully lit in one phase and dark in another: aN = %.3g "
                  "and (1 - a)N = %.3g must be >= 1 (a = %g, N = %u); use more phases, or give "
                  "the stripe period so that the pixels it misses are flagged",
                  ds_estimator_name (p->estimator), lit, unlit, p->duty, n);
      g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_PRECONDITION, "%s", out->refusal);
      return FALSE;
    }
    return TRUE;
  }

  /* The model costs N pattern evaluations per position; a long set samples the period finely
   * itself, so its statistics need fewer positions. */
  guint positions = CLAMP (65536u / n, 64u, N_POSITIONS);
  Model mo;
  model_init (&mo, p);
  guint affected = 0;
  double sum_ld = 0, sum_lg = 0, worst_ld = 0, worst_lg = 0;
  for (guint i = 0; i < positions; i++) {
    double d0 = (i + 0.5) / positions * g->period_px;
    double ld, lg;
    gboolean under;
    model_pixel (&mo, p, d0, &ld, &lg, &under);
    affected += under;
    sum_ld += ld - 1;
    sum_lg += lg;
    if (fabs (ld - 1) > fabs (worst_ld))
      worst_ld = ld - 1;
    if (fabs (lg) > fabs (worst_lg))
      worst_lg = lg;
  }
  model_clear (&mo);
  out->affected_fraction = (double) affected / positions;
  out->ld_error_mean = sum_ld / positions;
  out->lg_error_mean = sum_lg / positions;
  out->ld_error_worst = worst_ld;
  out->lg_error_worst = worst_lg;
  if (out->applies && affected == positions) {
    g_snprintf (out->refusal, sizeof out->refusal,
                "%s: no pixel is fully lit in one phase and fully dark in another: with period "
                "%g px, edge blur %g px and pixel aperture %g px the stripes light (a - e/P)N = "
                "%.3g and darken (1 - a - e/P)N = %.3g phases (a = %g, N = %u; need >= 1); use "
                "more phases, a coarser period or the sine estimator",
                ds_estimator_name (p->estimator), g->period_px, g->edge_blur_px, g->pixel_aperture,
                out->lit_phases, out->unlit_phases, p->duty, n);
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_PRECONDITION, "%s", out->refusal);
    return FALSE;
  }
  return TRUE;
}

guint64
ds_sampling_column_flags (const DsSeparationParams *p, double offset_cycles, guint width,
                          guint8 *flags)
{
  Model mo;
  model_init (&mo, p);
  guint64 affected = 0;
  double period = p->geometry.period_px;
  for (guint x = 0; x < width; x++) {
    double ld, lg;
    gboolean under;
    model_pixel (&mo, p, (double) x - offset_cycles * period, &ld, &lg, &under);
    flags[x] = under ? DS_MASK_UNDERSAMPLED : 0;
    affected += under;
  }
  model_clear (&mo);
  return affected;
}
