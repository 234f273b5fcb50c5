/* The streaming phase-set accumulator: frames are folded in one at a time as they arrive.
 *
 * Memory does not grow with N for maxmin and sine. The fast path (integer frames, one per
 * phase) keeps the raw extrema as u16 and, only when something needs the mean, an exact 32-bit
 * sum (exact up to DS_MAX_PHASES frames of 16 bits; widened to double at finalize). The row
 * loops below run over contiguous arrays with restrict pointers so the compiler vectorises them
 * (proc/separation.cmake builds this file with -ftree-vectorize). Float input and averaging (M
 * frames per phase) use float extrema of phase means and a double sum. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "proc/proc_error.h"
#include "proc/separation_internal.h"

static gboolean
needs_mean (const DsSeparationParams *p)
{
  return p->estimator != DS_ESTIMATOR_MAXMIN || p->keep_extrema;
}

static void
free_state (DsPhaseSet *set)
{
  g_clear_pointer (&set->max16, g_free);
  g_clear_pointer (&set->min16, g_free);
  g_clear_pointer (&set->sum32, g_free);
  g_clear_pointer (&set->maxf, g_free);
  g_clear_pointer (&set->minf, g_free);
  g_clear_pointer (&set->sumd, g_free);
  g_clear_pointer (&set->rawmax, g_free);
  g_clear_pointer (&set->psum, g_free);
  g_clear_pointer (&set->nonfinite, g_free);
  g_clear_pointer (&set->cos_sum, g_free);
  g_clear_pointer (&set->sin_sum, g_free);
  g_clear_pointer (&set->phase_means, g_free);
}

static gpointer
alloc_plane (DsPhaseSet *set, gsize n_elements, gsize element_size, gboolean *ok, GError **error)
{
  if (!*ok)
    return NULL;
  gsize bytes;
  gpointer p = NULL;
  /* 64-byte aligned (a cache line): vector loads of a row then never straddle two lines.
   * g_free releases it (GLib's allocator is the system's). */
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
  free_state (set);
  if (!is_float && !set->averaging) {
    set->max16 = alloc_plane (set, n, sizeof (guint16), &ok, error);
    set->min16 = alloc_plane (set, n, sizeof (guint16), &ok, error);
    if (needs_mean (p))
      set->sum32 = alloc_plane (set, n, sizeof (guint32), &ok, error);
  } else {
    set->maxf = alloc_plane (set, n, sizeof (float), &ok, error);
    set->minf = alloc_plane (set, n, sizeof (float), &ok, error);
    set->sumd = alloc_plane (set, n, sizeof (double), &ok, error);
    if (set->averaging) {
      set->rawmax = alloc_plane (set, n, sizeof (float), &ok, error);
      set->psum = alloc_plane (set, n, sizeof (double), &ok, error);
    }
  }
  if (is_float)
    set->nonfinite = alloc_plane (set, n, 1, &ok, error);
  if (p->estimator == DS_ESTIMATOR_SINE) {
    set->cos_sum = alloc_plane (set, n, sizeof (double), &ok, error);
    set->sin_sum = alloc_plane (set, n, sizeof (double), &ok, error);
  }
  if (p->estimator == DS_ESTIMATOR_ROBUST) {
    gsize planes;
    if (!g_size_checked_mul (&planes, n, p->n_phases))
      planes = G_MAXSIZE;
    set->phase_means = alloc_plane (set, planes, sizeof (float), &ok, error);
  }
  if (!ok)
    free_state (set);
  return ok;
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
  return set;
}

void
ds_phase_set_free (DsPhaseSet *set)
{
  if (!set)
    return;
  free_state (set);
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
   * memory; the first frame re-checks them. */
}

guint
ds_phase_set_frames_folded (const DsPhaseSet *set)
{
  return set->frames;
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
    for (guint x = 0; x < set->width; x++)
      d[x] = dark->type == DS_SAMPLE_U8    ? ((const guint8 *) row)[x]
             : dark->type == DS_SAMPLE_U16 ? ((const guint16 *) row)[x]
                                           : ((const float *) row)[x];
  }
  set->dark_type = dark->type;
  set->dark_bit_depth = dark->bit_depth;
  return TRUE;
}

