/* A rise of the transfer at the coarse period that no kernel the harmonics at and below P allow
 * (docs/accuracy.md, "Automatic operating point": scattered light wide against P, seen only at 2P).
 *
 * Physics. The apparent direct light of harmonic n at period Q is A_n (Q) / G_n (Q) =
 * Ld + S T (x), x = Q / n, with T the scattered light's MTF at 1 / x: it rises with x. Where
 * the harmonics at x <= P are flat within their noise, S (T (P) - T (x_lo)) is within it, x_lo the
 * finest x; what can the same kernel add from P to a coarser x_c? For the probe's two forms:
 *   - the line, log (A / G) linear in x: (x_c - P) / (P - x_lo) times the rise over [x_lo, P]
 *     (x 2 at x_c = 2P, x_lo = P / 2), to first order in a flat rise;
 *   - the acceptance cone's kernel (cone_kernel.h), T (x) = (2 / q) integral_0^q J1 (t) / t dt,
 *     q = 2 pi R / x: at periods short against R, T = x / (pi R), the line's linear rise (ratio 2
 *     again); long against R, 1 - T = q^2 / 24 falls as 1 / x^2 and the ratio is 1/4; between,
 *     the Bessel ripple of T at x_lo lifts it to at most 2.63 (at R = 1.17 P, x_lo = P / 2).
 * So flat harmonics at and below P leave at most a few times their noise at 2P. A larger rise is
 * light whose kernel's MTF is at its floor at P and below and rises only beyond: a kernel wide
 * against P (a Gaussian's exp (-c / x^2), multiple scattering's smooth core: its T at P/2, P, 2P
 * is t^4, t, t^(1/4), flat at 0 up to P and 0.3 at 2P for t = 0.01), whose leak at P is within the
 * flat harmonics' noise. Fitted with the rest, that one point turns into a slope (the line) or a
 * kernel that keeps the stripes (the cone), both of which extrapolate a leak at P the harmonics
 * at P do not show (A / G flat at and below P and 20 % higher at 2P puts the line's Ld a sixth
 * low). Such points are left out of the transfer fit, and the leak at P is
 * what the harmonics at and below P say.
 *
 * Internal to the scene probe; pure function, any thread. */
#pragma once
#include <glib.h>

#include "daemon/operating/scene_probe_transfer.h"

/* How many standard deviations the flat harmonics' slope may stand from zero (flat within the
 * noise), and how many the coarse point must stand above what they allow there. */
#define DS_PROBE_WIDE_FLAT_Z 2.0
#define DS_PROBE_WIDE_RISE_Z 3.0

typedef struct {
  gboolean left_out;         /* equations with x > P were dropped */
  guint dropped;
  double coarse_x;           /* the largest x dropped, px */
  double level;              /* the flat harmonics' A / G at P, DN */
  double rise;               /* the coarse point's A / G over level, a share of level */
  double allowed;            /* the most the kernels above add there, a share of level */
  double z;                  /* (rise - allowed) in its standard deviations */
  char note[200];
} DsProbeWideRise;

/* The most the acceptance cone's kernel (any radius) and the line add to the transfer from period
 * p to x_c, per unit of its rise from x_lo to p (x_lo < p < x_c). */
double ds_probe_wide_rise_ratio (double x_lo, double p, double x_c);

/* Removes from eq the equations with x > period whose rise over the harmonics at and below period
 * is more than any kernel those allow (above), when the harmonics at and below period span two
 * periods and are flat within their noise; the new count. *out says what was done and why. */
guint ds_probe_drop_wide_rise (const DsStripeModel *g, DsProbeEquation *eq, guint n_eq, double sigma, guint width,
                               double period, DsProbeWideRise *out);
