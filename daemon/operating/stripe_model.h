/* The stripe pattern as a pixel of the camera sees it, for the automatic operating point: the
 * projector's defocus blurs the pattern (Gaussian, sigma px), the pixel integrates it over its
 * sensitive width w (pixel x covers [x - w/2, x + w/2]; x is the column index, as in
 * proc/stripe_phase.h; w = 1, the whole pitch, unless a calibrated gain says less).
 * Phase shift s (cycles): u = x/P - s, square lit where |u| (wrapped) < a/2, sine
 * (1 + cos 2 pi u)/2; value b + (1 - b) pattern (proc/harmonic_gain.h's convention).
 *
 * Also the least-squares harmonic fit of a column profile (whole periods, mean and harmonics
 * 1..n jointly, so the square wave's harmonics do not leak into each other).
 * Pure functions, any thread. */
#pragma once
#include <glib.h>

#include "proc/separation.h"

G_BEGIN_DECLS

typedef struct {
  DsPatternKind kind;
  double period_px;
  double duty;          /* square only */
  double black_level;
  double blur_px;       /* Gaussian sigma of the projector's defocus on the sensor */
  double pixel_aperture; /* sensitive width w of a pixel along x, px; 0 = the whole pitch (1 px).
                            Narrower where a calibrated gain exceeds the whole pixel's
                            (ds_stripe_match_gain), down to DS_STRIPE_POINT_APERTURE */
} DsStripeModel;

/* A pixel that samples the pattern at its centre (the simulator's sine stripes,
 * drivers/sim/stage_pattern.c): its sinc (w n / P) is 1 to 1e-7 at any period of 4 px and up. */
#define DS_STRIPE_POINT_APERTURE 1e-3

/* The pattern's value at pixel x for phase shift `shift` (cycles), in [b, 1]. */
double ds_stripe_value (const DsStripeModel *g, double x, double shift);

/* Flags (columns[x] = 1) the columns 0 .. width - 1 where two opposite phases at g's period,
 * shifted by shift_fine, and two at twice it, shifted by shift_coarse, sum alike within tol of the
 * swing 1 - b, and so do both neighbours (a pixel of margin for the shifts' error); 0 elsewhere.
 * Returns how many are flagged. */
guint ds_stripe_pair_sums_agree (const DsStripeModel *g, double shift_fine, double shift_coarse, double tol,
                                 guint width, guint8 *columns);

/* Cosine coefficient of harmonic n (>= 1) of the pattern as pixels see it:
 * pattern(x) = m + sum_n C_n cos (2 pi n (x/P - shift)), with
 * C_n = (1 - b) (2 / (n pi)) sin (n pi a) B_n S_n for square stripes (B_n the blur's
 * exp (-2 pi^2 sigma^2 n^2 / P^2), S_n the pixel's sinc (w n / P)), (1 - b)/2 B_1 S_1 for sine. */
double ds_stripe_harmonic (const DsStripeModel *g, guint n);

/* sigma such that the first harmonic C_1 equals h (a calibrated harmonic gain), at g's aperture;
 * 0 when h is at or above the sharp pattern's, -1 when no blur up to P/2 brings it that low. */
double ds_stripe_blur_from_gain (const DsStripeModel *g, double h);

/* Sets g's blur and aperture so that its first harmonic C_1 is h, a calibrated harmonic gain (the
 * first harmonic as the rig's pixels see it, which is what the sine estimator divides by): a blur
 * on the whole pixel where h is below the sharp whole pixel's C_1; where h is above it, no blur
 * can explain it and the pixel integrates less than its pitch (a fill factor, or a sensor that
 * samples the pattern at the pixel centre as the simulator does for sine stripes): the aperture
 * whose sinc gives h, down to DS_STRIPE_POINT_APERTURE. FALSE when h is not positive (g
 * unchanged) or no blur up to P/2 brings C_1 down to h (blur P/2). Only the first harmonic is measured: blur and aperture lower it alike
 * (sinc (w f) ~ exp (-pi^2 w^2 f^2 / 6), a Gaussian of sigma^2 = w^2 / 12), so below the whole
 * pixel's C_1 the whole pixel is kept. */
gboolean ds_stripe_match_gain (DsStripeModel *g, double h);

#define DS_STRIPE_MAX_HARMONICS 8

typedef struct {
  guint n_harmonics;                              /* fitted: 1..n */
  double mean;
  double amplitude[DS_STRIPE_MAX_HARMONICS + 1];  /* [n], n >= 1 */
  double phase[DS_STRIPE_MAX_HARMONICS + 1];      /* [n], cycles: A_n cos (2 pi n (x/P - phase_n)) */
  double sigma_amplitude;                         /* 1 sigma of each amplitude (residual) */
  guint columns_used;
} DsStripeHarmonics;

/* Fits profile[x0 .. x0 + count) (x the column index, weight 0 = missing) with the mean and
 * harmonics 1..n_harmonics of period P over the largest whole number of periods. Harmonics at
 * or above the Nyquist frequency (P/n <= 2) are not fitted (n_harmonics is lowered).
 * Fails INVALID_ARGUMENT with fewer columns than unknowns + 2. */
gboolean ds_stripe_harmonics_fit (const double *profile, const guint32 *weight, guint x0,
                                  guint count, double period_px, guint n_harmonics,
                                  DsStripeHarmonics *out, GError **error);

/* The same, for a profile that is the stripes times a scene varying across the columns, with
 * envelope[i] (for profile[i]; mean 1 over the columns used) the scene's relative level: the
 * fit holds, for each harmonic, its cosine and sine times envelope - 1 as well, so that the
 * scene's variation at frequencies that beat with the stripes' (objects' edges within a period,
 * a grid whose pitch's harmonics lie next to twice the stripes') is not read as the harmonics'
 * amplitudes; those (amplitude, phase, sigma_amplitude) are the stripes' on the scene's mean.
 * envelope NULL: ds_stripe_harmonics_fit (). */
gboolean ds_stripe_harmonics_fit_envelope (const double *profile, const guint32 *weight, const double *envelope,
                                           guint x0, guint count, double period_px, guint n_harmonics,
                                           DsStripeHarmonics *out, GError **error);

/* The fitted profile (mean and harmonics) at column x. */
double ds_stripe_harmonics_eval (const DsStripeHarmonics *h, double period_px, double x);

G_END_DECLS
