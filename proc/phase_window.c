/* The sliding phase window (proc/phase_window.h).
 *
 * The window keeps the newest frame of each phase (a ring of N planes in the frames' own
 * sample type): a push must know the sample it retires. Its result is, by definition, that of
 * a fresh DsPhaseSet over those frames in arrival order. The first result after a break is
 * made exactly so: the frames are refolded into the window's own set. From then on, for
 * integer frames, each push updates that set's state in place instead, so that a result costs
 * one push and one finalize, not N folds:
 *
 * - sums (the mean's u32 sum, sine's fixed-point harmonic) add the new sample and subtract the
 *   retired one: integer arithmetic, exact, so the same as a fold in any order;
 * - max and min take the new sample when it is a new extreme; where the retired sample was the
 *   extreme and the new one is not, that pixel's extreme is rebuilt from its N kept samples
 *   (a max is the same whatever the order it is taken in). Under sensor noise that happens at
 *   about 1/N of the pixels per push, which touches every cache line of the kept frames: such
 *   rows are rebuilt whole, plane by plane, so a push reads the N kept frames as a refold
 *   would, but retires the sums instead of refolding them;
 * - sine keeps counts (when the finalize takes its fast row, ds_phase_set_sine_fast): that row
 *   reads the max only for SATURATED (max >= sat) and the min only for DARK_EXCEEDS with a
 *   dark frame (without one it cannot hold). The max is replaced by a count per pixel of the
 *   kept samples >= sat (set->sat_count): the push adds the new sample's and retires the old
 *   one's, exact, and never needs the kept frames. The min is kept as above only while a dark
 *   frame is set (a change of dark frame refolds); so a push without dark reads the new and
 *   retired samples, the sums and the counts, and nothing else;
 * - robust keeps its N phase planes already: the push writes the new frame into its plane;
 * - the data-derived noise comes from the set's first frame, the oldest: each slot keeps its
 *   frame's estimate, and the oldest slot's is the set's;
 * - the sampling check's column offset, while no frame has shown clear stripes, is tried on
 *   each frame as it comes (as the set tries each frame it folds).
 *
 * ds_phase_window_push_finalize_into runs the push's blocks of rows from inside the finalize
 * (ds_phase_set_finalize_prepared_into), each just before the finalize reads it: the state a
 * push writes is read back from cache, not memory. The rows' results do not depend on the
 * order they are updated in, so the state and result are those of the two calls.
 *
 * Float frames keep the refold for every result: a float sum depends on the order it is taken
 * in, and the daemon's per-frame mode gets u8 and u16 frames. */
#include "proc/phase_window.h"

#include <stdlib.h>
#include <string.h>

#include "proc/phase_window_rows.h"
#include "proc/proc_error.h"
#include "proc/separation_internal.h"

struct DsPhaseWindow {
  guint n;
  guint width, height;
  gsize npix;
  DsPhaseSet *set;
  guint8 *ring;        /* N planes of npix samples of ring_type: plane k the newest frame of
                          phase k since the last break (when live); NULL until the first push */
  DsSampleType ring_type;
  guint ring_depth;    /* bit depth of the live frames */
  DsImage *views;      /* N views over the planes, for refolds */
  double *noise;       /* per slot: its frame's data-derived noise (ds_separation_frame_noise) */
  guint64 *arrival;    /* push number of each slot's frame */
  guint64 pushes;      /* pushes since the window was made */
  guint64 since_break; /* pushes since the last break */
  guint fill;
  guint *order;        /* scratch: phases by arrival */
  gboolean state_current; /* the set's state is the fold of exactly the live frames (integer
                             frames after a refold); pushes keep it so */
  guint64 rebuilt;     /* pixels whose extremes were rebuilt from the kept frames */
  guint rebuild_all_for; /* pushes that will rebuild every row's extremes without tracking */
  guint8 *row_dense;   /* per row, in a push: so many extremes left that the row is rebuilt
                          plane by plane (update_block) */
  guint8 *need;        /* per thread of the set: a row of flags, the pixels whose extremes left */
  gboolean counts;     /* sine keeps counts (above): satn is the set's sat_count, max16 is not
                          kept, min16 only when track_min */
  gboolean track_min;
  guint32 sat_from;    /* ds_phase_set_saturated_from of the live frames */
  guint8 *satn;        /* npix counts, or NULL */
};

