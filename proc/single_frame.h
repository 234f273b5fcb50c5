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
 * Arithmetic: the window sums and extremes are taken in single precision by doubling (windows
 * of 1, 2, 4 ... columns, each the sum or extreme of two of the level below, the window the
 * levels its length's binary digits name), so every sum is a pairwise sum of at most ceil(P)
 * samples: its rounding error is at most 2 log2(ceil(P)) float epsilons of the sum of the
 * samples' magnitudes, with no drift along the row. Extremes are exact (on u8 and u16 frames
 * without a dark frame, taken in the samples' own type). When the window is a whole number of
 * periods its normal matrix is isotropic and the fit skips the rotation to the first
 * window's basis, which changes nothing but float rounding. */
#pragma once
#include <glib.h>

#include "proc/image.h"
#include "proc/separation.h"

G_BEGIN_DECLS

typedef struct {
  double period_px;  /* P, the stripe period on the sensor along x: > 2 (maxmin), >= 3 (sine) */
  guint window_px;   /* columns each output pixel is computed from: ceil(P) */
} DsSingleFrameInfo;

/* The window for stripe period P: ceil(P) columns, a whole period (a period a hair above an
 * integer from rounding in its computation counts as that integer). */
guint ds_single_frame_window_px (double period_px);

/* The plan for frames of one geometry: the pattern's constants, the basis tables, the threads
 * and their row scratch. Made once per capture; one thread at a time uses it. */
typedef struct DsSingleFrame DsSingleFrame;

/* For width x height frames with params->estimator (maxmin or sine), pattern, duty,
 * black_level, harmonic_gain (0: the theoretical h), saturation_level (0: 2^bit_depth - 1 for
 * integer frames), threads (0: one per processor; frames under DS_SINGLE_FRAME_THREADED_PIXELS
 * use the caller's thread alone) at period params->geometry.period_px. params->n_phases is
 * not used. Fails INVALID_ARGUMENT (robust, a period out of range, a frame narrower than the
 * window) or ILL_CONDITIONED (1/(1-b), 1/m or 1/h above DS_MAX_CONDITION), naming the
 * parameter. */
DsSingleFrame *ds_single_frame_new (const DsSeparationParams *params, guint width, guint height, GError **error);
void ds_single_frame_free (DsSingleFrame *sf);
G_DEFINE_AUTOPTR_CLEANUP_FUNC (DsSingleFrame, ds_single_frame_free)

DsSingleFrameInfo ds_single_frame_info (const DsSingleFrame *sf);

/* Separates `frame` (u8, u16 or f32 of the plan's size; `dark`, optional, of the same shape,
 * subtracted first) into `sep`, which the caller owns and may reuse from frame to frame:
 * transmissive, scattered (f32) and mask (u8) it already has are written in place and must
 * have the frame's size and their type, missing ones are allocated, other planes freed.
 * Mask: SATURATED, NONFINITE (any sample of the pixel's window), NEGATIVE, counted in meta;
 * meta.n_phases is the window, meta.frames_per_phase 1. The result is the same bit for bit
 * with any number of threads. Fails INVALID_ARGUMENT (a frame or plane of another size) or
 * SIZE_MISMATCH (a dark frame of another shape); the planes' contents are then unspecified. */
gboolean ds_single_frame_separate_into (DsSingleFrame *sf, const DsImage *frame, const DsImage *dark,
                                        DsSeparation *sep, GError **error);

/* One frame, one call: ds_single_frame_new, ds_single_frame_separate_into a new result. *out
 * is set only on success. info (may be NULL) gets the window. */
gboolean ds_single_frame_separate (const DsImage *frame, const DsImage *dark, const DsSeparationParams *params,
                                   DsSeparation **out, DsSingleFrameInfo *info, GError **error);

/* Frames with fewer pixels are separated on the caller's thread alone: waking workers would
 * cost more than the rows. */
#define DS_SINGLE_FRAME_THREADED_PIXELS (128u * 1024u)

G_END_DECLS
