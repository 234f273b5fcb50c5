/* The streaming phase-set accumulator: frames are folded in one at a time as they arrive.
 *
 * Memory does not grow with N for maxmin and sine. The fast path (integer frames, one per
 * phase) keeps the raw extrema as u16 and, only when something needs the mean, an exact 32-bit
 * sum (exact up to DS_MAX_PHASES frames of 16 bits; widened to double at finalize); robust keeps
 * the N raw frames as u16 planes (a copy per frame) and derives the rest at finalize. Float
 * input and averaging (M frames per phase) use float extrema of phase means and a double sum.
 * The row loops live in separation_kernels.c; rows are split over the set's worker threads. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "proc/proc_error.h"
#include "proc/separation_internal.h"
#include "proc/separation_rows.h"
#include "proc/stripe_phase.h"

static gboolean
needs_mean (const DsPhaseSet *set)
{
  return set->params.estimator != DS_ESTIMATOR_MAXMIN || set->params.keep_extrema || set->motion;
}

static void
free_state (DsPhaseSet *set)
{
  g_clear_pointer (&set->max16, free);
  g_clear_pointer (&set->min16, free);
  g_clear_pointer (&set->sum32, free);
  g_clear_pointer (&set->maxf, free);
  g_clear_pointer (&set->minf, free);
  g_clear_pointer (&set->sumd, free);
  g_clear_pointer (&set->rawmax, free);
  g_clear_pointer (&set->psum, free);
  g_clear_pointer (&set->nonfinite, free);
  g_clear_pointer (&set->cos_sum, free);
  g_clear_pointer (&set->sin_sum, free);
  g_clear_pointer (&set->cos64, free);
  g_clear_pointer (&set->sin64, free);
  g_clear_pointer (&set->sumsq, free);
  g_clear_pointer (&set->planes16, free);
  g_clear_pointer (&set->planesf, free);
}

static gpointer
alloc_plane (DsPhaseSet *set, gsize n_elements, gsize element_size, gboolean *ok, GError **error)
{
  if (!*ok)
    return NULL;
  gsize bytes;
  gpointer p = NULL;
  /* 64-byte aligned (a cache line): vector loads of a row then never straddle two lines. */
  if (g_size_checked_mul (&bytes, n_elements, element_size) && posix_memalign (&p, 64, MAX (bytes, 1)) != 0)
    p = NULL;
  if (!p) {
    *ok = FALSE;
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_TOO_LARGE,
                 "cannot allocate %" G_GSIZE_FORMAT " x %" G_GSIZE_FORMAT
                 " bytes of phase-set state for %ux%u frames",
                 n_elements, element_size, set->width, set->height);
  }
  return p;
}

/* Allocates the state for the layout given by set->type and set->averaging. */
static gboolean
alloc_state (DsPhaseSet *set, GError **error)
{
  const DsSeparationParams *p = &set->params;
  gsize n = set->npix;
  gboolean ok = TRUE;
  gboolean is_float = set->type == DS_SAMPLE_F32;
  gboolean robust = p->estimator == DS_ESTIMATOR_ROBUST;
  gsize planes;
  if (!g_size_checked_mul (&planes, n, p->n_phases))
    planes = G_MAXSIZE;
  free_state (set);
  if (!is_float && !set->averaging) {
    if (robust) {
      set->planes16 = alloc_plane (set, planes, sizeof (guint16), &ok, error);
    } else {
      set->max16 = alloc_plane (set, n, sizeof (guint16), &ok, error);
      set->min16 = alloc_plane (set, n, sizeof (guint16), &ok, error);
      if (needs_mean (set))
        set->sum32 = alloc_plane (set, n, sizeof (guint32), &ok, error);
    }
  } else {
    set->maxf = alloc_plane (set, n, sizeof (float), &ok, error);
    set->minf = alloc_plane (set, n, sizeof (float), &ok, error);
    set->sumd = alloc_plane (set, n, sizeof (double), &ok, error);
    if (set->averaging) {
      set->rawmax = alloc_plane (set, n, sizeof (float), &ok, error);
      set->psum = alloc_plane (set, n, sizeof (double), &ok, error);
    }
    if (robust)
      set->planesf = alloc_plane (set, planes, sizeof (float), &ok, error);
  }
  if (is_float)
    set->nonfinite = alloc_plane (set, n, 1, &ok, error);
  /* robust keeps every phase plane: its motion sums are made at finalize */
  gboolean motion_sums = set->motion && !robust;
  if (p->estimator == DS_ESTIMATOR_SINE && !is_float && !set->averaging) {
    /* integer samples: exact fixed-point sums (their value does not depend on the frames'
     * order, so a sliding window can retire a frame and still match a fresh set) */
    set->cos64 = alloc_plane (set, n, sizeof (gint64), &ok, error);
    set->sin64 = alloc_plane (set, n, sizeof (gint64), &ok, error);
  }
  /* the motion test reads the harmonic as doubles: with sine's fixed-point sums it keeps both */
  if ((p->estimator == DS_ESTIMATOR_SINE && !set->cos64) || motion_sums) {
    set->cos_sum = alloc_plane (set, n, sizeof (double), &ok, error);
    set->sin_sum = alloc_plane (set, n, sizeof (double), &ok, error);
  }
  if (motion_sums)
    set->sumsq = alloc_plane (set, n, sizeof (double), &ok, error);
  if (!ok)
    free_state (set);
  return ok;
}