/* A row whose extremes left at more than 1/DENSE_SHARE of its pixels is rebuilt whole: its
 * pixels' scattered reads would touch every cache line of the N planes anyway. */
#define DENSE_SHARE 16

DsPhaseWindow *
ds_phase_window_new (const DsSeparationParams *params, guint width, guint height, GError **error)
{
  g_autoptr (DsPhaseSet) set = ds_phase_set_new (params, width, height, error);
  if (!set)
    return NULL;
  DsPhaseWindow *w = g_new0 (DsPhaseWindow, 1);
  w->n = params->n_phases;
  w->width = width;
  w->height = height;
  w->npix = (gsize) width * height;
  w->set = g_steal_pointer (&set);
  w->views = g_new0 (DsImage, w->n);
  w->noise = g_new0 (double, w->n);
  w->arrival = g_new0 (guint64, w->n);
  w->order = g_new0 (guint, w->n);
  w->row_dense = g_new0 (guint8, height);
  w->need = g_new0 (guint8, (gsize) w->set->threads * width);
  return w;
}

void
ds_phase_window_free (DsPhaseWindow *window)
{
  if (!window)
    return;
  free (window->ring);
  g_free (window->views);
  g_free (window->noise);
  g_free (window->arrival);
  g_free (window->order);
  g_free (window->row_dense);
  g_free (window->need);
  g_free (window->satn);
  ds_phase_set_free (window->set);
  g_free (window);
}

/* The state is no longer the pushes' to update: the next result refolds. */
static void
state_drop (DsPhaseWindow *window)
{
  window->state_current = FALSE;
  window->rebuild_all_for = 0;
  window->counts = FALSE;
  window->set->sat_count = NULL;
}

gboolean
ds_phase_window_set_dark (DsPhaseWindow *window, const DsImage *dark, GError **error)
{
  if (!ds_phase_set_set_dark (window->set, dark, error))
    return FALSE;
  /* with counts the min is kept only with a dark frame: a new one refolds (a dark frame
   * changes with the settings, not per frame) */
  if (window->counts)
    state_drop (window);
  return TRUE;
}

void
ds_phase_window_set_push_threads (DsPhaseWindow *window, guint threads)
{
  /* pushes run on the set's fold threads: refolds and pushes share the setting */
  ds_phase_set_set_fold_threads (window->set, threads);
}

void
ds_phase_window_set_finalize_threads (DsPhaseWindow *window, guint threads)
{
  ds_phase_set_set_finalize_threads (window->set, threads);
}

static gboolean
slot_is_live (const DsPhaseWindow *window, guint k)
{
  /* A slot filled before the last break is stale: its memory is kept for reuse only. */
  return window->ring && window->arrival[k] > 0 &&
         window->arrival[k] + window->since_break > window->pushes;
}

static gsize
plane_bytes (const DsPhaseWindow *window)
{
  return window->npix * ds_sample_size (window->ring_type);
}

/* Bytes from one kept plane to the next: the plane rounded to whole pages plus five cache
 * lines. Planes a power of two apart (a megapixel of u16 is 2 MiB) would put the same pixel of
 * every plane in one cache set and make loads alias the stores of the extremes, which slows a
 * rebuild reading the N planes several-fold. */
static gsize
plane_stride_bytes (gsize plane)
{
  return ((plane + 4095) & ~(gsize) 4095) + 5 * 64;
}

static guint8 *
slot_row (const DsPhaseWindow *window, guint k, guint y)
{
  gsize size = ds_sample_size (window->ring_type);
  return window->ring + k * plane_stride_bytes (window->npix * size) + (gsize) y * window->width * size;
}

/* The ring for frames of `type` (the old planes are stale: only called with no live slot of
 * another type). */
