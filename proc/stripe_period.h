/* The stripe period as the camera sees it, measured in one frame: for focusing and aligning the
 * illuminator (the live view draws it over the frame), not for the sequencer, which trusts the
 * configured period and checks the phase (stripe_phase.h).
 *
 * Method: rows are averaged into a column profile (non-finite samples left out), its mean is
 * removed and a Hann window applied; the magnitude of its Fourier transform is searched over
 * the frequencies of periods min_px..max_px on a grid four times finer than the DFT's, and the
 * peak refined by a parabola through the grid's three highest points. The fundamental of a
 * square or sine pattern is its strongest component, so harmonics within the range do not
 * win. Pure function, any thread; CPU only (a few million multiply-adds for a 1000-wide frame).*/
#pragma once
#include <glib.h>

#include "proc/image.h"

G_BEGIN_DECLS

typedef struct {
  double period_px;      /* measured period; NAN when no peak stands out */
  double peak_ratio;     /* the peak's magnitude over the median magnitude of the range */
  gboolean reliable;     /* peak_ratio >= DS_STRIPE_PERIOD_MIN_RATIO */
} DsStripePeriod;

/* A peak this many times the median magnitude: noise alone exceeds it practically never. */
#define DS_STRIPE_PERIOD_MIN_RATIO 8.0

/* 2 < min_px < max_px <= the frame's width / 2 (at least two periods). Fails INVALID_ARGUMENT
 * (range) or FORMAT (sample type); a frame without stripes is not an error (reliable FALSE). */
gboolean ds_stripe_period_measure (const DsImage *frame, double min_px, double max_px, DsStripePeriod *out,
                                   GError **error);

/* The period of a phase set, for checking and calibrating it offline: from two of its frames
 * about half a period apart in phase (their difference cancels the scene and doubles the
 * stripes), or from one frame (b NULL). The strongest line of the column profile's spectrum at
 * whole cycles across the width (periods from 2.5 pixels to half the width; a harmonic of a
 * strong line at a whole fraction of its frequency is not taken for the fundamental), refined by
 * the least-squares fit of the mean and the harmonics the sampling resolves: within 0.02 % on
 * eight periods. FALSE (no error: nothing to see) when no line reaches 8 sigma of the
 * spectrum's noise; *snr says how strong the best one was. Fails only on invalid arguments. */
gboolean ds_stripe_period_detect (const DsImage *a, const DsImage *b, double *period_px, double *snr,
                                  GError **error);

G_END_DECLS
