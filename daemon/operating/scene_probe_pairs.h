/* The scene probe's pilot pairs (scene_probe.h): the column statistics and stripe harmonics of
 * one pair of opposite phases, and the places whose stripes' peaks clip, left out of those
 * statistics and counted back into the probe's Ld, its spread and Lg from their troughs.
 * Used by the scene probe (scene_probe.c) and the pilot's stripe check (pilot_stripes.c). Pure functions, any thread;
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
} DsProbePairFit;

/* The places whose stripes' peaks reach the clip level in the pilot frames, and what their
 * troughs say about their light. */
typedef struct {
  double fraction;           /* of the samples */
  double mean_peak_over_trough, mean_sq_peak_over_trough, mean_trough;   /* DN, over those samples */
} DsProbeClippedPlaces;

/* The pilot's rule for clipping: more than half the pixels at the clip level in either frame of
 * the pair (a sample at the clip level says only that its light is at least that) leave too few
 * to measure the scene by, and the request is refused with DS_OPERATING_ERROR_CLIPPED, naming the
 * remedy. clipped_out (may be NULL): the pixels at the clip level. ceiling <= 0: nothing clips. */
gboolean ds_probe_pair_check_clipping (const DsImage *a, const DsImage *b, double ceiling, guint64 *clipped_out,
                                       GError **error);

/* Sets *error for a pair's stripe harmonics that could not be fitted (fit_error, may be NULL): where
 * samples were left out at the clip level (clipped pixels, or stats->excluded), the columns they
 * emptied are why, and the error is DS_OPERATING_ERROR_CLIPPED with the remedy (lower the exposure
 * or the gain); otherwise a copy of fit_error. */
void ds_probe_pair_refuse_unfitted (const DsColumnStats *stats, guint64 clipped, double ceiling, double period,
                                    const GError *fit_error, GError **error);

/* Fills out, which the caller zeroes first and clears with ds_column_stats_clear (&out->stats)
 * whether or not this succeeds (the statistics may be allocated before the harmonics' fit fails);
 * FALSE with DS_OPERATING_ERROR_CLIPPED when most pixels clip, or the statistics' or the fit's error. */
gboolean ds_probe_pair_fit (const DsImage *a, const DsImage *b, const DsImage *stat_a, const DsImage *stat_b,
                            double ceiling, double period, double envelope_dn, DsProbePairFit *out, GError **error);

/* masked[i]: a new F32 copy of lit[i] with the places that clip set to NAN, or NULL when none do
 * (the caller owns the copies). */
void ds_probe_mask_clipped_places (const DsImage *const *lit, guint n_lit, double ceiling, double period_px,
                                   DsImage **masked, DsProbeClippedPlaces *places);

/* Updates out's light (ld_mean, ld_spread, lg_mean) and leak for the places left out, the leak's
 * change appended to leak_note (the leak's note as it is built). */
void ds_probe_count_clipped_places (DsSceneProbe *out, const DsProbeClippedPlaces *c, double black_level,
                                    double pattern_mean, GString *leak_note);

/* The spread of Ld from one column to the next, mean_x (Ld(x)^2) / mean_x (Ld(x))^2 over the
 * columns' mean Ld: the column statistics' mean square holds only the spread within each column
 * (an object that spans the rows, a vertical grid line, is not in it, and the spread would read
 * low). The columns' mean differences are Ld(x) Dp(x); their energy against the
 * fitted harmonics' (a uniform Ld times the pattern) is the spread across columns, once the
 * same ratio for the model's own profile, whose harmonics the fit leaves out (those at or
 * above the Nyquist frequency, aliased), divides out. */
double ds_probe_pair_spread_across_columns (const DsProbePairFit *f, const DsStripeModel *geometry,
                                           const DsSceneProbe *out);