static guint
resolve_threads (guint requested)
{
  guint t = requested ? requested : (guint) g_get_num_processors ();
  return CLAMP (t, 1u, DS_MAX_THREADS);
}

DsPhaseSet *
ds_phase_set_new (const DsSeparationParams *params, guint width, guint height, GError **error)
{
  if (!params) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_INVALID_ARGUMENT, "no separation parameters");
    return NULL;
  }
  if (!ds_separation_params_validate (params, error))
    return NULL;
  if (width == 0 || height == 0 || width > DS_IMAGE_MAX_SIDE || height > DS_IMAGE_MAX_SIDE) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_INVALID_ARGUMENT,
                 "phase-set frame size %ux%u is outside 1..%u on each side", width, height,
                 DS_IMAGE_MAX_SIDE);
    return NULL;
  }
  DsPhaseSet *set = g_new0 (DsPhaseSet, 1);
  set->params = *params;
  set->width = width;
  set->height = height;
  set->npix = (gsize) width * height;
  set->count = g_new0 (guint, params->n_phases);
  set->current = -1;
  set->data_noise_dn = NAN;
  set->range_quantile = ds_separation_range_quantile (params->n_phases, 0.999);
  set->threads = set->npix >= DS_THREADED_MIN_PIXELS ? resolve_threads (params->threads) : 1;
  ds_robust_windows (params, &set->robust_hi, &set->robust_lo);
  /* N - 3 dimensions beyond the mean and the first harmonic: none at N = 3 */
  set->motion = params->detect_motion && params->n_phases >= 4;
  if (set->motion) {
    set->motion_kappa = ds_motion_pattern_ratio (params);
    set->motion_chi2 = ds_chi2_upper_quantile (params->n_phases - 3, DS_MOTION_FALSE_ALARM);
  }
  set->offset_used = NAN;
  /* validate ran the check already and it passed; here its numbers are kept */
  ds_separation_check_sampling (params, &set->sampling, NULL);
  if (set->sampling.applies && set->sampling.affected_fraction > 0) {
    set->column_flags = g_new0 (guint8, width);
    const DsStripeGeometry *g = &params->geometry;
    if (g->phase_offset_known) {
      ds_sampling_column_flags (params, g->phase_offset_cycles, width, set->column_flags);
      set->offset_used = g->phase_offset_cycles;
    } else {
      set->flags_need_offset = TRUE;
    }
  }
  return set;
}

void
ds_phase_set_free (DsPhaseSet *set)
{
  if (!set)
    return;
  free_state (set);
  ds_worker_pool_free (set->pool);
  g_free (set->scratch);
  g_free (set->column_flags);
  g_free (set->dark);
  g_free (set->count);
  g_free (set);
}

