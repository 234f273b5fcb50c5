#include "daemon/operating/scene_probe_transfer.h"

#include <math.h>
#include <string.h>

#include "daemon/operating/cone_kernel.h"

/* The narrow kernel's MTF at the frequency 1 / x, k = 2 pi b / x: (1 + k^2 / nu)^-nu
 * (scene_probe.h: why this form and not a Gaussian). */
double
ds_probe_kernel_mtf (double b, double nu, double x)
{
  double k = 2 * G_PI * b / x;
  return x > 0 ? pow (1 + k * k / nu, -nu) : 0.0;
}

/* Amplitude of harmonic n of the model's difference profile, fitted the way the frames are (same
 * columns, same fit), so that the sampling of integer periods aliases alike. */
double
ds_probe_model_gain (const DsStripeModel *g, double period, double sigma, double offset, guint width, guint n)
{
  DsStripeModel m = *g;
  m.period_px = period;
  m.blur_px = sigma;
  g_autofree double *profile = g_new (double, width);
  for (guint x = 0; x < width; x++)
    profile[x] = ds_stripe_value (&m, x, offset) - ds_stripe_value (&m, x, offset + 0.5);
  DsStripeHarmonics h;
  if (!ds_stripe_harmonics_fit (profile, NULL, 0, width, period, n, &h, NULL) || h.n_harmonics < n)
    return 0;
  return h.amplitude[n];
}

/* Solves the k x k system a z = b in place (Gaussian elimination, partial pivoting); FALSE when
 * singular to rounding (e.g. a slope over equations that all share one x). */
static gboolean
solve_small (double a[3][3], double *b, guint k)
{
  double scale = 0;
  for (guint r = 0; r < k; r++)
    for (guint c = 0; c < k; c++)
      scale = MAX (scale, fabs (a[r][c]));
  for (guint c = 0; c < k; c++) {
    guint piv = c;
    for (guint r = c + 1; r < k; r++)
      if (fabs (a[r][c]) > fabs (a[piv][c]))
        piv = r;
    if (!(fabs (a[piv][c]) > 1e-9 * scale))
      return FALSE;
    for (guint j = 0; j < k; j++) {
      double t = a[c][j];
      a[c][j] = a[piv][j];
      a[piv][j] = t;
    }
    double t = b[c];
    b[c] = b[piv];
    b[piv] = t;
    for (guint r = 0; r < k; r++) {
      if (r == c)
        continue;
      double f = a[r][c] / a[c][c];
      for (guint j = c; j < k; j++)
        a[r][j] -= f * a[c][j];
      b[r] -= f * b[c];
    }
  }
  for (guint c = 0; c < k; c++)
    b[c] /= a[c][c];
  return TRUE;
}

/* Weighted least squares of log (A / G) = log Ld + alpha x + t g, x = Q / n, alpha >= 0; alpha is
 * free only when the equations span two periods. g (NULL: none) is how log G of each equation
 * moves when the blur is off by DS_PROBE_BLUR_UNCERTAINTY_PX: one error common to all the
 * equations, so it is a parameter of the fit, with a unit normal prior on t, not a variance per
 * equation (a blur slightly wider than modelled lowers every higher harmonic at once, the more
 * the more the blur has erased it, which a transfer fitted without t reads as a rise with x). */