static gboolean
ensure_ring (DsPhaseWindow *window, DsSampleType type, GError **error)
{
  if (window->ring && window->ring_type == type)
    return TRUE;
  gsize bytes = 0;
  void *p = NULL;
  if (!g_size_checked_mul (&bytes, plane_stride_bytes (window->npix * ds_sample_size (type)), window->n) ||
      posix_memalign (&p, 64, MAX (bytes, 1)) != 0) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_TOO_LARGE,
                 "cannot allocate %u kept frames of %ux%u %s for the sliding window", window->n,
                 window->width, window->height, ds_sample_type_name (type));
    return FALSE;
  }
  free (window->ring);
  window->ring = p;
  window->ring_type = type;
  memset (window->arrival, 0, sizeof (guint64) * window->n);
  state_drop (window);
  return TRUE;
}

typedef struct {
  DsPhaseWindow *window;
  const DsImage *frame;
  guint phase;
  gint32 c, s;                  /* sine's fixed-point weights of the phase */
  gsize plane_stride;           /* samples from one kept plane to the next */
  gboolean rebuild_all;         /* every row's extremes are rebuilt: the push skips its own */
  guint64 rebuilt[DS_MAX_THREADS]; /* per thread: pixels whose extremes were rebuilt */
  guint64 dense[DS_MAX_THREADS];   /* per thread: rows rebuilt whole */
} PushJob;

#define PUSH_INT_ROW(T, NAME)                                                                     \
  do {                                                                                            \
    const T *in = ds_image_row (frame, y);                                                        \
    T *ring = (T *) slot_row (window, j->phase, y);                                               \
    guint count = ds_window_push_row_##NAME (                                                     \
        in, ring, set->max16 + off, set->min16 + off, set->sum32 ? set->sum32 + off : NULL, j->c, \
        j->s, set->cos64 ? set->cos64 + off : NULL, set->sin64 ? set->sin64 + off : NULL, need, w); \
    window->row_dense[y] = count > w / DENSE_SHARE;                                               \
    if (count > 0 && !window->row_dense[y])                                                       \
      ds_window_rescan_row_##NAME ((const T *) slot_row (window, 0, y), j->plane_stride, window->n, \
                                   set->max16 + off, set->min16 + off, need, count, w);           \
    j->rebuilt[thread] += window->row_dense[y] ? w : count;                                       \
    j->dense[thread] += window->row_dense[y];                                                     \
  } while (0)

#define RETIRE_INT_ROW(T, NAME)                                                                   \
  ds_window_retire_row_##NAME (ds_image_row (frame, y), (T *) slot_row (window, j->phase, y),    \
                               set->sum32 ? set->sum32 + off : NULL, j->c, j->s,                 \
                               set->cos64 ? set->cos64 + off : NULL,                              \
                               set->sin64 ? set->sin64 + off : NULL, w)

/* One row of a push with counts (sine): the sums and counts, and the min when kept (its lost
 * pixels rescanned, or the row marked for the plane-by-plane rebuild as PUSH_INT_ROW's). */
#define PUSH_COUNTS_ROW_T(T, NAME)                                                                \
  do {                                                                                            \
    guint16 *mn = window->track_min && !j->rebuild_all ? set->min16 + off : NULL;                 \
    guint count = ds_window_push_counts_row_##NAME (                                              \
        ds_image_row (frame, y), (T *) slot_row (window, j->phase, y), window->satn + off,        \
        window->sat_from, mn, set->sum32 + off, j->c, j->s, set->cos64 + off, set->sin64 + off,   \
        need, w);                                                                                 \
    if (window->track_min && j->rebuild_all) {                                                    \
      window->row_dense[y] = 1;                                                                   \
      j->rebuilt[thread] += w;                                                                    \
      j->dense[thread]++;                                                                         \
      break;                                                                                      \
    }                                                                                             \
    window->row_dense[y] = count > w / DENSE_SHARE;                                               \
    if (count > 0 && !window->row_dense[y])                                                       \
      ds_window_rescan_min_row_##NAME ((const T *) slot_row (window, 0, y), j->plane_stride,      \
                                       window->n, set->min16 + off, need, count, w);              \
    j->rebuilt[thread] += window->row_dense[y] ? w : count;                                       \
    j->dense[thread] += window->row_dense[y];                                                     \
  } while (0)
