/* Private to proc/phase_window.c: the sliding window's row kernels. A push retires the slot's
 * old frame and adds the new one to the phase set's integer state (separation_internal.h):
 * exact integer arithmetic, so the state stays what folding the window's frames gives in any
 * order. */
#pragma once
#include <glib.h>

G_BEGIN_DECLS

/* ds_window_retire_row: the sums of ds_window_push_row and the slot's row, not the extremes
 * (for a push that rebuilds every row's extremes). */
/* ds_window_extrema_row: mx, mn = the row of one kept plane (first) or their max and min with
 * it; a whole row's extremes rebuilt plane by plane.
 * One row of a push into a slot of u8 or u16 samples. `ring` is the slot's row: it holds the
 * retired samples and receives the new ones (`in`). sum (NULL: none) gets new - old; cs and sn
 * (NULL: none) get the fixed-point weights times new - old. mx and mn take the new sample when
 * it is a new extreme; where the retired sample was the extreme and the new one is not,
 * need[x] is set (else cleared): that pixel's extreme must be rebuilt from the kept frames
 * (ds_window_rescan_row_* for a few pixels of a row, ds_window_extrema_row_* plane by plane for
 * a whole row). Returns how many pixels need it. */
#define DS_DECLARE_WINDOW_KERNELS(T, NAME)                                                        \
  guint ds_window_push_row_##NAME (const T *in, T *ring, guint16 *mx, guint16 *mn, guint32 *sum,  \
                                   gint32 c, gint32 s, gint64 *cs, gint64 *sn, guint8 *need,      \
                                   gsize w);                                                      \
  void ds_window_rescan_row_##NAME (const T *plane0, gsize plane_stride, guint n, guint16 *mx,    \
                                    guint16 *mn, const guint8 *need, guint count, gsize w);       \
  void ds_window_extrema_row_##NAME (const T *plane, guint16 *mx, guint16 *mn, gboolean first,    \
                                     gsize w);                                                    \
  void ds_window_retire_row_##NAME (const T *in, T *ring, guint32 *sum, gint32 c, gint32 s,       \
                                    gint64 *cs, gint64 *sn, gsize w);
DS_DECLARE_WINDOW_KERNELS (guint8, u8)
DS_DECLARE_WINDOW_KERNELS (guint16, u16)

/* The integer sine's push (proc/phase_window.c, "sine keeps counts"): sum, cs and sn as
 * ds_window_push_row; satn[x] (the kept samples >= thr) gets (new >= thr) - (old >= thr), exact
 * since it counts whole samples; the new samples go into `ring`. With mn (NULL: none), the
 * minimum alone as ds_window_push_row keeps it: need[x] set where the retired sample was the
 * minimum and the new one is above it; returns how many (0 without mn).
 * ds_window_satcount_row: satn = (plane >= thr) (first) or satn + (plane >= thr).
 * ds_window_rescan_min_row and ds_window_min_row: ds_window_rescan_row and
 * ds_window_extrema_row for the minimum alone. */
#define DS_DECLARE_WINDOW_COUNT_KERNELS(T, NAME)                                                  \
  guint ds_window_push_counts_row_##NAME (const T *in, T *ring, guint8 *satn, guint32 thr,        \
                                          guint16 *mn, guint32 *sum, gint32 c, gint32 s,          \
                                          gint64 *cs, gint64 *sn, guint8 *need, gsize w);         \
  void ds_window_satcount_row_##NAME (const T *plane, guint8 *satn, guint32 thr, gboolean first,  \
                                      gsize w);                                                   \
  void ds_window_rescan_min_row_##NAME (const T *plane0, gsize plane_stride, guint n,             \
                                        guint16 *mn, const guint8 *need, guint count, gsize w);   \
  void ds_window_min_row_##NAME (const T *plane, guint16 *mn, gboolean first, gsize w);
DS_DECLARE_WINDOW_COUNT_KERNELS (guint8, u8)
DS_DECLARE_WINDOW_COUNT_KERNELS (guint16, u16)

G_END_DECLS
