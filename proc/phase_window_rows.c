/* The sliding window's row kernels (proc/phase_window_rows.h). Contiguous rows, restrict
 * pointers, selects instead of branches, so that the auto-vectoriser (proc/CMakeLists.txt)
 * turns each loop into vector code. */
#include "proc/phase_window_rows.h"

#include <string.h>

#include "proc/simd.h"

#define DEFINE_WINDOW_KERNELS(T, NAME)                                                            \
  DS_KERNEL void window_sum_##NAME (const T *restrict in, const T *restrict old,                  \
                                    guint32 *restrict sum, gsize w)                               \
  {                                                                                               \
    /* modulo 2^32, and the true sum is in range: exact */                                        \
    for (gsize x = 0; x < w; x++)                                                                 \
      sum[x] += (guint32) in[x] - (guint32) old[x];                                               \
  }                                                                                               \
  DS_KERNEL void window_harmonic_##NAME (const T *restrict in, const T *restrict old, gint32 c,   \
                                         gint32 s, gint64 *restrict cs, gint64 *restrict sn,      \
                                         gsize w)                                                 \
  {                                                                                               \
    for (gsize x = 0; x < w; x++) {                                                               \
      gint32 d = (gint32) in[x] - (gint32) old[x];                                                \
      cs[x] += (gint64) c * d;                                                                    \
      sn[x] += (gint64) s * d;                                                                    \
    }                                                                                             \
  }                                                                                               \
  DS_KERNEL guint window_extrema_##NAME (const T *restrict in, T *restrict ring,                  \
                                         guint16 *restrict mx, guint16 *restrict mn,              \
                                         guint8 *restrict need, gsize w)                          \
  {                                                                                               \
    guint32 count = 0;                                                                            \
    for (gsize x = 0; x < w; x++) {                                                               \
      guint16 v = in[x], r = ring[x], hi = mx[x], lo = mn[x];                                     \
      /* a new extreme replaces the old one whatever leaves; otherwise the old one stays unless  \
       * it is the sample leaving (then only the other kept samples can tell the new one) */     \
      guint8 lost = (guint8) (((v < hi) & (r == hi)) | ((v > lo) & (r == lo)));                   \
      mx[x] = v > hi ? v : hi;                                                                    \
      mn[x] = v < lo ? v : lo;                                                                    \
      ring[x] = in[x];                                                                            \
      need[x] = lost;                                                                             \
      count += lost;                                                                              \
    }                                                                                             \
    return count;                                                                                 \
  }                                                                                               \
  DS_CLONES guint ds_window_push_row_##NAME (const T *in, T *ring, guint16 *mx, guint16 *mn,      \
                                             guint32 *sum, gint32 c, gint32 s, gint64 *cs,        \
                                             gint64 *sn, guint8 *need, gsize w)                   \
  {                                                                                               \
    if (sum)                                                                                      \
      window_sum_##NAME (in, ring, sum, w);                                                       \
    if (cs)                                                                                       \
      window_harmonic_##NAME (in, ring, c, s, cs, sn, w);                                         \
    return window_extrema_##NAME (in, ring, mx, mn, need, w);                                     \
  }                                                                                               \
  DS_KERNEL void window_extrema_all_##NAME (const T *restrict p, guint16 *restrict mx,            \
                                            guint16 *restrict mn, gboolean first, gsize w)        \
  {                                                                                               \
    if (first)                                                                                    \
      for (gsize x = 0; x < w; x++)                                                               \
        mx[x] = mn[x] = p[x];                                                                     \
    else                                                                                          \
      for (gsize x = 0; x < w; x++) {                                                             \
        guint16 v = p[x];                                                                         \
        mx[x] = v > mx[x] ? v : mx[x];                                                            \
        mn[x] = v < mn[x] ? v : mn[x];                                                            \
      }                                                                                           \
  }                                                                                               \
  DS_CLONES void ds_window_rescan_row_##NAME (const T *plane0, gsize plane_stride, guint n,       \
                                              guint16 *mx, guint16 *mn, const guint8 *need,       \
                                              guint count, gsize w)                               \
  {                                                                                               \
    /* the few flagged pixels, each from its n samples (a dense row goes plane by plane) */      \
    for (gsize x = 0; x < w && count > 0; x++) {                                                  \
      if (!need[x])                                                                               \
        continue;                                                                                 \
      count--;                                                                                    \
      guint16 hi = plane0[x], lo = plane0[x];                                                     \
      for (guint k = 1; k < n; k++) {                                                             \
        guint16 v = plane0[x + k * plane_stride];                                                 \
        hi = v > hi ? v : hi;                                                                     \
        lo = v < lo ? v : lo;                                                                     \
      }                                                                                           \
      mx[x] = hi;                                                                                 \
      mn[x] = lo;                                                                                 \
    }                                                                                             \
  }                                                                                               \
  DS_CLONES void ds_window_retire_row_##NAME (const T *in, T *ring, guint32 *sum, gint32 c,       \
                                              gint32 s, gint64 *cs, gint64 *sn, gsize w)          \
  {                                                                                               \
    if (sum)                                                                                      \
      window_sum_##NAME (in, ring, sum, w);                                                       \
    if (cs)                                                                                       \
      window_harmonic_##NAME (in, ring, c, s, cs, sn, w);                                         \
    memcpy (ring, in, w * sizeof (T));                                                            \
  }                                                                                               \
  DS_CLONES void ds_window_extrema_row_##NAME (const T *plane, guint16 *mx, guint16 *mn,          \
                                               gboolean first, gsize w)                           \
  {                                                                                               \
    window_extrema_all_##NAME (plane, mx, mn, first, w);                                          \
  }