#define PUSH_COUNTS_ROW()                                                                         \
  do {                                                                                            \
    if (frame->type == DS_SAMPLE_U16)                                                             \
      PUSH_COUNTS_ROW_T (guint16, u16);                                                           \
    else                                                                                          \
      PUSH_COUNTS_ROW_T (guint8, u8);                                                             \
  } while (0)

/* The rows y0..y1 of a push: the sums retired and added, the extremes kept where they
 * can be, then the rows where many extremes left rebuilt from the kept planes one plane at a
 * time over the block (each plane's rows read as one stream, which costs less than reading
 * the N planes side by side row by row). */
static void
update_block (PushJob *j, guint y0, guint y1, guint thread)
{
  DsPhaseWindow *window = j->window;
  DsPhaseSet *set = window->set;
  const DsImage *frame = j->frame;
  gsize w = window->width;
  guint8 *need = window->need + (gsize) thread * w;
  for (guint y = y0; y < y1; y++) {
    gsize off = (gsize) y * w;
    if (window->counts) {
      PUSH_COUNTS_ROW ();
      continue;
    }
    if (set->planes16) {
      /* robust: its phase planes are the state; the ring keeps the frame for refolds */
      guint16 *plane = set->planes16 + (gsize) j->phase * window->npix + off;
      if (frame->type == DS_SAMPLE_U16)
        ds_widen_u16 (ds_image_row (frame, y), plane, w);
      else
        ds_widen_u8 (ds_image_row (frame, y), plane, w);
      memcpy (slot_row (window, j->phase, y), ds_image_row (frame, y), w * ds_sample_size (frame->type));
    } else if (j->rebuild_all) {
      if (frame->type == DS_SAMPLE_U16)
        RETIRE_INT_ROW (guint16, u16);
      else
        RETIRE_INT_ROW (guint8, u8);
      window->row_dense[y] = 1;
      j->rebuilt[thread] += w;
      j->dense[thread]++;
    } else if (frame->type == DS_SAMPLE_U16) {
      PUSH_INT_ROW (guint16, u16);
    } else {
      PUSH_INT_ROW (guint8, u8);
    }
  }
  if (set->planes16 || (window->counts && !window->track_min))
    return;
  for (guint k = 0; k < window->n; k++)
    for (guint y = y0; y < y1; y++) {
      if (!window->row_dense[y])
        continue;
      gsize off = (gsize) y * w;
      if (window->counts && window->ring_type == DS_SAMPLE_U16)
        ds_window_min_row_u16 ((const guint16 *) slot_row (window, k, y), set->min16 + off, k == 0, w);
      else if (window->counts)
        ds_window_min_row_u8 (slot_row (window, k, y), set->min16 + off, k == 0, w);
      else if (window->ring_type == DS_SAMPLE_U16)
        ds_window_extrema_row_u16 ((const guint16 *) slot_row (window, k, y), set->max16 + off,
                                   set->min16 + off, k == 0, w);
      else
        ds_window_extrema_row_u8 (slot_row (window, k, y), set->max16 + off, set->min16 + off,
                                  k == 0, w);
    }
}

/* Rows per block of a fused push and finalize: about 256 KiB of each kept plane, so that the
 * block's extremes (and sums) are still in the core's cache when the finalize reads them,
 * while each plane is still read in runs long enough for the hardware prefetcher. (Blocks of
 * 16 KiB measured slower: every block restarts N streams.) */
static guint
block_rows (const DsPhaseWindow *window)
{
  gsize row = (gsize) window->width * ds_sample_size (window->ring_type);
  return (guint) MAX (262144 / MAX (row, 1), 1);
}

/* A push alone: the band as one block, each kept plane read in one run. */
static void
push_rows (gpointer data, guint y0, guint y1, guint thread)
{
  update_block (data, y0, y1, thread);
}

