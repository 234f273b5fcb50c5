/* Stripe phase of a single frame: where the first harmonic of the stripe pattern lies, so the
 * sequencer can prove that frame k was lit with phase k (design: "Sequencer contract").
 *
 * Convention (the project's, shared with the simulator and the illuminator): phase k of N
 * lights x where u = frac(x/P - k/N) wrapped to [-1/2, 1/2) is near 0, stripes centred at
 * x = jP + kP/N. The first harmonic of such a frame is M + A cos(2 pi (x/P - phi)) with
 * phi = k/N, which is what ds_stripe_phase_measure returns (x = pixel centre, absolute frame
 * column, so a region does not shift the phase).
 *
 * Method: rows of the region are averaged into a column profile (non-finite samples are left
 * out, columns with none are dropped); then a least-squares fit of mean + cos + sin at the
 * period over the largest whole number of periods that fits in the region starting at its
 * left edge (round(floor(W/P) * P) columns). The fit includes the mean, so a fractional period
 * left over from rounding leaks nothing of the (possibly huge, scattered) mean into the
 * harmonic; whole periods keep the square wave's odd harmonics out of the estimate.
 * The fit residual gives the noise of the amplitude; snr = A / sigma_A.
 *
 * Pure function, any thread; CPU only (one pass over the region). */
#pragma once
#include <glib.h>

#include "proc/image.h"

G_BEGIN_DECLS

typedef struct {
  guint x, y, width, height; /* width or height 0: to the frame's edge */
} DsRegion;

/* snr at which a measurement is trusted: pure Gaussian noise exceeds it with probability
 * exp(-snr^2/2) = 4e-6, and the phase's 1-sigma is 1/(2 pi snr) = 0.032 periods. */
#define DS_STRIPE_PHASE_MIN_SNR 5.0

typedef struct {
  double phase;          /* cycles in [0, 1) */
  double amplitude;      /* A of the first harmonic, in the frame's units (DN) */
  double mean;           /* M over the fitted columns */
  double modulation;     /* A / M (0 when M <= 0) */
  double snr;            /* A / sigma_A; Rayleigh-distributed (mean 1.25) for pure noise */
  double phase_sigma;    /* 1-sigma uncertainty of phase in cycles, 1 / (2 pi snr) */
  double confidence;     /* 1 - exp(-snr^2 / 2): 1 minus the chance that noise alone gives A */
  gboolean reliable;     /* snr >= DS_STRIPE_PHASE_MIN_SNR: otherwise "cannot tell" */
  guint columns_used;    /* columns in the fit */
  guint periods_used;    /* whole periods in the fit */
} DsStripePhase;

/* period_px > 2 (Nyquist) and <= the region's width. region NULL: the whole frame.
 * Fails INVALID_ARGUMENT (period, region outside the frame, fewer than 4 usable columns) or
 * FORMAT (sample type). A frame without modulation is not an error: reliable is FALSE. */
gboolean ds_stripe_phase_measure (const DsImage *frame, double period_px, const DsRegion *region,
                                  DsStripePhase *out, GError **error);

/* The column sums the measurement starts from: each of `cols` columns from column x, over
 * `rows` rows from row y, summed into sum[cols] (in doubles), the samples summed into
 * count[cols]: the finite ones of an F32 frame, every one of a U8 or U16 frame (summed exactly
 * in 32 bits on the vector units first, so the sums are those of doubles). The caller keeps
 * the region inside the frame and the type one of those three. Any thread. */
void ds_stripe_phase_column_sums (const DsImage *frame, guint x, guint y, guint cols, guint rows, double *sum,
                                  guint32 *count);

/* Signed difference a - b wrapped to [-1/2, 1/2) cycles. */
double ds_stripe_phase_diff (double a, double b);

G_END_DECLS
