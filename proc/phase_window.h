/* The sliding phase window: a result for every new frame from the newest frame of each of the
 * N phases (continuous mode `results = per-frame`).
 *
 * A window holds, per phase, the newest frame lit with it. Once every phase has a frame since
 * the last break, each push completes a window and ds_phase_window_finalize_into gives the
 * result of a fresh DsPhaseSet fed those N frames in the order they arrived, bit for bit: the
 * window is only a faster way to the same numbers, never a different estimator. In cyclic
 * sequencing (phase k follows phase k-1 mod N) the window is exactly the last N frames.
 *
 * One frame per phase (M = 1): a second frame of a phase replaces the first, it is not
 * averaged. A lost or refused frame breaks the window (ds_phase_window_break): no result until
 * every phase has a frame again, so no result mixes frames from both sides of a gap.
 *
 * Threading: one thread at a time (the daemon's fold thread); nothing blocks but CPU and
 * memory. Errors: DS_PROC_ERROR; on any error the window is unchanged. */
#pragma once
#include <glib.h>

#include "proc/image.h"
#include "proc/separation.h"

G_BEGIN_DECLS

typedef struct DsPhaseWindow DsPhaseWindow;

/* A window for width x height frames. params as for ds_phase_set_new (n_phases = N). Fails
 * as ds_phase_set_new does. */
DsPhaseWindow *ds_phase_window_new (const DsSeparationParams *params, guint width, guint height,
                                    GError **error);
void ds_phase_window_free (DsPhaseWindow *window);
G_DEFINE_AUTOPTR_CLEANUP_FUNC (DsPhaseWindow, ds_phase_window_free)

/* Dark frame, as ds_phase_set_set_dark; kept across breaks. When the window keeps sine's
 * counts (phase_window.c) the minimum is kept only with a dark frame, so setting one (or
 * another, or none) makes the next result a refold. */
gboolean ds_phase_window_set_dark (DsPhaseWindow *window, const DsImage *dark, GError **error);

/* Takes the newest frame, lit with `phase` (0 <= phase < N); it replaces the window's frame of
 * that phase. The frame is only read, and not after this returns (a camera buffer may be
 * lent). Frames must share the window's size and one sample type and bit depth (as a set's);
 * on a mismatch SIZE_MISMATCH and nothing changes. *complete (may be NULL) says whether every
 * phase now has a frame since the last break, so that a result can be computed. */
gboolean ds_phase_window_push (DsPhaseWindow *window, guint phase, const DsImage *frame,
                               gboolean *complete, GError **error);

/* ds_phase_window_push, then, when the window is complete, ds_phase_window_finalize_into
 * `sep`: the same state and result bit for bit, but once the window's state is current
 * (after its first result since a break) each block of rows is pushed and finalized while
 * it is in cache, on the finalize's threads. *pushed (may be NULL) says whether the frame went
 * in: on an error with *pushed TRUE the window took the frame, as after a successful push
 * and a failed finalize (planes of the wrong shape). *complete as for the push; no result
 * when FALSE. */
gboolean ds_phase_window_push_finalize_into (DsPhaseWindow *window, guint phase,
                                             const DsImage *frame, DsSeparation *sep,
                                             gboolean *complete, gboolean *pushed, GError **error);

/* Forgets every frame (keeps the dark): the next result needs a frame of every phase. For a
 * lost frame, a frame the phase check refused, or a changed setting. */
void ds_phase_window_break (DsPhaseWindow *window);

/* Phases that have a frame since the last break (0..N); N when complete. */
guint ds_phase_window_fill (const DsPhaseWindow *window);

/* Frames pushed since the last break, whatever their phase. */
guint64 ds_phase_window_frames_since_break (const DsPhaseWindow *window);

/* How many pushes the current window's frames span, oldest to newest inclusive: N in cyclic
 * sequencing, more when a phase was repeated out of turn; 0 when not complete. */
guint64 ds_phase_window_span (const DsPhaseWindow *window);

/* The result of the current window into `sep`, as ds_phase_set_finalize_into (planes reused
 * where their shape fits). NOT_ENOUGH_PHASES when the window is not complete. */
gboolean ds_phase_window_finalize_into (DsPhaseWindow *window, DsSeparation *sep, GError **error);

/* Threads for the pushes and for the finalize, as ds_phase_set_set_fold_threads and
 * ds_phase_set_set_finalize_threads for a set (0, the default: all of params.threads); the
 * results are the same bit for bit with any number. A fused push and finalize
 * (ds_phase_window_push_finalize_into) runs on the finalize's threads. A caller receiving the next frame on the
 * same cores meanwhile may leave them some. */
void ds_phase_window_set_push_threads (DsPhaseWindow *window, guint threads);
void ds_phase_window_set_finalize_threads (DsPhaseWindow *window, guint threads);

/* Memory for the benchmark's ratio, in bytes: *window_bytes what the window holds per pixel
 * (its set's state, the kept frames and sine's counts), *set_bytes what one DsPhaseSet of the same
 * parameters holds for the frames pushed so far (0 before the first result). Either may be
 * NULL. */
void ds_phase_window_memory (const DsPhaseWindow *window, gsize *window_bytes, gsize *set_bytes);

/* Pixels whose max and min (sine with counts: min) were rebuilt from the kept frames since the
 * window was made (a
 * push retired a pixel's extreme and brought no new one, at that pixel or at enough pixels of
 * its row that the whole row was rebuilt); for the benchmark. */
guint64 ds_phase_window_rebuilt_pixels (const DsPhaseWindow *window);

G_END_DECLS