/* Float input: NaN and Inf are replaced by 0 in the sums and flagged, so one bad sample
 * cannot poison the arithmetic (the pixel's outputs are then 0, see docs/estimators.md). */
static void
clean_row_f32 (const float *restrict in, float *restrict out, guint8 *restrict nf, gboolean first,
               gsize w)
{
  for (gsize x = 0; x < w; x++) {
    float v = in[x];
    guint8 bad = !isfinite (v);
    out[x] = bad ? 0.0f : v;
    nf[x] = first ? bad : (guint8) (nf[x] | bad);
  }
}

static void
fold_float_row (const float *restrict v, float *restrict mx, float *restrict mn,
                double *restrict sum, gboolean first, gsize w)
{
  if (first) {
    for (gsize x = 0; x < w; x++) {
      mx[x] = mn[x] = v[x];
      sum[x] = v[x];
    }
    return;
  }
  for (gsize x = 0; x < w; x++) {
    mx[x] = v[x] > mx[x] ? v[x] : mx[x];
    mn[x] = v[x] < mn[x] ? v[x] : mn[x];
    sum[x] += v[x];
  }
}

static void
fold_harmonic_f32 (const float *restrict v, double c, double s, double *restrict cs,
                   double *restrict sn, gboolean first, gsize w)
{
  for (gsize x = 0; x < w; x++) {
    cs[x] = (first ? 0.0 : cs[x]) + c * v[x];
    sn[x] = (first ? 0.0 : sn[x]) + s * v[x];
  }
}

static void
phase_angle (const DsPhaseSet *set, guint phase, double *c, double *s)
{
  double t = 2.0 * G_PI * (double) phase / (double) set->params.n_phases;
  *c = cos (t);
  *s = sin (t);
}

/* Folds one row of values for phase `phase` (float path: float input or phase means). */
static void
fold_values_row (DsPhaseSet *set, guint phase, const float *v, gsize off, gboolean first)
{
  gsize w = set->width;
  fold_float_row (v, set->maxf + off, set->minf + off, set->sumd + off, first, w);
  if (set->cos_sum) {
    double c, s;
    phase_angle (set, phase, &c, &s);
    fold_harmonic_f32 (v, c, s, set->cos_sum + off, set->sin_sum + off, first, w);
  }
  if (set->phase_means)
    memcpy (set->phase_means + (gsize) phase * set->npix + off, v, w * sizeof (float));
}

/* Averaging: the pending phase's mean is folded into the extrema and sums. */
static void
fold_pending_phase (DsPhaseSet *set)
{
  if (set->current < 0 || !set->averaging)
    return;
  guint phase = (guint) set->current;
  double inv = 1.0 / set->count[phase];
  gboolean first = set->phases_folded == 0;
  g_autofree float *row = g_new (float, set->width);
  for (guint y = 0; y < set->height; y++) {
    gsize off = (gsize) y * set->width;
    for (guint x = 0; x < set->width; x++)
      row[x] = (float) (set->psum[off + x] * inv);
    fold_values_row (set, phase, row, off, first);
  }
  set->phases_folded++;
}

/* The first phase got a second frame: until now exactly one frame was folded, so its value is
 * still in the extrema; it becomes the running phase sum and averaging starts. */