/* ds_phase_set_finalize_prepared_into's hook: the block's rows of the push. */
static void
push_block (gpointer data, guint y0, guint y1, guint thread)
{
  update_block (data, y0, y1, thread);
}

static void
copy_rows (gpointer data, guint y0, guint y1, guint thread)
{
  (void) thread;
  PushJob *j = data;
  gsize row = (gsize) j->window->width * ds_sample_size (j->frame->type);
  for (guint y = y0; y < y1; y++)
    memcpy (slot_row (j->window, j->phase, y), ds_image_row (j->frame, y), row);
}

/* The frames kept since the last break share one sample type and depth: a set refuses a mix,
 * and the window refuses it at the push so that the error names the frame that broke it. */
static gboolean
live_slot_type (const DsPhaseWindow *window, DsSampleType *type, guint *depth)
{
  for (guint k = 0; k < window->n; k++)
    if (slot_is_live (window, k)) {
      *type = window->ring_type;
      *depth = window->ring_depth;
      return TRUE;
    }
  return FALSE;
}

static guint
oldest_slot (const DsPhaseWindow *window)
{
  guint oldest = 0;
  for (guint k = 1; k < window->n; k++)
    if (window->arrival[k] < window->arrival[oldest])
      oldest = k;
  return oldest;
}

/* The push's checks, and the ring made ready for the frame; nothing else changes. */
static gboolean
push_check (DsPhaseWindow *window, guint phase, const DsImage *frame, GError **error)
{
  if (phase >= window->n) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_INVALID_ARGUMENT,
                 "phase %u is outside 0..%u of an N = %u window", phase, window->n - 1, window->n);
    return FALSE;
  }
  if (!frame || frame->width != window->width || frame->height != window->height) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_SIZE_MISMATCH,
                 "phase %u: frame is %ux%u, the window expects %ux%u", phase,
                 frame ? frame->width : 0, frame ? frame->height : 0, window->width,
                 window->height);
    return FALSE;
  }
  DsSampleType live_type;
  guint live_depth;
  if (live_slot_type (window, &live_type, &live_depth) &&
      (live_type != frame->type || live_depth != frame->bit_depth)) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_SIZE_MISMATCH,
                 "phase %u: frame is %s with %u bits, the window's frames are %s with %u bits",
                 phase, ds_sample_type_name (frame->type), frame->bit_depth,
                 ds_sample_type_name (live_type), live_depth);
    return FALSE;
  }
  return ensure_ring (window, frame->type, error);
}

/* A push into the current state (window->state_current): the job for its rows. */
static void
push_job_init (DsPhaseWindow *window, guint phase, const DsImage *frame, PushJob *j)
{
  /* complete since the refold (a break clears state_current): the slot is live */
  g_assert (slot_is_live (window, phase));
  memset (j, 0, sizeof *j);
  j->window = window;
  j->frame = frame;
  j->phase = phase;
  j->plane_stride = plane_stride_bytes (plane_bytes (window)) / ds_sample_size (frame->type);
  if (window->set->cos64)
    ds_harmonic_fix_weights (window->n, phase, &j->c, &j->s);
  j->rebuild_all = window->rebuild_all_for > 0;
}

/* After the rows of a push into the current state. */
static void
push_job_done (DsPhaseWindow *window, const PushJob *j)
{
  guint64 dense = 0;
  for (guint t = 0; t < DS_MAX_THREADS; t++) {
    window->rebuilt += j->rebuilt[t];
    dense += j->dense[t];
  }
  /* Whether a push loses extremes at many pixels depends on the scene and its noise, which
   * change slowly: when nearly every row was rebuilt whole, the next N - 1 pushes rebuild
   * every row without tracking the extremes first, then one tracks them again. */
  if (j->rebuild_all)
    window->rebuild_all_for--;
  else if (dense * 4 > (guint64) window->height * 3)
    window->rebuild_all_for = window->n - 1;
}

/* The window's own record of a push (after its rows, or before a fused finalize reads the
 * noise of the oldest slot). */
