/* Column statistics of a pair of frames: the reductions the automatic operating point makes of
 * its pilot frames (daemon/operating/scene_probe.h). Stripes vary along x only, so averaging
 * each column over the rows keeps the whole stripe pattern and averages noise and scene
 * structure down; the mean square of the difference of two frames keeps how Ld varies across
 * the scene (docs/accuracy.md, "Automatic operating point").
 *
 * Pure functions, any thread, CPU only (one pass over the frames). */
#pragma once
#include <glib.h>

#include "proc/image.h"

G_BEGIN_DECLS

typedef struct {
  guint width;
  double *mean_diff;     /* per column: mean over rows of a - b */
  double *mean_sq_diff;  /* per column: mean over rows of (a - b)^2 */
  double *mean_sum;      /* per column: mean over rows of a + b */
  guint32 *count;        /* samples used per column (0: the column's values are 0) */
  guint64 excluded;      /* samples left out: at or above the ceiling, or not finite */
} DsColumnStats;

/* a and b of one size (any sample types); b NULL reads as a frame of zeros. Samples where a or
 * b is at or above `ceiling` (saturated; 0 = no ceiling) or not finite are left out.
 * Fails INVALID_ARGUMENT on a size mismatch. */
gboolean ds_column_stats_compute (const DsImage *a, const DsImage *b, double ceiling,
                                  DsColumnStats *out, GError **error);
void ds_column_stats_clear (DsColumnStats *stats);

/* The temporal noise (DN, 1 sigma) of a - b (b NULL: of a), from the second difference along y
 * d = v(y-1) - 2 v(y) + v(y+1) (stripes vary along x and cancel; var d = 6 sigma^2 for white
 * noise): the mean of d^2 over the samples within 5 robust sigmas (from the median of |d|),
 * corrected for the truncation. Unlike the median alone it is not quantised by integer
 * samples (a dark frame's 1.5 DN), and unlike the plain mean it ignores sharp scene edges along
 * y (not soft ones: ds_column_stats_noise_sets_dn ()). One scale for all the samples: where most
 * of them are dim it cuts into the bright ones' noise (ds_column_stats_noise_sets_dn () does not).
 * Samples at or above `ceiling` (0: none) are left out. NAN below 3 rows or without samples. */
double ds_column_stats_noise_dn (const DsImage *a, const DsImage *b, double ceiling);

/* The temporal noise (DN, 1 sigma) of (a0 + a1) - (b0 + b1), as ds_column_stats_noise_dn () reads
 * it, for two pairs of opposite phases at two periods, on the columns where the two pairs' sums
 * are equal: there each pair sums to the scene under the same light, so the scene itself cancels,
 * its soft structure along y too (objects' blurred edges, which the second difference of one pair
 * keeps within its cut, and reads as shot noise above the sensor's), and only the four frames'
 * noise is left: var = var a0 + var a1 + var b0 + var b1, the rms over the samples of a noise that
 * grows with the signal: each sample is cut at its own level's scale (a robust line in the level,
 * column_stats.c), so dim places in the majority do not cut into the bright ones' core. Sine
 * stripes and square ones of duty 1/2 sum to a constant at every column (columns NULL: all are
 * read); square stripes of another duty leave gaps or overlaps, at other columns for each period,
 * which the caller leaves out (columns[x] 0). All four of one size; columns, where given, holds
 * one flag per column.
 * mean_level (NULL: not wanted): the mean of a0 + a1 + b0 + b1 over the samples the noise was read
 * on (the signal whose shot noise it holds; a frame's dark level not taken off). */
double ds_column_stats_noise_sets_dn (const DsImage *const set_a[2], const DsImage *const set_b[2],
                                      const guint8 *columns, double ceiling, double *mean_level);

/* The temporal noise (DN, 1 sigma) of one pair of opposite phases a, b with the scene cancelled,
 * for any pattern: per column c = (1 - rho) a - (1 + rho) b, with rho[x] the column's ratio of
 * a - b to a + b - 2 dark_dn (NAN: the column is left out; clamped to [-1, 1]). Where an object's
 * transmittance T(x, y) multiplies the stripes p(x), a - b and a + b - 2 dark both scale with T
 * down a column, so c holds no T and its second difference along y only the two frames' noise
 * (a - b alone keeps T's soft edges and shading inside any cut, and reads them as noise).
 * Scattered light adds to a and b alike and is cancelled only where it is smooth along y. The
 * reading is ds_column_stats_noise_sets_dn ()'s (strata by level, each sample cut at its own
 * level's scale). With each frame's variance var0 + K (f - dark), c's mean square over the
 * samples read is var0 * mean_w2 + K * mean_shot: mean_w2 the mean of (1 - rho)^2 + (1 + rho)^2,
 * mean_shot of (1 - rho)^2 (a - dark) + (1 + rho)^2 (b - dark) (either may be NULL; NAN when the
 * result is). Samples at or above `ceiling` (0: none) are left out; NAN below 3 rows, on a size
 * mismatch or without samples. */
double ds_column_stats_noise_pair_dn (const DsImage *a, const DsImage *b, const double *rho, double dark_dn,
                                      double ceiling, double *mean_w2, double *mean_shot);

G_END_DECLS