static gboolean
switch_to_averaging (DsPhaseSet *set, GError **error)
{
  gsize n = set->npix;
  g_autofree float *first = g_try_new (float, n);
  if (!first) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_TOO_LARGE, "cannot allocate a phase plane");
    return FALSE;
  }
  for (gsize i = 0; i < n; i++)
    first[i] = set->max16 ? set->max16[i] : set->maxf[i];
  guint8 *nf = g_steal_pointer (&set->nonfinite);
  set->averaging = TRUE;
  if (!alloc_state (set, error)) {
    g_free (nf);
    set->averaging = FALSE;
    set->typed = FALSE;
    return FALSE;
  }
  if (nf) {
    g_free (set->nonfinite);
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

gboolean
ds_phase_set_accumulate (DsPhaseSet *set, guint phase, const DsImage *frame, GError **error)
{
  if (!check_frame (set, phase, frame, error))
    return FALSE;

  if (set->frames == 0) {
    /* First frame of a set: (re)allocate if the layout changed since the last set. */
    gboolean layout_same = set->typed && set->type == frame->type;
    set->type = frame->type;
    set->bit_depth = frame->bit_depth;
    if (!layout_same || !(set->max16 || set->maxf)) {
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

  gsize w = set->width;
  gboolean new_phase = (int) phase != set->current;
  if (new_phase && set->averaging)
    fold_pending_phase (set);

  if (set->averaging) {
    gboolean first_of_phase = set->count[phase] == 0;
    gboolean first_of_set = set->frames == 0;
    g_autofree float *row = g_new (float, w);
    for (guint y = 0; y < set->height; y++) {
      gsize off = (gsize) y * w;
      const void *in = ds_image_row (frame, y);
      if (frame->type == DS_SAMPLE_U8)
        ds_copy_plane_u8 (in, row, w);
      else if (frame->type == DS_SAMPLE_U16)
        ds_copy_plane_u16 (in, row, w);
      else
        clean_row_f32 (in, row, set->nonfinite + off, first_of_set, w);
      double *ps = set->psum + off;
      float *rm = set->rawmax + off;
      for (gsize x = 0; x < w; x++) {
        ps[x] = (first_of_phase ? 0.0 : ps[x]) + row[x];
        rm[x] = first_of_set || row[x] > rm[x] ? row[x] : rm[x];
      }
    }
  } else if (frame->type == DS_SAMPLE_F32) {
    gboolean first = set->frames == 0;
    g_autofree float *row = g_new (float, w);
    for (guint y = 0; y < set->height; y++) {
      gsize off = (gsize) y * w;
      clean_row_f32 (ds_image_row (frame, y), row, set->nonfinite + off, first, w);
      fold_values_row (set, phase, row, off, first);
    }
    set->phases_folded++;
  } else {
    gboolean first = set->frames == 0;
    double c = 0, s = 0;
    if (set->cos_sum)
      phase_angle (set, phase, &c, &s);
    for (guint y = 0; y < set->height; y++) {
      gsize off = (gsize) y * w;
      const void *in = ds_image_row (frame, y);
      guint32 *sum = set->sum32 ? set->sum32 + off : NULL;
      if (frame->type == DS_SAMPLE_U16) {
        if (first)
          ds_fold_first_u16 (in, set->max16 + off, set->min16 + off, sum, w);
        else if (sum)
          ds_fold_extrema_sum_u16 (in, set->max16 + off, set->min16 + off, sum, w);
        else
          ds_fold_extrema_u16 (in, set->max16 + off, set->min16 + off, w);
        if (set->cos_sum) {
          if (first)
            memset (set->cos_sum + off, 0, w * sizeof (double)),
              memset (set->sin_sum + off, 0, w * sizeof (double));
          ds_fold_harmonic_u16 (in, c, s, set->cos_sum + off, set->sin_sum + off, w);
        }
        if (set->phase_means)
          ds_copy_plane_u16 (in, set->phase_means + (gsize) phase * set->npix + off, w);
      } else {
        if (first)
          ds_fold_first_u8 (in, set->max16 + off, set->min16 + off, sum, w);
        else if (sum)
          ds_fold_extrema_sum_u8 (in, set->max16 + off, set->min16 + off, sum, w);
        else
          ds_fold_extrema_u8 (in, set->max16 + off, set->min16 + off, w);
        if (set->cos_sum) {
          if (first)
            memset (set->cos_sum + off, 0, w * sizeof (double)),
              memset (set->sin_sum + off, 0, w * sizeof (double));
          ds_fold_harmonic_u8 (in, c, s, set->cos_sum + off, set->sin_sum + off, w);
        }
        if (set->phase_means)
          ds_copy_plane_u8 (in, set->phase_means + (gsize) phase * set->npix + off, w);
      }
    }
    set->phases_folded++;
  }
  set->count[phase]++;
  set->current = (int) phase;
  set->frames++;
  return TRUE;
}

void
ds_phase_set_fold_pending (DsPhaseSet *set)
{
  fold_pending_phase (set);
  set->current = -1;
}
