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
 * samples (a dark frame's 1.5 DN), and unlike the plain mean it ignores scene edges along y.
 * Samples at or above `ceiling` (0: none) are left out. NAN below 3 rows or without samples. */
double ds_column_stats_noise_dn (const DsImage *a, const DsImage *b, double ceiling);

G_END_DECLS