void
ds_phase_set_reset (DsPhaseSet *set)
{
  memset (set->count, 0, sizeof (guint) * set->params.n_phases);
  set->frames = 0;
  set->phases_folded = 0;
  set->current = -1;
  set->data_noise_dn = NAN;
  /* typed, type and averaging stay: the next set most likely looks the same and reuses the
   * memory; the first frame re-checks them. The column flags stay with the offset they were
   * made for: the illuminator does not move between sets. */
}

guint
ds_phase_set_frames_folded (const DsPhaseSet *set)
{
  return set->frames;
}

void
ds_phase_set_run_rows_on (DsPhaseSet *set, guint max_threads, DsRowJob job, gpointer data)
{
  if (set->threads > 1 && max_threads != 1 && !set->pool)
    set->pool = ds_worker_pool_new (set->threads);
  ds_worker_pool_run_on (set->pool, max_threads, set->height, job, data);
}

void
ds_phase_set_run_rows (DsPhaseSet *set, DsRowJob job, gpointer data)
{
  ds_phase_set_run_rows_on (set, 0, job, data);
}

void
ds_phase_set_set_fold_threads (DsPhaseSet *set, guint threads)
{
  set->fold_threads = threads;
}

void
ds_phase_set_set_finalize_threads (DsPhaseSet *set, guint threads)
{
  set->finalize_threads = threads;
}

void
ds_phase_set_reserve_scratch (DsPhaseSet *set, gsize doubles)
{
  if (set->scratch && set->scratch_doubles >= doubles)
    return;
  g_free (set->scratch);
  /* rounded to whole cache lines so that threads never share one */
  set->scratch_doubles = (doubles + 7) & ~(gsize) 7;
  set->scratch = g_new (double, set->scratch_doubles * set->threads);
}

double *
ds_phase_set_scratch (DsPhaseSet *set, guint thread)
{
  return set->scratch + (gsize) thread * set->scratch_doubles;
}

static gboolean
check_frame_type (const DsImage *img, const char *what, GError **error)
{
  gboolean ok = img->type == DS_SAMPLE_F32 ? img->bit_depth == 32
                : img->type == DS_SAMPLE_U16 ? img->bit_depth >= 1 && img->bit_depth <= 16
                : img->type == DS_SAMPLE_U8 ? img->bit_depth >= 1 && img->bit_depth <= 8
                                            : FALSE;
  if (!ok)
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_FORMAT,
                 "%s has sample type %d with bit depth %u; expected u8 (1..8 bits), u16 (1..16) "
                 "or f32 (32)", what, (int) img->type, img->bit_depth);
  return ok;
}

gboolean
ds_phase_set_set_dark (DsPhaseSet *set, const DsImage *dark, GError **error)
{
  if (!dark) {
    g_clear_pointer (&set->dark, g_free);
    return TRUE;
  }
  if (!check_frame_type (dark, "dark frame", error))
    return FALSE;
  if (dark->width != set->width || dark->height != set->height) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_SIZE_MISMATCH,
                 "dark frame is %ux%u, the phase set expects %ux%u", dark->width, dark->height,
                 set->width, set->height);
    return FALSE;
  }
  if (set->typed && set->frames > 0 && dark->type != set->type) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_SIZE_MISMATCH,
                 "dark frame is %s, the phase frames are %s", ds_sample_type_name (dark->type),
                 ds_sample_type_name (set->type));
    return FALSE;
  }
  if (!set->dark)
    set->dark = g_try_new (float, set->npix);
  if (!set->dark) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_TOO_LARGE, "cannot allocate the dark frame");
    return FALSE;
  }
  for (guint y = 0; y < set->height; y++) {
    float *d = set->dark + (gsize) y * set->width;
    const void *row = ds_image_row (dark, y);
    if (dark->type == DS_SAMPLE_U8)
      ds_copy_plane_u8 (row, d, set->width);
    else if (dark->type == DS_SAMPLE_U16)
      ds_copy_plane_u16 (row, d, set->width);
    else
      memcpy (d, row, set->width * sizeof (float));
  }
  set->dark_type = dark->type;
  set->dark_bit_depth = dark->bit_depth;
  return TRUE;
}

