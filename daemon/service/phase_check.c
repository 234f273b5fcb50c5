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
    *why = g_strdup_printf ("stripe modulation too weak to verify phase %u (snr %.1f < %.1f)", k,
                            sp.snr, check->min_confidence);
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
