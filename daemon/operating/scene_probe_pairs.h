/* The scene probe's pilot pairs (scene_probe.h): the column statistics and stripe harmonics of
 * one pair of opposite phases, and the places whose stripes' peaks clip, left out of those
 * statistics and counted back into the probe's Ld, its spread and Lg from their troughs.
 * Internal to the scene probe: scene_probe.c is the only user. Pure functions, any thread;
 * CPU only (passes over the pilot frames). */
#pragma once
#include <glib.h>

#include "daemon/operating/scene_probe.h"
#include "daemon/operating/stripe_model.h"
#include "proc/column_stats.h"
#include "proc/image.h"

typedef struct {
  DsColumnStats stats;
  DsStripeHarmonics fit;
  guint64 clipped;           /* pixels at the clip level in either frame */
  gboolean ok;
  DsStripeHarmonics on_envelope;   /* ds_probe_pairs_refit_pattern ()'s pass */
} DsProbePairFit;

/* The light that carries the stripes' harmonics at x = Q / n, read off the pilot pairs' first
 * harmonics: A_1 / G_1 at x = Q (G_1 the calibrated pattern's gain: ds_probe_model_gain ()) of
 * each pair whose first harmonic is above 4 times its noise, sorted by x. The first harmonics
 * only: the blur's 0.05 px uncertainty moves the higher ones' gains by 4-20 %, and an objects'
 * column profile puts several % on them (daemon/probe-narrow's higher-harmonic-only case, a third
 * harmonic 10 % low: Ld read 3.7 % low with it in the pool). */
#define DS_PROBE_POOL_MAX 8
typedef struct {
  guint n;
  double x[DS_PROBE_POOL_MAX], y[DS_PROBE_POOL_MAX];
} DsProbeLightPool;

void ds_probe_light_pool_add (DsProbeLightPool *pool, const DsStripeHarmonics *fit, const DsStripeModel *pattern,
                              double period, guint width);

/* Linear in x between the pool's neighbours of x, the nearest one's beyond them; 0 when empty. */
double ds_probe_light_pool_at (const DsProbeLightPool *pool, double x);

/* Refits the pairs (fitted plainly by ds_probe_pair_fit (), at periods[i]) of square stripes whose
 * opposite phases do not sum flat on the scene's envelope, the stripes' even harmonics taken off
 * their sums at the light the pool reads at each one's x (scene_probe_pairs.c: pattern_envelope ()),
 * DS_PROBE_POOL_PASSES times, the pool read from the pairs' fits before each pass. pattern: the
 * duty, black level, calibrated blur and aperture. Only where objects make the columns' level vary
 * (its RMS over the columns, the stripes taken off) more than the stripes' even harmonics make
 * the pair's sum vary, on the pair at pairs[0]: else FALSE, the plain fits unchanged. */
#define DS_PROBE_POOL_PASSES 3
gboolean ds_probe_pairs_refit_pattern (DsProbePairFit *const *pairs, const double *periods, guint n_pairs, double dark_dn,
                                   const DsStripeModel *pattern);

/* The places whose stripes' peaks reach the clip level in the pilot frames, and what their
 * troughs say about their light. */
typedef struct {
  double fraction;           /* of the samples */
  double mean_peak_over_trough, mean_sq_peak_over_trough, mean_trough;   /* DN, over those samples */
} DsProbeClippedPlaces;

/* Fits one pair (envelope_dn >= 0: on the scene's envelope, for stripes whose opposite phases sum
 * flat). Fills out, which the caller zeroes first and clears with ds_column_stats_clear (&out->stats)
 * whether or not this succeeds (the statistics may be allocated before the harmonics' fit fails);
 * FALSE with DS_PROTOCOL_ERROR_DEVICE when most pixels clip, or the statistics' or the fit's error. */
gboolean ds_probe_pair_fit (const DsImage *a, const DsImage *b, const DsImage *stat_a, const DsImage *stat_b,
                            double ceiling, double period, double envelope_dn, DsProbePairFit *out, GError **error);

/* masked[i]: a new F32 copy of lit[i] with the places that clip set to NAN, or NULL when none do
 * (the caller owns the copies). */
void ds_probe_mask_clipped_places (const DsImage *const *lit, guint n_lit, double ceiling, double period_px,
                                   DsImage **masked, DsProbeClippedPlaces *places);

/* Updates out's ld_mean, ld_spread, lg_mean (and the leak and its note) for the places left out. */
void ds_probe_count_clipped_places (DsSceneProbe *out, const DsProbeClippedPlaces *c, double black_level,
                                    double pattern_mean);
