#include "daemon/service/phase_check.h"

#include <math.h>

#include "proc/stripe_phase.h"

void
ds_phase_check_init (DsPhaseCheck *check, double period_px, double tolerance_deg)
{
  *check = (DsPhaseCheck) { .period_px = period_px,
                            .tolerance_cycles = tolerance_deg / 360.0,
                            .min_confidence = DS_STRIPE_PHASE_MIN_SNR };
}

/* Rows kept for the measurement: the stripes vary along x only, so the rows are averaged into
 * one profile, and beyond a few hundred rows more of them only buy noise margin the check does
 * not need, at a cost (a pass over a 4 MP frame) that sits between the last frame and the
 * result. A view of every step-th row: no copy. */
#define PHASE_CHECK_MIN_ROWS 256

/* The stripe period the frame does show, when the configured one finds nothing: the rows are
 * averaged into one profile, and the first harmonic is fitted at candidate periods 2 % apart,
 * from just above Nyquist to a quarter of the width. The best one, if it is reliable, else NAN.
 * A failure path only (a frame that could not be verified): a few hundred fits of one row. */
static double
dominant_period (const DsImage *rows, double *best_snr)
{
  *best_snr = 0;
  g_autoptr (DsImage) profile = ds_image_new (DS_SAMPLE_F32, rows->width, 1, NULL);
  if (!profile || rows->width < 16)
    return NAN;
  float *out = ds_image_row (profile, 0);
  for (guint x = 0; x < rows->width; x++) {
    double sum = 0;
    for (guint y = 0; y < rows->height; y++) {
      const guint8 *row = ds_image_row (rows, y);
      sum += rows->type == DS_SAMPLE_U8    ? ((const guint8 *) row)[x]
             : rows->type == DS_SAMPLE_U16 ? ((const guint16 *) row)[x]
                                           : ((const float *) row)[x];
    }
    out[x] = (float) (sum / rows->height);
  }
  double best = NAN;
  for (double p = 2.2; p <= rows->width / 4.0; p *= 1.02) {
    DsStripePhase sp;
    if (ds_stripe_phase_measure (profile, p, NULL, &sp, NULL) && sp.reliable && sp.snr > *best_snr) {
      *best_snr = sp.snr;
      best = p;
    }
  }
  return best;
}

DsPhaseVerdict
ds_phase_check_frame (DsPhaseCheck *check, const DsImage *frame, guint k, guint n,
                      double *measured_cycles, char **why)
{
  DsStripePhase sp;
  g_autoptr (GError) error = NULL;
  *measured_cycles = NAN;
  DsImage rows = *frame;
  guint step = frame->height / PHASE_CHECK_MIN_ROWS;
  if (step > 1) {
    rows.stride = frame->stride * step;
    rows.height = frame->height / step;
    rows.allocation = NULL;
  }
  if (!ds_stripe_phase_measure (&rows, check->period_px, NULL, &sp, &error)) {
    *why = g_strdup_printf ("stripe phase not measurable: %s", error->message);
    return DS_PHASE_VERDICT_UNVERIFIABLE;
  }
  *measured_cycles = sp.phase;
  if (!sp.reliable || sp.snr < check->min_confidence) {
    /* Say what to check: a wrong period-px shows as stripes at another period. */
    double found_snr = 0;
    double found = dominant_period (&rows, &found_snr);
    if (isfinite (found))
      *why = g_strdup_printf ("no stripes at the configured period of %.1f px to verify phase %u (snr %.1f < %.1f), "
                              "but the frame shows stripes with a period of about %.1f px (snr %.0f): "
                              "check [illuminator] period-px (the period as the camera sees it)",
                              check->period_px, k, sp.snr, check->min_confidence, found, found_snr);
    else
      *why = g_strdup_printf ("no stripes in the frame to verify phase %u (snr %.1f < %.1f at the configured "
                              "period of %.1f px, and no other period stands out): check that the illuminator "
                              "lights the camera's field of view, and the exposure (too much scattering or "
                              "too little light leaves no measurable stripes; verify-phase=false skips the check)",
                              k, sp.snr, check->min_confidence, check->period_px);
    return DS_PHASE_VERDICT_UNVERIFIABLE;
  }
  double nominal = (double) k / n;
  if (!check->offset_known && !check->provisional) {
    /* The first frame of a set without a known offset defines it; the rest of the set must
     * agree with it, or the set fails and the next one tries again. */
    check->provisional = TRUE;
    check->provisional_offset = ds_stripe_phase_diff (sp.phase, nominal);
    return DS_PHASE_VERDICT_OK;
  }
  double offset = check->offset_known ? check->offset_cycles : check->provisional_offset;
  double err = ds_stripe_phase_diff (sp.phase, nominal + offset);
  if (fabs (err) > check->tolerance_cycles) {
    /* Name the phase the frame looks like, which tells a stale frame from a stuck projector. */
    double looks = (sp.phase - offset) * n;
    long as_k = lround (looks - floor (looks / n) * n) % (long) n;
    *why = g_strdup_printf ("frame for phase %u shows phase %.2f of %u (looks like phase %ld): "
                            "off by %.1f deg, tolerance %.1f deg",
                            k, looks - floor (looks / n) * n, n, as_k, err * 360.0,
                            check->tolerance_cycles * 360.0);
    return DS_PHASE_VERDICT_WRONG;
  }
  return DS_PHASE_VERDICT_OK;
}

void
ds_phase_check_confirm (DsPhaseCheck *check)
{
  if (!check->provisional)
    return;
  check->offset_known = TRUE;
  check->offset_cycles = check->provisional_offset;
  check->provisional = FALSE;
}

void
ds_phase_check_abandon (DsPhaseCheck *check)
{
  check->provisional = FALSE;
}
