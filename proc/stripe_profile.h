/* The stripes' profile across one period, from a pair of opposite phases (phase 0 and 1/2) and
 * the dark frame: the per-pixel passes of the pilot's pattern check
 * (daemon/operating/pattern_check.h), which fits the pattern to the binned profile.
 *
 * Per usable pixel (no sample at or above the clip level, all finite, and the sum
 * S = L0 + L1 - 2D above a quarter of its 90th percentile):
 *   r = (L0 - D) / S        the pixel's own brightness divides out;
 *   t = S / mean S over the usable pixels of a box of about two periods around it (radius
 *       max (4, ceil P)), where that mean is above the same threshold: high where the phases
 *       overlap, low in their gaps;
 * binned by the position in the period u = frac (x / P - offset), bin floor (u n_bins). Each
 * bin holds the mean r, the mean u of its r pixels (its centre when it has none) and the
 * mean t, with their counts.
 *
 * Pure functions of the frames; any thread; CPU and O(w h) memory. */
#pragma once
#include <glib.h>

#include "proc/image.h"

G_BEGIN_DECLS

typedef struct {
  guint width, height;
  double period_px, offset_cycles;
  double threshold;        /* the sum below which a pixel is too dark to use; 0 when no pixel is */
  double *sum;             /* per pixel (row-major) S, NaN where a sample clips or is not finite */
  guint n_bins;
  double *r, *u, *t;       /* per bin, means */
  guint64 *n, *nt;         /* per bin, the pixels in r (and u) and in t */
  guint64 pixels;          /* pixels in r over all bins */
  guint bins_used;         /* bins with r or t pixels */
} DsStripeProfile;

void ds_stripe_profile_free (DsStripeProfile *profile);
G_DEFINE_AUTOPTR_CLEANUP_FUNC (DsStripeProfile, ds_stripe_profile_free)

/* Where phase 0's stripes lie (cycles, [0, 1)): the first harmonic of L0 - L1 at the period, in
 * which the scene's own detail cancels (proc/stripe_phase.h). FALSE when it shows no reliable
 * stripes. */
gboolean ds_stripe_profile_offset (const DsImage *l0, const DsImage *l1, double period_px, double *offset_cycles);

/* The binned profile (above). saturation: samples at or above leave their pixel out; 0 = none.
 * Fails (DS_PROC_ERROR_INVALID_ARGUMENT) on frames of different shapes, a period <= 0 or no
 * bins; a pair with fewer than 64 usable pixels, or none bright, gives a profile with no
 * pixels (pixels = 0, threshold 0). */
DsStripeProfile *ds_stripe_profile_bin (const DsImage *dark, const DsImage *l0, const DsImage *l1, double period_px,
                                        double offset_cycles, double saturation, guint n_bins, GError **error);

/* Per pixel of the profile's frames, for proc/calibration_scatter.h: brightness = S, and off =
 * the off-stripe fraction (the dark phase over the lit one, dark frame subtracted) at the
 * stripe centres, where one phase is fully lit and the other fully dark: within a quarter of
 * min (duty, 1 - duty) of a period of either phase's centre; NaN elsewhere and where S is below
 * the threshold. brightness and off hold width * height values. */
void ds_stripe_profile_centres (const DsStripeProfile *profile, const DsImage *dark, const DsImage *l0,
                                const DsImage *l1, double duty, double *brightness, double *off);

G_END_DECLS