DEFINE_WINDOW_KERNELS (guint8, u8)
DEFINE_WINDOW_KERNELS (guint16, u16)

#define DEFINE_WINDOW_COUNT_KERNELS(T, NAME)                                                      \
  DS_KERNEL void window_satcount_##NAME (const T *restrict in, const T *restrict old,             \
                                         guint8 *restrict satn, guint32 thr, gsize w)             \
  {                                                                                               \
    /* a count of whole samples, in range 0..N: exact whatever the order of the pushes */        \
    for (gsize x = 0; x < w; x++)                                                                 \
      satn[x] = (guint8) (satn[x] + ((guint32) in[x] >= thr) - ((guint32) old[x] >= thr));        \
  }                                                                                               \
  DS_KERNEL guint window_min_##NAME (const T *restrict in, T *restrict ring,                      \
                                     guint16 *restrict mn, guint8 *restrict need, gsize w)        \
  {                                                                                               \
    guint32 count = 0;                                                                            \
    for (gsize x = 0; x < w; x++) {                                                               \
      guint16 v = in[x], r = ring[x], lo = mn[x];                                                 \
      /* as window_extrema's minimum half */                                                      \
      guint8 lost = (guint8) ((v > lo) & (r == lo));                                              \
      mn[x] = v < lo ? v : lo;                                                                    \
      ring[x] = in[x];                                                                            \
      need[x] = lost;                                                                             \
      count += lost;                                                                              \
    }                                                                                             \
    return count;                                                                                 \
  }                                                                                               \
  DS_CLONES guint ds_window_push_counts_row_##NAME (const T *in, T *ring, guint8 *satn,           \
                                                    guint32 thr, guint16 *mn, guint32 *sum,       \
                                                    gint32 c, gint32 s, gint64 *cs, gint64 *sn,   \
                                                    guint8 *need, gsize w)                        \
  {                                                                                               \
    if (sum)                                                                                      \
      window_sum_##NAME (in, ring, sum, w);                                                       \
    if (cs)                                                                                       \
      window_harmonic_##NAME (in, ring, c, s, cs, sn, w);                                         \
    window_satcount_##NAME (in, ring, satn, thr, w);                                              \
    if (mn)                                                                                       \
      return window_min_##NAME (in, ring, mn, need, w);                                           \
    memcpy (ring, in, w * sizeof (T));                                                            \
    return 0;                                                                                     \
  }                                                                                               \
  DS_CLONES void ds_window_satcount_row_##NAME (const T *plane, guint8 *satn, guint32 thr,        \
                                                gboolean first, gsize w)                          \
  {                                                                                               \
    if (first)                                                                                    \
      for (gsize x = 0; x < w; x++)                                                               \
        satn[x] = (guint8) ((guint32) plane[x] >= thr);                                           \
    else                                                                                          \
      for (gsize x = 0; x < w; x++)                                                               \
        satn[x] = (guint8) (satn[x] + ((guint32) plane[x] >= thr));                               \
  }                                                                                               \
  DS_CLONES void ds_window_rescan_min_row_##NAME (const T *plane0, gsize plane_stride, guint n,   \
                                                  guint16 *mn, const guint8 *need, guint count,   \
                                                  gsize w)                                        \
  {                                                                                               \
    for (gsize x = 0; x < w && count > 0; x++) {                                                  \
      if (!need[x])                                                                               \
        continue;                                                                                 \
      count--;                                                                                    \
      guint16 lo = plane0[x];                                                                     \
      for (guint k = 1; k < n; k++) {                                                             \
        guint16 v = plane0[x + k * plane_stride];                                                 \
        lo = v < lo ? v : lo;                                                                     \
      }                                                                                           \
      mn[x] = lo;                                                                                 \
    }                                                                                             \
  }                                                                                               \
  DS_KERNEL void window_min_all_##NAME (const T *restrict p, guint16 *restrict m, gboolean first, \
                                        gsize w)                                                  \
  {                                                                                               \
    if (first)                                                                                    \
      for (gsize x = 0; x < w; x++)                                                               \
        m[x] = p[x];                                                                              \
    else                                                                                          \
      for (gsize x = 0; x < w; x++) {                                                             \
        guint16 v = p[x];                                                                         \
        m[x] = v < m[x] ? v : m[x];                                                               \
      }                                                                                           \
  }                                                                                               \
  DS_CLONES void ds_window_min_row_##NAME (const T *plane, guint16 *mn, gboolean first, gsize w) \
  {                                                                                               \
    window_min_all_##NAME (plane, mn, first, w);                                                  \
  }

DEFINE_WINDOW_COUNT_KERNELS (guint8, u8)
DEFINE_WINDOW_COUNT_KERNELS (guint16, u16)