static DsProbeSolution
solve_linear (const double *y, const double *w, const double *g, const DsProbeEquation *eq, guint n_eq, gboolean leak)
{
  double x[DS_PROBE_MAX_EQUATIONS];
  for (guint i = 0; i < n_eq; i++)
    x[i] = eq[i].period / eq[i].n;
  DsProbeSolution s = { 0 };
  double t = 0;
  /* Parameters: log Ld, then alpha when free, then t when g is given. */
  for (int attempt = 0; attempt < 2; attempt++) {
    gboolean free_alpha = leak && attempt == 0;
    guint ia = free_alpha ? 1 : 0, it = ia + 1, k = g ? it + 1 : ia + 1;
    double a[3][3] = { { 0 } }, b[3] = { 0 };
    for (guint i = 0; i < n_eq; i++) {
      double z[3] = { 1, 0, 0 };
      if (free_alpha)
        z[ia] = x[i];
      if (g)
        z[it] = g[i];
      for (guint r = 0; r < k; r++) {
        b[r] += w[i] * z[r] * y[i];
        for (guint c = 0; c < k; c++)
          a[r][c] += w[i] * z[r] * z[c];
      }
    }
    if (g)
      a[it][it] += 1;
    if (!solve_small (a, b, k)) {
      if (free_alpha)
        continue;
      break;
    }
    s.log_ld = b[0];
    s.alpha = free_alpha ? b[ia] : 0;
    t = g ? b[it] : 0;
    if (s.alpha >= 0)
      break;
    s.alpha = 0;
  }
  for (guint i = 0; i < n_eq; i++) {
    double r = y[i] - (s.log_ld + s.alpha * x[i] + (g ? t * g[i] : 0));
    s.residual += w[i] * r * r;
  }
  return s;
}

/* How far log G of an equation moves when the blur is off by DS_PROBE_BLUR_UNCERTAINTY_PX
 * (INFINITY when the harmonic then vanishes). */
double
ds_probe_gain_shift (const DsStripeModel *g, const DsProbeEquation *e, double sigma, double G, guint width)
{
  double Gb = ds_probe_model_gain (g, e->period, sigma + DS_PROBE_BLUR_UNCERTAINTY_PX, e->offset, width, e->n);
  return Gb > 0 && G > 0 ? log (G / Gb) : INFINITY;
}

/* The leak line at one blur: log A / G has the fit's variance and a 2 % floor for what the model
 * leaves out. With blur_uncertain, the blur's error is a parameter of the fit (solve_linear);
 * without, as in the blur search that moves sigma itself, it is not. */
static void
prepare (const DsStripeModel *g, const DsProbeEquation *eq, guint n_eq, double sigma, guint width,
         gboolean blur_uncertain, double *y, double *w, double *shift)
{
  for (guint i = 0; i < n_eq; i++) {
    shift[i] = 0;
    double G = ds_probe_model_gain (g, eq[i].period, sigma, eq[i].offset, width, eq[i].n);
    double rel = eq[i].sigma / eq[i].amplitude;
    y[i] = G > 0 ? log (eq[i].amplitude / G) : 0;
    w[i] = G > 0 ? 1.0 / (rel * rel + 0.02 * 0.02) : 0;
    if (blur_uncertain) {
      shift[i] = ds_probe_gain_shift (g, &eq[i], sigma, G, width);
      if (!isfinite (shift[i]))
        w[i] = shift[i] = 0;
    }
  }
}

DsProbeSolution
ds_probe_solve_at (const DsStripeModel *g, const DsProbeEquation *eq, guint n_eq, double sigma, guint width,
                   gboolean two_periods, gboolean blur_uncertain)
{
  double y[DS_PROBE_MAX_EQUATIONS] = { 0 }, w[DS_PROBE_MAX_EQUATIONS] = { 0 }, shift[DS_PROBE_MAX_EQUATIONS] = { 0 };
  prepare (g, eq, n_eq, sigma, width, blur_uncertain, y, w, shift);
  return solve_linear (y, w, blur_uncertain ? shift : NULL, eq, n_eq, two_periods);
}