static void
push_record (DsPhaseWindow *window, guint phase, const DsImage *frame, gboolean was_live,
             gboolean *complete)
{
  window->noise[phase] = ds_separation_frame_noise (frame);
  window->ring_depth = frame->bit_depth;
  window->pushes++;
  window->since_break++;
  window->arrival[phase] = window->pushes;
  if (!was_live)
    window->fill++;
  if (complete)
    *complete = window->fill == window->n;
}

gboolean
ds_phase_window_push (DsPhaseWindow *window, guint phase, const DsImage *frame,
                      gboolean *complete, GError **error)
{
  if (!push_check (window, phase, frame, error))
    return FALSE;
  gboolean was_live = slot_is_live (window, phase);
  DsPhaseSet *set = window->set;
  PushJob j;
  if (window->state_current) {
    push_job_init (window, phase, frame, &j);
    ds_phase_set_run_rows_on (set, set->fold_threads, push_rows, &j);
    push_job_done (window, &j);
    ds_phase_set_locate_columns (set, phase, frame);
  } else {
    j = (PushJob) { .window = window, .frame = frame, .phase = phase };
    ds_phase_set_run_rows_on (set, set->fold_threads, copy_rows, &j);
  }
  push_record (window, phase, frame, was_live, complete);
  return TRUE;
}

gboolean
ds_phase_window_push_finalize_into (DsPhaseWindow *window, guint phase, const DsImage *frame,
                                    DsSeparation *sep, gboolean *complete, gboolean *pushed,
                                    GError **error)
{
  if (pushed)
    *pushed = FALSE;
  if (!window->state_current) {
    /* the first result after a break is a refold: the two calls */
    gboolean full = FALSE;
    if (!ds_phase_window_push (window, phase, frame, &full, error))
      return FALSE;
    if (pushed)
      *pushed = TRUE;
    if (complete)
      *complete = full;
    return !full || ds_phase_window_finalize_into (window, sep, error);
  }
  if (!push_check (window, phase, frame, error))
    return FALSE;
  DsPhaseSet *set = window->set;
  PushJob j;
  push_job_init (window, phase, frame, &j);
  /* everything the finalize takes for the whole set is settled before its rows: the column
   * flags (from the frame alone) and the noise of the oldest slot */
  ds_phase_set_locate_columns (set, phase, frame);
  push_record (window, phase, frame, TRUE, complete);
  set->data_noise_dn = window->noise[oldest_slot (window)];
  if (pushed)
    *pushed = TRUE;
  if (!ds_phase_set_finalize_prepared_into (set, sep, push_block, block_rows (window), &j, error)) {
    /* no result (planes that do not fit): the frame still goes in, as with the two calls */
    ds_phase_set_run_rows_on (set, set->fold_threads, push_rows, &j);
    push_job_done (window, &j);
    return FALSE;
  }
  push_job_done (window, &j);
  return TRUE;
}

void
ds_phase_window_break (DsPhaseWindow *window)
{
  window->since_break = 0;
  window->fill = 0;
  state_drop (window);
}

guint
ds_phase_window_fill (const DsPhaseWindow *window)
{
  return window->fill;
}

guint64
ds_phase_window_frames_since_break (const DsPhaseWindow *window)
{
  return window->since_break;
}

guint64
ds_phase_window_span (const DsPhaseWindow *window)
{
  if (window->fill < window->n)
    return 0;
  return window->pushes - window->arrival[oldest_slot (window)] + 1;
}

/* The definition: a fresh set (the window's own, reset) fed the kept frames in arrival order. */
static gboolean
refold (DsPhaseWindow *window, GError **error)
{
  for (guint k = 0; k < window->n; k++)
    window->order[k] = k;
  /* Insertion sort by arrival: N is small and the order is nearly cyclic. */
  for (guint i = 1; i < window->n; i++) {
    guint k = window->order[i], j = i;
    for (; j > 0 && window->arrival[window->order[j - 1]] > window->arrival[k]; j--)
      window->order[j] = window->order[j - 1];
    window->order[j] = k;
  }
  ds_phase_set_reset (window->set);
  gsize row = (gsize) window->width * ds_sample_size (window->ring_type);
  for (guint i = 0; i < window->n; i++) {
    guint k = window->order[i];
    DsImage *view = &window->views[k];
    if (!ds_image_view_init (view, window->ring_type, window->ring_depth, window->width,
                             window->height, row, slot_row (window, k, 0), plane_bytes (window),
                             error) ||
        !ds_phase_set_accumulate (window->set, k, view, error))
      return FALSE;
  }
  return TRUE;
}