static void
phase_angle (const DsPhaseSet *set, guint phase, double *c, double *s)
{
  double t = 2.0 * G_PI * (double) phase / (double) set->params.n_phases;
  *c = cos (t);
  *s = sin (t);
}

void
ds_harmonic_fix_weights (guint n, guint phase, gint32 *c, gint32 *s)
{
  double t = 2.0 * G_PI * (double) phase / (double) n, one = (double) (1u << DS_HARMONIC_FIX_BITS);
  *c = (gint32) lround (cos (t) * one);
  *s = (gint32) lround (sin (t) * one);
}

/* Folds one row of values for phase `phase` (float path: float input or phase means). */
static void
fold_values_row (DsPhaseSet *set, guint phase, const float *v, gsize off, gboolean first)
{
  gsize w = set->width;
  ds_fold_float_row (v, set->maxf + off, set->minf + off, set->sumd + off, first, w);
  if (set->cos_sum) {
    double c, s;
    phase_angle (set, phase, &c, &s);
    ds_fold_harmonic_f32 (v, c, s, set->cos_sum + off, set->sin_sum + off, first, w);
  }
  if (set->sumsq)
    ds_fold_sumsq_f32 (v, set->sumsq + off, first, w);
  if (set->planesf)
    memcpy (set->planesf + (gsize) phase * set->npix + off, v, w * sizeof (float));
}

typedef struct {
  DsPhaseSet *set;
  const DsImage *frame;
  guint phase;
  gboolean first;          /* first frame (or phase mean) of the set */
  gboolean first_of_phase; /* averaging */
  double inv;              /* averaging: 1 / frames of the pending phase */
} FoldJob;

/* Averaging: the pending phase's mean is folded into the extrema and sums. */
static void
fold_pending_rows (gpointer data, guint y0, guint y1, guint thread)
{
  FoldJob *j = data;
  DsPhaseSet *set = j->set;
  float *row = (float *) ds_phase_set_scratch (set, thread);
  for (guint y = y0; y < y1; y++) {
    gsize off = (gsize) y * set->width;
    const double *ps = set->psum + off;
    for (guint x = 0; x < set->width; x++)
      row[x] = (float) (ps[x] * j->inv);
    fold_values_row (set, j->phase, row, off, j->first);
  }
}

static void
fold_pending_phase (DsPhaseSet *set, guint max_threads)
{
  if (set->current < 0 || !set->averaging)
    return;
  FoldJob j = { .set = set, .phase = (guint) set->current, .first = set->phases_folded == 0,
                .inv = 1.0 / set->count[set->current] };
  ds_phase_set_reserve_scratch (set, set->width);
  ds_phase_set_run_rows_on (set, max_threads, fold_pending_rows, &j);
  set->phases_folded++;
}

/* The first phase got a second frame: until now exactly one frame was folded, so its value is
 * still in the state; it becomes the running phase sum and averaging starts. */
static gboolean
switch_to_averaging (DsPhaseSet *set, GError **error)
{
  gsize n = set->npix;
  g_autofree float *first = g_try_new (float, n);
  if (!first) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_TOO_LARGE, "cannot allocate a phase plane");
    return FALSE;
  }
  const guint16 *v16 = set->max16 ? set->max16
                       : set->planes16 ? set->planes16 + (gsize) set->current * n
                                       : NULL;
  for (gsize i = 0; i < n; i++)
    first[i] = v16 ? v16[i] : set->maxf[i];
  guint8 *nf = g_steal_pointer (&set->nonfinite);
  set->averaging = TRUE;
  if (!alloc_state (set, error)) {
    free (nf);
    set->averaging = FALSE;
    set->typed = FALSE;
    return FALSE;
  }
  if (nf) {
    free (set->nonfinite);
    set->nonfinite = nf;
  }
  for (gsize i = 0; i < n; i++) {
    set->psum[i] = first[i];
    set->rawmax[i] = first[i];
  }
  set->phases_folded = 0;
  return TRUE;
}

