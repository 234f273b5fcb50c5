/* A replica of a pilot pair: the frames a pattern would give on a flat scene, for a reading to be
 * compared with what the same reading makes of the real frames (the pattern check's expected
 * duty, daemon/operating/pattern_check.c). The caller renders the pattern as the pixels see it,
 * one noise-free value per column and phase (the model lives with the caller); each pixel of
 * every row then gets its column's value plus Gaussian noise of the given standard deviation,
 * and the dark frame the noise alone.
 *
 * Pure functions of their arguments and the generator's state; any thread, one generator per
 * thread. */
#pragma once
#include <glib.h>

#include "proc/image.h"
#include "proc/stripe_profile.h"

G_BEGIN_DECLS

/* A standard normal deviate from rng (Box-Muller, two uniform draws). */
double ds_stripe_replica_normal (GRand *rng);

/* Fills dark, l0 and l1 (float, one shape, w columns): per pixel, row by row and column by
 * column, three draws in that order: dark = n, l0 = phase0[x] + n, l1 = phase1[x] + n, n noise_dn
 * times a fresh normal deviate. FALSE (frames untouched) unless all three are float frames of one
 * shape. */
gboolean ds_stripe_replica_render (const double *phase0, const double *phase1, double noise_dn, GRand *rng,
                                   DsImage *dark, DsImage *l0, DsImage *l1);

/* The mean sum S of a profile's pixels above its threshold (stripe_profile.h), the pair's lit
 * level; 0 when none is. */
double ds_stripe_profile_lit_mean (const DsStripeProfile *profile, guint64 *n_lit);

G_END_DECLS