/* After a refold into the current state, for sine's fast row: the counts from the kept
 * frames (satn is made on first use and kept: its size is the window's). */
static void
counts_build (DsPhaseWindow *window)
{
  DsPhaseSet *set = window->set;
  if (!window->satn)
    window->satn = g_malloc (window->npix);
  window->sat_from = ds_phase_set_saturated_from (set);
  gsize w = window->width;
  for (guint k = 0; k < window->n; k++)
    for (guint y = 0; y < window->height; y++) {
      guint8 *satn = window->satn + (gsize) y * w;
      if (window->ring_type == DS_SAMPLE_U16)
        ds_window_satcount_row_u16 ((const guint16 *) slot_row (window, k, y), satn,
                                    window->sat_from, k == 0, w);
      else
        ds_window_satcount_row_u8 (slot_row (window, k, y), satn, window->sat_from, k == 0, w);
    }
  window->counts = TRUE;
  window->track_min = set->dark != NULL;
  set->sat_count = window->satn;
}

gboolean
ds_phase_window_finalize_into (DsPhaseWindow *window, DsSeparation *sep, GError **error)
{
  if (window->fill < window->n) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_NOT_ENOUGH_PHASES,
                 "the window has frames of %u of its %u phases since it was last broken",
                 window->fill, window->n);
    return FALSE;
  }
  if (!window->state_current) {
    state_drop (window);
    if (!refold (window, error))
      return FALSE;
    DsPhaseSet *set = window->set;
    /* integer frames, one per phase: the state the pushes know how to update. The motion
     * test's double sums (sum of squares, maxmin's harmonic) depend on the order they were
     * taken in, so with them every result is a refold, which is the definition. */
    window->state_current = window->ring_type != DS_SAMPLE_F32 && !set->averaging &&
                            (set->max16 || set->planes16) && !set->sumsq && !set->cos_sum;
    if (window->state_current && ds_phase_set_sine_fast (set) && window->n <= G_MAXUINT8)
      counts_build (window);
  }
  /* the set's noise estimate is its first frame's: the oldest kept one */
  window->set->data_noise_dn = window->noise[oldest_slot (window)];
  return ds_phase_set_finalize_into (window->set, sep, error);
}

static gsize
set_state_bytes (const DsPhaseSet *set)
{
  gsize n = set->npix, per_pixel = 0;
  per_pixel += (set->max16 ? 2 : 0) + (set->min16 ? 2 : 0) + (set->sum32 ? 4 : 0);
  per_pixel += (set->maxf ? 4 : 0) + (set->minf ? 4 : 0) + (set->sumd ? 8 : 0);
  per_pixel += (set->rawmax ? 4 : 0) + (set->psum ? 8 : 0) + (set->nonfinite ? 1 : 0);
  per_pixel += (set->cos_sum ? 16 : 0) + (set->cos64 ? 16 : 0) + (set->dark ? 4 : 0);
  per_pixel += (set->planes16 ? 2 * set->params.n_phases : 0);
  per_pixel += (set->planesf ? 4 * set->params.n_phases : 0);
  return n * per_pixel;
}

void
ds_phase_window_memory (const DsPhaseWindow *window, gsize *window_bytes, gsize *set_bytes)
{
  gsize set_state = set_state_bytes (window->set);
  if (set_bytes)
    *set_bytes = set_state;
  if (window_bytes)
    *window_bytes = set_state + (window->ring ? window->n * plane_stride_bytes (plane_bytes (window)) : 0) +
                    (window->satn ? window->npix : 0);
}

guint64
ds_phase_window_rebuilt_pixels (const DsPhaseWindow *window)
{
  return window->rebuilt;
}
