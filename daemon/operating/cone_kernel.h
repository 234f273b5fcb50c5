/* The stripe transfer of light scattered into the lens's acceptance cone, and its fit to the
 * pilot's harmonics (docs/accuracy.md, "Automatic operating point": scattered light that keeps
 * the stripes).
 *
 * Physics. A photon scattered once at a distance u in front of the exit face, into a direction
 * theta that the lens accepts (theta <= theta_c inside the medium), leaves the slab displaced by
 * u tan theta. Over the small cone a forward-peaked phase function is nearly flat (Henyey-
 * Greenstein g = 0.8 falls by x1.5 from 0 to 7 degrees), so the accepted directions fill the cone's
 * solid angle evenly: tan theta / tan theta_c = rho is spread evenly over the unit disc. And u is
 * spread evenly over the thickness d: the path to the scattering point and on to the exit,
 * z + u / cos theta, is d to within theta^2, so attenuation weighs every depth alike. The
 * displacements fill discs of radius R u, R = d tan theta_c: a uniform disc of radius a has the
 * MTF jinc (2 pi a / x) = 2 J1 (q) / q along x at period x, and averaged over u
 *     T (x) = integral_0^1 jinc (2 pi R u / x) du = (2 / q) integral_0^q J1 (t) / t dt,  q = 2 pi R / x.
 * Its limits say what two periods can see:
 *   - periods long against R: T = 1 - q^2 / 24, the stripes all but kept, 1 - T falling as 1 / x^2;
 *   - periods short against R: T = x / (pi R) (the integral of J1 (t) / t is 1), a transfer rising
 *     linearly with the period from 0. This is the small-angle law's linear rise in x that the
 *     probe's line log (A / G) = log Ld + alpha x extrapolates to x = 0: the line is this kernel
 *     seen at periods short against it.
 * Between, the transfer saturates at the whole scattered light S = M - Ld (M the mean's light),
 * and the line, whose slope it reads between the periods, does not: where the cone keeps most of
 * the stripes at P and 2P, the slope between them is small, and the extrapolation removes that
 * slope's worth of the leak, not the leak (a leak several times the one read at P, and Lg read
 * at a fraction of the mean's). A Monte Carlo kernel with multiple scattering included follows
 * this form within its own noise, with R close to the geometry's d tan theta_c
 * (tests/daemon/test_probe_sim.c). So the apparent direct light of harmonic n at period
 * Q is
 *     A_n (Q) / G_n (Q) = Ld + (M - Ld) T (Q / n),
 * one unknown besides Ld (R; the daemon knows neither d nor theta_c), and the scattered light that
 * keeps the stripes is bounded by what the mean shows.
 *
 * What it cannot tell: where every period the pilot resolves is long against R, 1 - T = q^2 / 24
 * at all of them, so only (M - Ld) R^2 is measured, not Ld; the blur's uncertainty, which lowers
 * every harmonic as exp (-c / x^2) does too, blurs that further. The fit therefore also returns
 * the range of Ld and of the leak at P over the parameters within DS_CONE_CHI2_RANGE of its
 * best: a leak known within DS_CONE_TOLD_FACTOR either way is a measurement, a wider one is not.
 *
 * Pure functions; any thread; CPU only. */
#pragma once
#include <glib.h>

G_BEGIN_DECLS

/* The increase of the fit's weighted squared residuals (the blur's prior included) that bounds
 * the range returned: 4, two standard deviations of one parameter. */
#define DS_CONE_CHI2_RANGE 4.0
/* The leak at P counts as measured when its range lies within this factor of the best fit's
 * either way (the factor the validation asks of a prediction). */
#define DS_CONE_TOLD_FACTOR 1.5
/* The kernel's radius is seen when the best fit's objective lies at least this far below both of
 * the fit's limits, a kernel narrower than every period (R -> 0: the stripes kept at all of them,
 * indistinguishable from direct light) and one wider than every period (R -> infinity: the line's
 * regime, no stripes kept): one standard deviation. */
#define DS_CONE_SEEN_CHI2 1.0

/* T (x) above for the kernel radius R (px) at the period x (px); 1 for R = 0, 0 for x <= 0. */
double ds_cone_kernel_mtf (double radius_px, double x_px);

typedef struct {
  gboolean ok;
  double ld;                 /* DN */
  double radius_px;          /* R */
  double blur_t;             /* the blur's error in units of its uncertainty */
  double chi2;               /* weighted squared residuals, without the blur's prior */
  double ld_low, ld_high;    /* over the grid points within DS_CONE_CHI2_RANGE of the best */
  double leak, leak_low, leak_high; /* (M - Ld) T (P) / Ld at the best and over that range */
  double objective;          /* chi2 plus the blur's prior at the best */
  double objective_narrow, objective_wide; /* the least at the smallest and at the largest R */
  gboolean seen;             /* objective DS_CONE_SEEN_CHI2 below both limits */
  gboolean told;             /* seen, and leak_low and leak_high within DS_CONE_TOLD_FACTOR of leak */
  /* The objective stays within DS_CONE_SEEN_CHI2 of the best up to the grid's end, nearly all the
   * light scattered (Ld / M = 0.005): the harmonics bound the scattered light from below only. Along
   * that valley (periods long against R see (M - Ld) R^2 alone) the objective is flat within the
   * noise while the leak (M - Ld) T (P) / Ld grows without limit as Ld goes to 0, so the best fit's
   * place on it is the noise's, not the scene's. ld, radius_px, blur_t, chi2 and leak are then the
   * point with the most direct light within DS_CONE_SEEN_CHI2 of the best (one standard deviation:
   * the least leak the harmonics allow, the lower end a lower bound needs); objective stays the
   * best's. */
  gboolean open_above;
} DsConeFit;

/* Fits Ld and R (the blur's error t with a unit normal prior) to n equations
 *     y_i = log (Ld + (total - Ld) T (x_i)) + t shift_i,
 * y_i the log of a harmonic's amplitude over its gain, w_i its weight (0: left out), shift_i how
 * far its log gain moves for the blur's uncertainty (NULL: none), x_i = Q / n; total the light the
 * mean shows (M). period_px: where the leak is reported. FALSE (out->ok FALSE) with fewer than two
 * weighted equations or a total that is not positive. */
gboolean ds_cone_kernel_fit (const double *x, const double *y, const double *w, const double *shift, guint n,
                             double total, double period_px, DsConeFit *out);

G_END_DECLS