gboolean
ds_probe_fit_cone (const DsStripeModel *g, const DsProbeEquation *eq, guint n_eq, double sigma, guint width,
                   double total, double ld_line, DsConeFit *out)
{
  double y[DS_PROBE_MAX_EQUATIONS] = { 0 }, w[DS_PROBE_MAX_EQUATIONS] = { 0 }, shift[DS_PROBE_MAX_EQUATIONS] = { 0 };
  double x[DS_PROBE_MAX_EQUATIONS] = { 0 };
  prepare (g, eq, n_eq, sigma, width, TRUE, y, w, shift);
  for (guint i = 0; i < n_eq; i++)
    x[i] = eq[i].period / eq[i].n;
  if (!ds_cone_kernel_fit (x, y, w, shift, n_eq, total, g->period_px, out))
    return FALSE;
  return out->seen && ds_cone_kernel_mtf (out->radius_px, g->period_px) >= 0.5 && out->ld < ld_line;
}

/* The narrow kernel's term (scene_probe.h): beta and w on a grid, Ld, alpha and the blur's error
 * linear at each. Only kernels whose MTF changes within the x the harmonics span can be told from
 * Ld (all at 1) or from nothing (all at 0): from 0.9 at the finest x to 0.1 at the coarsest; and
 * only kernels narrow against the period (MTF >= 1/2 at P): a wider one is the small-angle
 * line's, whose rise with x the harmonics below P follow, and a kernel term fitted to it
 * over-reads the leak by more than the line under-reads it.
 * FALSE when none explains the harmonics DS_PROBE_NARROW_MIN_CHI2 better than the line alone. */
gboolean
ds_probe_fit_narrow (const DsStripeModel *g, const DsProbeEquation *eq, guint n_eq, double sigma, guint width,
                     double period, const DsProbeSolution *line, DsProbeNarrowFit *out)
{
  double y[DS_PROBE_MAX_EQUATIONS] = { 0 }, w[DS_PROBE_MAX_EQUATIONS] = { 0 }, shift[DS_PROBE_MAX_EQUATIONS] = { 0 };
  double x[DS_PROBE_MAX_EQUATIONS], x_min = INFINITY, x_max = 0;
  prepare (g, eq, n_eq, sigma, width, TRUE, y, w, shift);
  for (guint i = 0; i < n_eq; i++) {
    x[i] = eq[i].period / eq[i].n;
    if (w[i] > 0) {
      x_min = MIN (x_min, x[i]);
      x_max = MAX (x_max, x[i]);
    }
  }
  out->s = *line;
  out->beta = out->width = out->shape = 0;
  if (!(x_max > x_min * 1.5))
    return FALSE;
  double lo = x_min / (6 * G_PI), hi = MIN (3 * x_max, period) / (2 * G_PI);
  double best = INFINITY;
  gboolean found = FALSE;
  static const double shapes[] = { 1, 2 }; /* scene_probe.h: why these */
  for (guint sh = 0; sh < G_N_ELEMENTS (shapes); sh++)
    for (double kw = lo; kw <= hi; kw *= 1.06)
      for (double beta = 0.005; beta <= 20; beta *= 1.08) {
        double yy[DS_PROBE_MAX_EQUATIONS];
        for (guint i = 0; i < n_eq; i++)
          yy[i] = y[i] - log1p (beta * ds_probe_kernel_mtf (kw, shapes[sh], x[i]));
        DsProbeSolution so = solve_linear (yy, w, shift, eq, n_eq, TRUE);
        if (so.residual < best) {
          best = so.residual;
          out->s = so;
          out->beta = beta;
          out->width = kw;
          out->shape = shapes[sh];
        }
      }
  found = best < line->residual - DS_PROBE_NARROW_MIN_CHI2;
  return found;
}

guint
ds_probe_collect_equations (const DsStripeHarmonics *fit, double period, const DsStripeModel *g, guint width,
                            DsProbeEquation *eq, guint n_eq)
{
  double offset = fit->phase[1];
  double g1 = ds_probe_model_gain (g, period, 0, offset, width, 1);
  for (guint n = 1; n <= fit->n_harmonics && n_eq < DS_PROBE_MAX_EQUATIONS; n += 2) {
    double a = fit->amplitude[n];
    if (period / n < 2.5 || !(a > 4 * fit->sigma_amplitude))
      continue;
    if (n > 1 && ds_probe_model_gain (g, period, 0, offset, width, n) < 0.03 * g1)
      continue;
    eq[n_eq++] = (DsProbeEquation){ .period = period, .n = n, .amplitude = a, .sigma = fit->sigma_amplitude,
                                    .offset = offset };
  }
  return n_eq;
}

