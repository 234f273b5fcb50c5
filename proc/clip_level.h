/* Where a sensor's frames clip, and which pixels do: one rule for every reader of pilot frames.
 *
 * A pixel clips at the format's top (the ADC's last code) or, where the full well is reached
 * first, at a level below it where its samples pile up. Light alone never piles samples at one
 * value: noise (read noise, and the photons' shot noise wherever there is light) spreads an
 * unclipped distribution over many values, and its brightest samples are a tail that thins
 * towards its top. So a frame clips at its highest sample value when at least 0.02 %
 * (DS_CLIP_PILE_PERCENTILE) of its samples hold that value, it lies above the dark level, at or below the given
 * saturation, and the frame has noise to spread it (a noise-free frame's flat top is the
 * pattern's plateau, not a clip): the dark frame's noise, or where that is below half a DN (a
 * sensor with little read noise) the lit frame's own. Float frames carry no format top and are
 * not searched. A pixel of a pair is clipped where either frame is at or above the level.
 *
 * Pure functions, any thread. */
#pragma once
#include <glib.h>

#include "proc/image.h"

G_BEGIN_DECLS

/* A pile-up: the share of a frame's samples at its top, 0.02 %, as the percentile that must
 * reach the top. */
#define DS_CLIP_PILE_PERCENTILE 99.98

typedef struct {
  double level;      /* the clip level: saturation, or a pile-up found at or below it; 0 = none */
  gboolean piled;    /* a pile-up was found (level is where the sensor clips, measured) */
} DsClipLevel;

/* Where frame f (integer samples) may clip: TRUE, with *top its highest sample value, where the
 * percentile pile_percentile of its samples reaches that value (DS_CLIP_PILE_PERCENTILE: 0.02 % of
 * them hold it) and, with need_own_noise (no noisy dark frame to vouch for the sensor's noise),
 * its own noise spreads its other samples over 0.5 DN or more. */
gboolean ds_clip_level_pile_top (const DsImage *f, double pile_percentile, gboolean need_own_noise, double *top);

/* The clip level of lit[0..n_lit) given the dark frame and saturation (the format's top or a
 * configured clip level; 0 = none). */
void ds_clip_level_find (const DsImage *dark, const DsImage *const *lit, guint n_lit, double saturation,
                         DsClipLevel *out);

/* Pixels where a or b (NULL: a alone) is at or above level; 0 for a level <= 0. */
guint64 ds_clip_count (const DsImage *a, const DsImage *b, double level);

G_END_DECLS
