/* Whether the narrow kernel term measures a kernel where the harmonics do not over-determine it
 * (docs/accuracy.md, "Automatic operating point": isotropic scattering read as stripes, gen-17-02).
 *
 * The term (scene_probe.h) adds a kernel holding beta Ld of light with an MTF of width w to the
 * line's Ld and alpha: four free parameters (the blur's error has its unit prior and the form nu
 * two values). Sine stripes have one harmonic per period, so a pilot at P/4, P/2, P and 2P gives
 * four equations, as many as the parameters, and the fit has no degree of freedom left to be
 * tested with. What it still cannot do is fall with the period: every kernel's transfer rises
 * with x = Q / n, so the term passes through harmonics that a kernel made (development sine scenes
 * where it won: gen-4-01, gen-8-02, gen-10-03, gen-12-03, gen-14-06, and square gen-13-00 with
 * three usable harmonics, leave a weighted RMS under 0.05 % of their amplitudes) and
 * misses harmonics whose differences are something else: objects' column profiles, or a Monte
 * Carlo kernel's own structure. gen-17-02 (15.9 mm of a near-isotropic medium, sine stripes at
 * 19.25 px): the renderer's kernel keeps 1.3 to 4.3 % of its scattered light modulated at the four
 * periods, magnitudes at its Monte Carlo noise with signs of their own (`descatter-sim describe`
 * with period-px changed), so A / G reads 2341, 2303, 2418 and 2392 DN at 4.81, 9.63, 19.25 and
 * 38.5 px without the scene's objects (Ld 2368): up at P, down at P/2 and at 2P. The term turned
 * that into a kernel of 1.4 px holding 15 % of Ld and keeping 83 % of it at P (its MTF only halves
 * from P to P/2, so the step is magnified about three times), the harmonic at P/4, which
 * contradicts it by 8 %, put down to the blur's error, and still missed them by 0.96 % RMS (1.28 %
 * with the objects): Ld 2119, the leak at P 12 % (with the objects, Ld 1498 against 1738 and
 * 16.6 %).
 *
 * So where the equations do not over-determine the term (no more distinct x = Q / n than its
 * parameters), it is taken only if it passes through them: a weighted RMS of its relative
 * residuals within half the scatter that objects put between two periods' harmonics
 * (DS_PROBE_PAIR_SCATTER). Otherwise the harmonics are no kernel's transfer, and the line (or
 * the acceptance cone's kernel) is the fit. A kernel the search finds keeping more than
 * DS_PROBE_NARROW_MAX_AT_FINEST of Ld at the finest period still makes the prediction a lower
 * bound (that check comes first), and the hidden light's rule (scene_probe_hidden.h) and the
 * interval of Ld apply as without the term.
 *
 * Internal to the scene probe; pure functions, any thread. */
#pragma once
#include <glib.h>

#include "daemon/operating/scene_probe_transfer.h"

/* The narrow term's free parameters: Ld, alpha, beta and w. */
#define DS_PROBE_NARROW_PARAMETERS 4
/* The floor of the transfer fit's weights (scene_probe_transfer.c: 1 / (noise^2 + floor^2)). */
#define DS_PROBE_TRANSFER_FLOOR 0.02
/* How far an under-determined term may miss the harmonics (weighted RMS of the relative residuals). */
#define DS_PROBE_NARROW_PASS_RMS (DS_PROBE_PAIR_SCATTER / 2)

/* How many of eq's equations lie at distinct x = Q / n (within 0.1 %). */
guint ds_probe_distinct_points (const DsProbeEquation *eq, guint n_eq);

/* The weighted RMS of the relative residuals behind a fit's chi2 over eq (the transfer fit's
 * weights). */
double ds_probe_residual_rms (const DsProbeEquation *eq, guint n_eq, double chi2);

/* TRUE when the narrow term, fitted with chi2 over eq, is a measurement: the equations
 * over-determine it, or it passes through them (above). Otherwise FALSE, with note (if not NULL)
 * saying why. */
gboolean ds_probe_narrow_measured (const DsProbeEquation *eq, guint n_eq, double chi2, char *note, gsize note_size);