static gboolean
check_frame (DsPhaseSet *set, guint phase, const DsImage *frame, GError **error)
{
  guint n = set->params.n_phases;
  if (!frame) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_INVALID_ARGUMENT, "phase %u: no frame", phase);
    return FALSE;
  }
  if (phase >= n) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_INVALID_ARGUMENT,
                 "phase %u is outside 0..%u of an N = %u set", phase, n - 1, n);
    return FALSE;
  }
  g_autofree char *what = g_strdup_printf ("phase %u frame", phase);
  if (!check_frame_type (frame, what, error))
    return FALSE;
  if (frame->width != set->width || frame->height != set->height) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_SIZE_MISMATCH,
                 "phase %u: frame is %ux%u, the set expects %ux%u", phase, frame->width,
                 frame->height, set->width, set->height);
    return FALSE;
  }
  if (set->frames > 0 && (frame->type != set->type || frame->bit_depth != set->bit_depth)) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_SIZE_MISMATCH,
                 "phase %u: frame is %s with %u bits, earlier frames of the set are %s with %u bits",
                 phase, ds_sample_type_name (frame->type), frame->bit_depth,
                 ds_sample_type_name (set->type), set->bit_depth);
    return FALSE;
  }
  if (set->dark && set->dark_type != frame->type) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_SIZE_MISMATCH,
                 "phase %u: frame is %s, the dark frame is %s", phase,
                 ds_sample_type_name (frame->type), ds_sample_type_name (set->dark_type));
    return FALSE;
  }
  if (set->count[phase] > 0 && (int) phase != set->current) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_INVALID_ARGUMENT,
                 "phase %u was already completed; a phase cannot be revisited (now at phase %d)",
                 phase, set->current);
    return FALSE;
  }
  if (set->count[phase] >= DS_MAX_PHASES) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_INVALID_ARGUMENT,
                 "phase %u: more than %u frames", phase, DS_MAX_PHASES);
    return FALSE;
  }
  if (set->count[phase] > 0 && !set->averaging && set->frames > 1) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_INVALID_ARGUMENT,
                 "phase %u: a second frame, but the first phase of the set had one frame only "
                 "(averaging is decided by the first phase)", phase);
    return FALSE;
  }
  return TRUE;
}

/* Integer frame, one per phase. */
#define FOLD_INT_ROW(T, NAME)                                                                     \
  do {                                                                                            \
    const T *in = ds_image_row (frame, y);                                                        \
    if (set->planes16) {                                                                          \
      ds_widen_##NAME (in, set->planes16 + (gsize) j->phase * set->npix + off, w);                \
      break;                                                                                      \
    }                                                                                             \
    guint32 *sum = set->sum32 ? set->sum32 + off : NULL;                                          \
    if (j->first)                                                                                 \
      ds_fold_first_##NAME (in, set->max16 + off, set->min16 + off, sum, w);                      \
    else if (sum)                                                                                 \
      ds_fold_extrema_sum_##NAME (in, set->max16 + off, set->min16 + off, sum, w);                \
    else                                                                                          \
      ds_fold_extrema_##NAME (in, set->max16 + off, set->min16 + off, w);                         \
    if (set->cos64)                                                                               \
      ds_fold_harmonic_fix_##NAME (in, cf, sf, set->cos64 + off, set->sin64 + off, j->first, w);  \
    if (set->cos_sum)                                                                             \
      ds_fold_harmonic_##NAME (in, c, s, set->cos_sum + off, set->sin_sum + off, j->first, w);    \
    if (set->sumsq)                                                                               \
      ds_fold_sumsq_##NAME (in, set->sumsq + off, j->first, w);                                   \
  } while (0)

