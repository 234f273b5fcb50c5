/* Separation of one frame from the stripes' spatial neighbourhood (Nayar et al. 2006, the
 * single-image variant): along x, the pixels of one stripe period see the pattern at every
 * shift a phase set would apply in time. Where the scene is uniform over that window, the
 * window's samples are a phase set of one frame, and a set's estimator applied to them
 * separates the frame alone. The cost is resolution along x: each output pixel is the window
 * of `window_px` columns around it (clamped at the frame's sides so that every window is
 * whole), so detail finer than one period is averaged (sine) or mixed into max/min (maxmin).
 * For moving scenes this trades spatial resolution for time: no frame waits for another.
 *
 * Estimators (docs/estimators.md, "Single frame"):
 * - sine: the least-squares fit of M + a cos(2 pi x/P) + b sin(2 pi x/P) over the window of
 *   ceil(P) columns (P need not be whole: the fit is exact for any P on a uniform scene lit
 *   by sine stripes); A = sqrt(a^2 + b^2), Ld = A/h, Lg = M/m - Ld with the pattern's m and h
 *   as in the phase-set sine estimator;
 * - maxmin: max and min over the window of ceil(P) columns (a whole period, so each pixel's
 *   window holds a lit and an unlit column when the stripes are wide enough against the
 *   pixel), Ld = (max - min)/(1 - b), Lg = (min - b Ld)/m.
 * robust needs more samples per level than one period offers and is refused.
 *
 * Pure functions, any thread, CPU and memory only (two rows of scratch per call). */
#pragma once
#include <glib.h>

#include "proc/image.h"
#include "proc/separation.h"

G_BEGIN_DECLS

typedef struct {
  double period_px;  /* P, the stripe period on the sensor along x: > 2 (maxmin), >= 3 (sine) */
  guint window_px;   /* columns each output pixel is computed from: ceil(P) */
} DsSingleFrameInfo;

/* Separates `frame` (u8, u16 or f32; `dark`, optional, of the same shape, subtracted first)
 * with params->estimator (maxmin or sine), pattern, duty, black_level, harmonic_gain
 * (0: the theoretical h) and saturation_level (0: 2^bit_depth - 1 for integer frames) at
 * period params->geometry.period_px. params->n_phases is not used. *out gets transmissive,
 * scattered and mask (SATURATED, NONFINITE, NEGATIVE as for sets; meta.n_phases is the
 * window). Fails INVALID_ARGUMENT (robust, a period out of range, a frame narrower than the
 * window, a dark frame of another shape) or ILL_CONDITIONED (1/(1-b), 1/m or 1/h above
 * DS_MAX_CONDITION), naming the parameter; nothing is returned then. */
gboolean ds_single_frame_separate (const DsImage *frame, const DsImage *dark, const DsSeparationParams *params,
                                   DsSeparation **out, DsSingleFrameInfo *info, GError **error);

G_END_DECLS