/* How far Ld, read from the first harmonic at the period P, can be off as a share of it: the
 * harmonic's noise and how far its gain moves for the blur's uncertainty (narrow_verdict () in scene_probe.c).
 * 0 when the fit has no first harmonic at P. */
double
ds_probe_ld_uncertainty (const DsProbeEquation *eq, guint n_eq, const DsStripeModel *g, double sigma, guint width)
{
  for (guint i = 0; i < n_eq; i++) {
    if (eq[i].n != 1 || fabs (eq[i].period - g->period_px) > 1e-9 * g->period_px)
      continue;
    double G = ds_probe_model_gain (g, eq[i].period, sigma, eq[i].offset, width, 1);
    double shift = ds_probe_gain_shift (g, &eq[i], sigma, G, width), rel = eq[i].sigma / eq[i].amplitude;
    return isfinite (shift) && isfinite (rel) ? sqrt (shift * shift + rel * rel) : 0;
  }
  return 0;
}

/* 1 - T for the bound's kernel, (1 + 2 k^2)^-1/2 (scene_probe.h), without cancellation at small k. */
static double
lost_share (double k)
{
  return -expm1 (-0.5 * log1p (2 * k * k));
}

/* ds_scene_probe_worst_case ()'s lower end of Ld (scene_probe.h: the physics and its limit) from
 * the first harmonics at the finest and the coarsest period the fit used, the fit's Ld and the
 * mean's M = Ld + Lg. */