static void
fold_frame_rows (gpointer data, guint y0, guint y1, guint thread)
{
  FoldJob *j = data;
  DsPhaseSet *set = j->set;
  const DsImage *frame = j->frame;
  gsize w = set->width;
  gint32 cf = 0, sf = 0;
  if (set->cos64)
    ds_harmonic_fix_weights (set->params.n_phases, j->phase, &cf, &sf);
  double c = 0, s = 0;
  if (set->cos_sum)
    phase_angle (set, j->phase, &c, &s);
  float *row = (float *) ds_phase_set_scratch (set, thread);
  for (guint y = y0; y < y1; y++) {
    gsize off = (gsize) y * w;
    if (set->averaging) {
      const void *in = ds_image_row (frame, y);
      if (frame->type == DS_SAMPLE_U8)
        ds_copy_plane_u8 (in, row, w);
      else if (frame->type == DS_SAMPLE_U16)
        ds_copy_plane_u16 (in, row, w);
      else
        ds_clean_row_f32 (in, row, set->nonfinite + off, j->first, w);
      ds_fold_average_row (row, set->psum + off, set->rawmax + off, j->first_of_phase, j->first, w);
    } else if (frame->type == DS_SAMPLE_F32) {
      ds_clean_row_f32 (ds_image_row (frame, y), row, set->nonfinite + off, j->first, w);
      fold_values_row (set, j->phase, row, off, j->first);
    } else if (frame->type == DS_SAMPLE_U16) {
      FOLD_INT_ROW (guint16, u16);
    } else {
      FOLD_INT_ROW (guint8, u8);
    }
  }
}

/* The column flags of the sampling precondition need the phase offset: measured on the first
 * frame whose stripes are clear enough, as the daemon's phase check does. */
static void
locate_columns (DsPhaseSet *set, guint phase, const DsImage *frame)
{
  const DsStripeGeometry *g = &set->params.geometry;
  DsStripePhase sp;
  if (g->period_px > 2 && g->period_px <= frame->width &&
      ds_stripe_phase_measure (frame, g->period_px, NULL, &sp, NULL) && sp.reliable) {
    double offset = sp.phase - (double) phase / set->params.n_phases;
    offset -= floor (offset);
    ds_sampling_column_flags (&set->params, offset, set->width, set->column_flags);
    set->offset_used = offset;
    set->flags_need_offset = FALSE;
  }
}

void
ds_phase_set_locate_columns (DsPhaseSet *set, guint phase, const DsImage *frame)
{
  if (set->flags_need_offset)
    locate_columns (set, phase, frame);
}

gboolean
ds_phase_set_fold_begin (DsPhaseSet *set, guint phase, const DsImage *frame, GError **error)
{
  if (!check_frame (set, phase, frame, error))
    return FALSE;

  if (set->frames == 0) {
    /* First frame of a set: (re)allocate if the layout changed since the last set. */
    gboolean layout_same = set->typed && set->type == frame->type;
    set->type = frame->type;
    set->bit_depth = frame->bit_depth;
    if (!layout_same || !(set->max16 || set->maxf || set->planes16)) {
      set->typed = TRUE;
      if (!alloc_state (set, error)) {
        set->typed = FALSE;
        return FALSE;
      }
    }
    set->data_noise_dn = ds_separation_frame_noise (frame);
  } else if (set->count[phase] == 1 && !set->averaging) {
    if (!switch_to_averaging (set, error))
      return FALSE;
  }
  ds_phase_set_locate_columns (set, phase, frame);

  gboolean new_phase = (int) phase != set->current;
  if (new_phase && set->averaging)
    fold_pending_phase (set, set->fold_threads);
  return TRUE;
}

void
ds_phase_set_fold_frame (DsPhaseSet *set, guint phase, const DsImage *frame)
{
  FoldJob j = { .set = set, .frame = frame, .phase = phase, .first = set->frames == 0,
                .first_of_phase = set->count[phase] == 0 };
  ds_phase_set_reserve_scratch (set, set->width);
  ds_phase_set_run_rows_on (set, set->fold_threads, fold_frame_rows, &j);
}

void
ds_phase_set_fold_end (DsPhaseSet *set, guint phase)
{
  if (!set->averaging)
    set->phases_folded++;
  set->count[phase]++;
  set->current = (int) phase;
  set->frames++;
}

gboolean
ds_phase_set_accumulate (DsPhaseSet *set, guint phase, const DsImage *frame, GError **error)
{
  if (!ds_phase_set_fold_begin (set, phase, frame, error))
    return FALSE;
  ds_phase_set_fold_frame (set, phase, frame);
  ds_phase_set_fold_end (set, phase);
  return TRUE;
}

void
ds_phase_set_fold_pending (DsPhaseSet *set)
{
  /* The finalize's first step (the last phase's mean, when averaging). */
  fold_pending_phase (set, set->finalize_threads);
  set->current = -1;
}
