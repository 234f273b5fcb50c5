/* Whether the narrow kernel term measures a kernel where the harmonics do not over-determine it
 * (docs/accuracy.md, "Automatic operating point": isotropic scattering read as stripes).
 *
 * The term (scene_probe.h) adds a kernel holding beta Ld of light with an MTF of width w to the
 * line's Ld and alpha: four free parameters (the blur's error has its unit prior and the form nu
 * two values). Sine stripes have one harmonic per period, so a pilot at P/4, P/2, P and 2P gives
 * four equations, as many as the parameters, and the fit has no degree of freedom left to be
 * tested with. What it still cannot do is fall with the period: every kernel's transfer rises
 * with x = Q / n, so the term passes through harmonics that a kernel made (a weighted RMS of a
 * small fraction of a % of their amplitudes) and misses harmonics whose differences are something
 * else: objects' column profiles, or a kernel's own structure. A thick, near-isotropic medium keeps
 * a few % of its scattered light modulated at every period, with differences between periods at
 * the level of its own noise and of either sign: A / G then goes up at P and down at P/2 and at 2P.
 * The term turns such a pattern into a kernel a pixel or so wide that keeps most of its light at
 * P (its MTF only halves from P to P/2, so a step between them is magnified about three times),
 * puts the harmonic at P/4 that contradicts it down to the blur's error, still misses the
 * harmonics by about 1 % RMS, and takes a tenth or more of Ld from the direct light.
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
