/* Each pixel's lit level from a pair of opposite phases: (L0 + L1 - 2 D) / e(x), where D is the
 * dark frame and e(x) the sum the pattern model gives the two phases at column x (1 where a
 * stripe is fully lit). The two phases together light every column the pattern reaches, so the
 * quotient is the level a fully lit stripe would have there, whatever the phase.
 *
 * Columns where e is below half its mean over all columns are skipped: square stripes of a duty
 * under 1/2 leave gaps lit by neither phase, where the quotient would divide noise by a small
 * number. A pixel with a sample of either lit frame at or above the clip level, or not finite, is
 * skipped too: its sum is not its light.
 *
 * Pure function, any thread; the caller owns every buffer. */
#pragma once
#include <glib.h>

#include "proc/image.h"

G_BEGIN_DECLS

/* The quantile of the pixels' lit levels taken as a clear pixel's, by the calibration's open
 * field (proc/calibration.h) and by the scene probe's lost light alike, so that the two compare:
 * objects, dust and their shaded edges only darken pixels, and as long as they cover less than
 * 1 - DS_LIT_LEVEL_QUANTILE of the frame the quantile is a pixel the light crossed alone; an
 * uneven field lifts both quantiles alike. */
#define DS_LIT_LEVEL_QUANTILE 0.8

/* Writes the lit level of the pixels kept (above) in rows 0, row_step, 2 row_step, ... (row_step
 * >= 1) of l0, l1 and dark (one shape) into levels, row by row, and returns how many. expected
 * holds e for each of the frames' columns; clip <= 0 clips nothing. levels must hold
 * width * ceil (height / row_step) values. expected_mean (may be NULL) gets the mean of e over the
 * columns kept, 0 when none is. */
gsize ds_lit_level_samples (const DsImage *l0, const DsImage *l1, const DsImage *dark, const double *expected,
                            double clip, guint row_step, double *levels, double *expected_mean);

G_END_DECLS
