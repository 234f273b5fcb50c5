/* Stripes that step with the phases (calibration_steps.h). */
#include <math.h>

#include "proc/calibration_steps.h"
#include "proc/proc_error.h"

gboolean
ds_stripe_steps_check (const DsStripePhase *sp, guint n, double period_px, const char *period_source,
                       DsStripeSteps *out, GError **error)
{
  g_return_val_if_fail (n >= 3, FALSE);
  /* C = (1/N) sum_k a_k e^{-2 pi i k/N}, a_k = A_k e^{2 pi i phi_k} */
  double cr = 0, ci = 0, mean = 0, fit_var = 0;
  for (guint k = 0; k < n; k++) {
    double t = 2 * G_PI * (sp[k].phase - (double) k / n);
    cr += sp[k].amplitude * cos (t) / n;
    ci += sp[k].amplitude * sin (t) / n;
    mean += sp[k].mean / n;
    /* the fit's variance of one component of a_k: snr = A / sigma_A */
    double s = sp[k].snr > 0 ? sp[k].amplitude / sp[k].snr : INFINITY;
    fit_var += s * s / n;
  }
  double c = hypot (cr, ci), off = atan2 (ci, cr) / (2 * G_PI);
  off -= floor (off);
  double rss = 0, spread = 0;
  for (guint k = 0; k < n; k++) {
    double t = 2 * G_PI * (double) k / n;
    double pr = cr * cos (t) - ci * sin (t), pi = cr * sin (t) + ci * cos (t);
    double ar = sp[k].amplitude * cos (2 * G_PI * sp[k].phase), ai = sp[k].amplitude * sin (2 * G_PI * sp[k].phase);
    rss += (ar - pr) * (ar - pr) + (ai - pi) * (ai - pi);
    double d = sp[k].phase - (double) k / n - off;
    d -= floor (d + 0.5);
    spread += d * d / n;
  }
  /* One component of C: the residuals hold 2 (N - 1) degrees of freedom, C averages N phases. */
  double var_c = MAX (rss / (2.0 * (n - 1)), fit_var) / n;
  double se = sqrt (var_c);
  out->stepping = c;
  out->not_stepping = se;
  out->mean = mean;
  out->snr = se > 0 ? c / se : (c > 0 ? INFINITY : 0);
  out->offset_cycles = off;
  out->spread_cycles = sqrt (spread);
  if (out->snr >= DS_STRIPE_PHASE_MIN_SNR)
    return TRUE;
  g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_EMPTY,
               "no stripes at the %s period %.4g px: the frames' first harmonic at that period that steps "
               "with the phases is %.3g DN, against a standard error of %.3g DN from what does not step (noise, "
               "or a picture that does not move with the illuminator: the %u phases' stripe positions scatter "
               "by %.3f periods rms about the steps of 1/%u), %.1f standard errors where %.0f are needed; the "
               "frames' mean level (less the dark frame's, when one was taken) is %.4g DN. Is the illuminator on and lighting the camera's view, and is the "
               "period right?",
               period_source, period_px, out->stepping, out->not_stepping, n, out->spread_cycles, n, out->snr,
               DS_STRIPE_PHASE_MIN_SNR, out->mean);
  return FALSE;
}
