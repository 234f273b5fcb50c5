/* Do a phase set's frames show stripes at a period, stepping with the phases? (calibration.h)
 *
 * A period found in, or given for, a set is not yet stripes: a frame source whose picture moves
 * by itself (Aravis's fake camera draws a diagonal ramp that shifts one pixel per frame) has a
 * first harmonic at some period in every frame, noise-free and so "significant", but it does not
 * move by 1/N of a period from one phase to the next as the illuminator's stripes do. The test:
 * phase k's first harmonic a_k (complex, proc/stripe_phase.h) is C e^{2 pi i k/N} for stripes of
 * any shape, blur or black level; C is the part of the modulation that steps with the phases,
 * the residuals r_k = a_k - C e^{2 pi i k/N} the part that does not (noise, or light that does
 * not follow the illuminator). C must stand DS_STRIPE_PHASE_MIN_SNR standard errors clear of
 * zero, the standard error from the residuals or from the per-phase fits' own noise, whichever
 * is larger. Pure function, any thread; CPU only. */
#pragma once
#include <glib.h>

#include "proc/stripe_phase.h"

G_BEGIN_DECLS

typedef struct {
  double stepping;     /* |C|: the first harmonic that steps with the phases (the frames' units) */
  double not_stepping; /* its standard error (noise and what does not step) */
  double snr;          /* stepping / not_stepping */
  double mean;         /* the frames' mean level */
  double offset_cycles;/* arg C / 2 pi in [0, 1): where phase 0's stripes are */
  double spread_cycles;/* rms of the per-phase phases about offset + k/N */
} DsStripeSteps;

/* sp: the N >= 3 phases' measurements at one period. Fills out and returns TRUE when the
 * stripes step (snr >= DS_STRIPE_PHASE_MIN_SNR); FALSE with DS_PROC_ERROR_EMPTY naming the
 * period (period_source: "measured", "given", ...) and what was measured otherwise. */
gboolean ds_stripe_steps_check (const DsStripePhase *sp, guint n, double period_px, const char *period_source,
                                DsStripeSteps *out, GError **error);

G_END_DECLS