void
ds_probe_direct_interval (const DsProbeEquation *eq, guint n_eq, const DsStripeModel *g, double sigma, guint width,
                          double ld_fit, double total, DsProbeDirectInterval *out)
{
  memset (out, 0, sizeof *out);
  out->ratio = 1;
  const DsProbeEquation *f = NULL, *c = NULL;
  for (guint i = 0; i < n_eq; i++) {
    if (eq[i].n != 1)
      continue;
    if (!f || eq[i].period < f->period)
      f = &eq[i];
    if (!c || eq[i].period > c->period)
      c = &eq[i];
  }
  if (!f || !c || !(c->period > 1.01 * f->period) || !(ld_fit > 0) || !(total > 0))
    return;
  double gf = ds_probe_model_gain (g, f->period, sigma, f->offset, width, 1);
  double gc = ds_probe_model_gain (g, c->period, sigma, c->offset, width, 1);
  if (!(gf > 0 && gc > 0))
    return;
  out->computed = TRUE;
  double af = f->amplitude / gf, ac = c->amplitude / gc, sf = f->sigma / gf, sc = c->sigma / gc;
  double noise = sqrt (sf * sf + sc * sc + DS_PROBE_PAIR_SCATTER * af * DS_PROBE_PAIR_SCATTER * af);
  double drop = ac - af, lost_f = total - af, lost_c = total - ac, rho = f->period / c->period;
  if (!(drop > 3 * noise)) {
    g_snprintf (out->note, sizeof out->note,
                "the modulation falls by %.1f %% from %g px to %g px, within the noise (%.1f %%): no kernel at the edge "
                "of what the pilot resolves; one narrower than every period would not show at all (the method's limit)",
                100 * drop / af, c->period, f->period, 300 * noise / af);
    return;
  }
  /* No lower end only where the measured ratio of the losses is outside what the family allows
   * (r <= rho^2; lost_c <= 0 among them): the lower end below is read at the same, measured r.
   * A loss at Q_c within the noise of zero is no evidence of r <= rho^2 when r itself is above
   * it: the noise makes lost_c uncertain, not r's side of rho^2, and the family's kernel read at
   * that r still brackets the direct light. */
  if (!(lost_c > 0) || !(lost_c > rho * rho * lost_f)) {
    out->unbounded = TRUE;
    g_snprintf (out->note, sizeof out->note,
                "the modulation falls by %.1f %% from %g px to %g px while the mean holds only %.1f %% more light than "
                "the modulation at %g px: scattered light narrower than any kernel with a 1/k tail keeps the stripes, "
                "and the direct light could be any part of the %.0f DN modulated at %g px",
                100 * drop / af, c->period, f->period, 100 * lost_c / af, c->period, af, f->period);
    return;
  }
  double r = lost_c / lost_f, lo = 1e-4, hi = 1e4;
  if (r >= 1)
    return;
  /* lost_share (k rho) / lost_share (k) rises from rho^2 (k -> 0) to 1 (k -> infinity). */
  for (int i = 0; i < 100; i++) {
    double k = sqrt (lo * hi);
    if (lost_share (k * rho) / lost_share (k) < r)
      lo = k;
    else
      hi = k;
  }
  double k = sqrt (lo * hi), scattered = lost_f / lost_share (k), ld = total - scattered;
  out->kernel_px = k * f->period / (2 * G_PI);
  if (!(ld > 0)) {
    out->unbounded = TRUE;
    g_snprintf (out->note, sizeof out->note,
                "the modulation falls by %.1f %% from %g px to %g px: one kernel of %.2f px with a 1/k tail would hold all "
                "the light the mean shows, so the direct light could be any part of the %.0f DN modulated at %g px",
                100 * drop / af, c->period, f->period, out->kernel_px, af, f->period);
    return;
  }
  out->ratio = MIN (1.0, ld / ld_fit);
  g_snprintf (out->note, sizeof out->note,
              "the modulation falls by %.1f %% from %g px to %g px: if all the scattered light shares one kernel with a 1/k "
              "tail (%.2f px), it keeps %.0f %% of its stripes at %g px and Ld is %.0f %% of the fit's; a second kernel "
              "narrower than every period would not show (the method's limit)",
              100 * drop / af, c->period, f->period, out->kernel_px, 100 * (1 - lost_share (k)), f->period,
              100 * out->ratio);
}

/* The 1 - p quantile of chi^2 with k degrees of freedom (Wilson and Hilferty's cube-root normal
 * approximation; within 3 % of the table at 99.9 % for k >= 1), z the normal quantile. */
static double
chi2_quantile (double k, double z)
{
  double c = 2 / (9 * k), t = 1 - c + z * sqrt (c);
  return k * t * t * t;
}

/* Whether the fit's weighted squared residuals (chi^2: each harmonic's noise and the fit's 2 % floor
 * for what the model leaves out) are beyond the 99.9 % quantile for n_eq equations and n_par
 * parameters (the blur's error has its own prior). Where most places clip and what is left is
 * shaped by objects (a shadow, a grid), the first harmonics at successive periods can read Ld
 * values far apart against their noise, which no transfer the probe models makes: Ld and the
 * leak read from such a fit are no measurement. A model that cannot fit its own data measures
 * nothing: a lower bound, saying why. */
void
ds_probe_fit_consistency (double chi2, guint n_eq, guint n_par, DsSceneProbe *out)
{
  out->transfer.inconsistent = FALSE;
  if (n_eq <= n_par || !(chi2 >= 0))
    return;
  double dof = n_eq - n_par, limit = chi2_quantile (dof, DS_PROBE_FIT_Z);
  if (!(chi2 > limit))
    return;
  out->transfer.inconsistent = TRUE;
  g_snprintf (out->transfer.note, sizeof out->transfer.note,
              "the stripes' harmonics at the pilot's periods disagree with every transfer the probe models "
              "(chi^2 %.1f for %u equations, at most %.1f from their noise): Ld and the scattered stripes are not "
              "measured, so the prediction is a lower bound",
              chi2, n_eq, limit);
}
