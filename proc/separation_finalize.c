/* Finalize: the estimators (maxmin, sine, robust), the quality mask, the noise model and the
 * result. Formulas and choices: docs/estimators.md. Per pixel in double precision (the row
 * kernels of separation_rows.c); integer state is widened there, and the dark frame is
 * subtracted there in signed arithmetic. Integer maxmin and sine without a noise model, kept
 * extrema or the motion test take float rows instead (separation_kernels.c): the same mask
 * rules, Ld and Lg within float rounding of the double rows (/separation-fused/...,
 * /separation-sine-fast/...). Rows are split over the set's worker threads; every
 * per-set sum is made per row and added in row order, so any split gives the same bits. */
#include <math.h>
#include <string.h>
#include <sys/mman.h>

#include "proc/harmonic_gain.h"
#include "proc/proc_error.h"
#include "proc/separation_internal.h"
#include "proc/separation_rows.h"

/* P(Rayleigh noise amplitude > t) = exp(-t^2 / (2 s^2)) = 1e-3 at t = 3.717 s. */
#define DS_RAYLEIGH_999 3.7169221888498383

typedef struct {
  DsPhaseSet *set;
  DsSeparation *sep;
  DsRowConsts c;
  DsMaxminFast fast;       /* the integer maxmin path without model or extrema */
  gboolean use_fast;
  DsSineFast sine_fast;    /* the integer sine path without model, extrema or motion */
  gboolean use_sine_fast;
  DsRobustTables tables;
  double *row_mean_sum;    /* per row */
  guint64 *row_mean_count; /* per row */
  guint64 *counts;         /* per thread: DS_MASK_N_BITS + 1 */
  const guint8 *column_flags; /* undersampled columns, NULL if none */
  const DsImage *last_frame; /* fast path: the set's last frame, folded on the way; or NULL */
  double last_c, last_s;     /* its phase's angle, for the motion sums */
  DsRowJob prepare;          /* or NULL: run over each block of rows before they are read */
  gpointer prepare_data;
  guint prepare_block;
} FinalizeJob;

static void
finalize_rows (gpointer data, guint y0, guint y1, guint thread)
{
  FinalizeJob *j = data;
  DsPhaseSet *set = j->set;
  DsSeparation *sep = j->sep;
  const DsRowConsts *c = &j->c;
  const guint8 *column_flags = j->column_flags;
  guint w = set->width;
  guint64 *counts = j->counts + (gsize) thread * (DS_MASK_N_BITS + 1);
  DsRowBuffers rb;
  ds_row_buffers_init (&rb, ds_phase_set_scratch (set, thread), w);
  for (guint y = y0; y < y1; y++) {
    if (j->prepare && (y - y0) % j->prepare_block == 0)
      j->prepare (j->prepare_data, y, MIN (y + j->prepare_block, y1), thread);
    gsize off = (gsize) y * w;
    const float *dark = set->dark ? set->dark + off : rb.dark_zero;
    DsRowOutputs o = {
      .t = ds_image_row (sep->transmissive, y), .g = ds_image_row (sep->scattered, y),
      .mk = ds_image_row (sep->mask, y),
      .mx = sep->max ? ds_image_row (sep->max, y) : NULL,
      .mn = sep->min ? ds_image_row (sep->min, y) : NULL,
      .me = sep->mean ? ds_image_row (sep->mean, y) : NULL,
      .st = sep->sigma_transmissive ? ds_image_row (sep->sigma_transmissive, y) : NULL,
      .sg = sep->sigma_scattered ? ds_image_row (sep->sigma_scattered, y) : NULL,
    };
    if (j->use_fast) {
      const DsImage *f = j->last_frame;
      if (f && set->sumsq) {
        /* the motion sums take the frame as the fold does (the same kernels, so the same bits);
         * the fast row then reads the extrema from the state */
        if (f->type == DS_SAMPLE_U16) {
          const guint16 *in = ds_image_row (f, y);
          ds_fold_extrema_sum_u16 (in, set->max16 + off, set->min16 + off, set->sum32 + off, w);
          ds_fold_harmonic_u16 (in, j->last_c, j->last_s, set->cos_sum + off, set->sin_sum + off, FALSE, w);
          ds_fold_sumsq_u16 (in, set->sumsq + off, FALSE, w);
        } else {
          const guint8 *in = ds_image_row (f, y);
          ds_fold_extrema_sum_u8 (in, set->max16 + off, set->min16 + off, set->sum32 + off, w);
          ds_fold_harmonic_u8 (in, j->last_c, j->last_s, set->cos_sum + off, set->sin_sum + off, FALSE, w);
          ds_fold_sumsq_u8 (in, set->sumsq + off, FALSE, w);
        }
        f = NULL;
      }
      DsMaxminFastRow r = { .hi = set->max16 + off, .lo = set->min16 + off,
                            .in16 = f && f->type == DS_SAMPLE_U16 ? ds_image_row (f, y) : NULL,
                            .in8 = f && f->type == DS_SAMPLE_U8 ? ds_image_row (f, y) : NULL,
                            .dark = set->dark ? set->dark + off : NULL,
                            .flags = column_flags,
                            .t = o.t, .g = o.g, .mk = o.mk };
      ds_maxmin_fast_row (&r, w, &j->fast, counts);
      if (c->motion) {
        /* the extrema as the fast row left them */
        ds_row_load_fast (set->max16 + off, set->min16 + off, set->sum32 + off, c->n, &rb, w);
        ds_row_motion (c, set->sumsq + off, rb.mean_raw, 1.0, set->cos_sum + off, set->sin_sum + off, dark, &rb, w);
        ds_row_or_motion (rb.motion, o.mk, w, counts);
      }
      continue;
    }
    if (j->use_sine_fast) {
      DsSineFastRow r = { .c64 = set->cos64 + off, .s64 = set->sin64 + off, .hi = set->max16 + off,
                          .lo = set->min16 + off, .sum = set->sum32 + off,
                          .satn = set->sat_count ? set->sat_count + off : NULL,
                          .dark = set->dark ? set->dark + off : NULL, .flags = column_flags,
                          .t = o.t, .g = o.g, .mk = o.mk };
      ds_sine_fast_row (&r, w, &j->sine_fast, counts);
      continue;
    }
    if (set->max16)
      ds_row_load_fast (set->max16 + off, set->min16 + off, set->sum32 ? set->sum32 + off : NULL,
                        c->n, &rb, w);
    else
      ds_row_load_float (set->maxf ? set->maxf + off : NULL, set->minf ? set->minf + off : NULL,
                         set->sumd ? set->sumd + off : NULL, set->rawmax ? set->rawmax + off : NULL,
                         set->nonfinite ? set->nonfinite + off : NULL, c->n, dark, &rb, w);
    switch (c->estimator) {
    case DS_ESTIMATOR_SINE:
      if (set->cos64) {
        ds_row_harmonic_from_fix (set->cos64 + off, set->sin64 + off, DS_HARMONIC_FIX_BITS, &rb, w);
        ds_row_sine (c, rb.cs, rb.sn, dark, &rb, w);
      } else {
        ds_row_sine (c, set->cos_sum + off, set->sin_sum + off, dark, &rb, w);
      }
      break;
    case DS_ESTIMATOR_ROBUST:
      ds_row_robust (c, &j->tables, set->planes16 ? set->planes16 + off : NULL,
                     set->planesf ? set->planesf + off : NULL, set->npix, dark, &rb, w);
      if (!set->rawmax)
        memcpy (rb.rmax, rb.hi_raw, w * sizeof (double));
      break;
    default:
      ds_row_maxmin (c, dark, &rb, w);
      break;
    }
    const guint8 *flags = column_flags;
    if (c->motion) {
      /* robust judged its row from its planes; the others kept the sums */
      if (c->estimator != DS_ESTIMATOR_ROBUST)
        ds_row_motion (c, set->sumsq + off, rb.mean_raw, 1.0, set->cos_sum + off, set->sin_sum + off,
                       dark, &rb, w);
      flags = ds_row_motion_flags (&rb, column_flags, w);
    }
    j->row_mean_sum[y] = 0;
    j->row_mean_count[y] = 0;
    ds_row_tail (c, &rb, dark, flags, &o, w, &j->row_mean_sum[y], &j->row_mean_count[y], counts);
  }
}

/* Result planes are fresh memory: first-touch page faults cost more than the arithmetic.
 * Asking for transparent huge pages (where the system allows them on request) cuts the
 * faults 512-fold. Advisory only: failure changes nothing. */
static DsImage *
new_plane (DsSampleType type, guint w, guint h, GError **error)
{
  DsImage *img = ds_image_new (type, w, h, error);
#ifdef MADV_HUGEPAGE
  const gsize huge = 2u << 20;
  gsize bytes = img ? img->stride * h : 0;
  if (bytes >= 2 * huge) {
    guintptr start = ((guintptr) img->data + huge - 1) & ~(guintptr) (huge - 1);
    guintptr end = ((guintptr) img->data + bytes) & ~(guintptr) (huge - 1);
    if (end > start)
      (void) madvise ((void *) start, end - start, MADV_HUGEPAGE);
  }
#endif
  return img;
}

static const char *const plane_names[] = { "transmissive", "scattered", "mask", "max", "min", "mean",
                                           "sigma_transmissive", "sigma_scattered" };

static DsImage **
plane_slot (DsSeparation *sep, guint i)
{
  DsImage **slots[] = { &sep->transmissive, &sep->scattered, &sep->mask, &sep->max, &sep->min,
                        &sep->mean, &sep->sigma_transmissive, &sep->sigma_scattered };
  return slots[i];
}

/* Checks the caller's planes, then allocates the missing ones and frees the unwanted ones. */
static gboolean
prepare_planes (DsSeparation *sep, const gboolean want[8], guint w, guint h, GError **error)
{
  for (guint i = 0; i < G_N_ELEMENTS (plane_names); i++) {
    DsImage *p = *plane_slot (sep, i);
    DsSampleType type = i == 2 ? DS_SAMPLE_U8 : DS_SAMPLE_F32;
    if (p && want[i] && (p->type != type || p->width != w || p->height != h)) {
      g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_INVALID_ARGUMENT,
                   "result plane %s is %ux%u %s, the phase set makes %ux%u %s", plane_names[i], p->width,
                   p->height, ds_sample_type_name (p->type), w, h, ds_sample_type_name (type));
      return FALSE;
    }
  }
  for (guint i = 0; i < G_N_ELEMENTS (plane_names); i++) {
    DsImage **slot = plane_slot (sep, i);
    if (!want[i]) {
      g_clear_pointer (slot, ds_image_free);
    } else if (!*slot) {
      *slot = new_plane (i == 2 ? DS_SAMPLE_U8 : DS_SAMPLE_F32, w, h, error);
      if (!*slot)
        return FALSE;
    }
  }
  return TRUE;
}

DsSeparation *
ds_separation_new (void)
{
  return g_new0 (DsSeparation, 1);
}

DsSeparation *
ds_phase_set_finalize (DsPhaseSet *set, GError **error)
{
  return ds_phase_set_finalize_reusing (set, NULL, error);
}

DsSeparation *
ds_phase_set_finalize_reusing (DsPhaseSet *set, DsSeparation *reuse, GError **error)
{
  g_autoptr (DsSeparation) sep = reuse ? reuse : ds_separation_new ();
  /* a plane of another shape is simply replaced here (the caller gave the result away) */
  for (guint i = 0; i < G_N_ELEMENTS (plane_names); i++) {
    DsImage **slot = plane_slot (sep, i);
    DsSampleType type = i == 2 ? DS_SAMPLE_U8 : DS_SAMPLE_F32;
    if (*slot && ((*slot)->type != type || (*slot)->width != set->width || (*slot)->height != set->height))
      g_clear_pointer (slot, ds_image_free);
  }
  if (!ds_phase_set_finalize_into (set, sep, error))
    return NULL;
  return g_steal_pointer (&sep);
}

/* Everything that can fail, before any pixel is written: the set has a frame in every phase
 * (`pending`: a phase whose first frame is being folded in the same pass, or -1) and the
 * caller's planes fit; missing planes are allocated. */
static gboolean
finalize_prepare (DsPhaseSet *set, DsSeparation *sep, int pending, guint *m_frames_out, GError **error)
{
  const DsSeparationParams *p = &set->params;
  guint n = p->n_phases;
  if (!sep) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_INVALID_ARGUMENT, "no result to finalize into");
    return FALSE;
  }
  if (set->frames == 0 && pending < 0) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_EMPTY, "phase set is empty: no frame folded");
    return FALSE;
  }
  guint m_frames = G_MAXUINT;
  for (guint k = 0; k < n; k++) {
    guint count = set->count[k] + ((int) k == pending);
    if (count == 0) {
      g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_NOT_ENOUGH_PHASES,
                   "phase %u of N = %u has no frame (%u frames folded)", k, n, set->frames);
      return FALSE;
    }
    m_frames = MIN (m_frames, count);
  }
  gboolean model = p->system_gain > 0, extrema = p->keep_extrema;
  gboolean want[8] = { TRUE, TRUE, TRUE, extrema, extrema, extrema, model, model };
  if (!prepare_planes (sep, want, set->width, set->height, error))
    return FALSE;
  *m_frames_out = m_frames;
  return TRUE;
}

/* The integer sine's fast row but for the motion test, which needs a noise level besides. The
 * sum is converted as a signed 32-bit integer: N samples of the type's full scale must stay
 * below 2^31 (whatever bit depth the frames claim). */
static gboolean
sine_fast_state (const DsPhaseSet *set)
{
  const DsSeparationParams *p = &set->params;
  return set->cos64 && set->max16 && set->sum32 && p->estimator == DS_ESTIMATOR_SINE &&
         !(p->system_gain > 0) && !p->keep_extrema &&
         (guint64) p->n_phases * (set->type == DS_SAMPLE_U8 ? 255u : 65535u) < (1ull << 31);
}

gboolean
ds_phase_set_sine_fast (const DsPhaseSet *set)
{
  return sine_fast_state (set) && !set->motion;
}

guint32
ds_phase_set_saturated_from (const DsPhaseSet *set)
{
  /* as finalize_run's c->sat for integer frames; an integer sample is >= sat exactly when it
   * is >= ceil (sat) */
  double sat = set->params.saturation_level > 0 ? set->params.saturation_level
                                                : (double) ((1u << set->bit_depth) - 1);
  return (guint32) MIN (ceil (sat), 65536.0);
}

/* The pixels and meta; cannot fail. last_frame: see FinalizeJob; prepare, block, data: see
 * ds_phase_set_finalize_prepared_into (prepare NULL: none). */
static void
finalize_run (DsPhaseSet *set, DsSeparation *sep, guint m_frames, const DsImage *last_frame, guint last_phase,
              DsRowJob prepare, guint block, gpointer data)
{
  const DsSeparationParams *p = &set->params;
  guint n = p->n_phases;
  gboolean model = p->system_gain > 0, extrema = p->keep_extrema;
  FinalizeJob j = { .set = set, .sep = sep, .last_frame = last_frame, .prepare = prepare,
                    .prepare_data = data, .prepare_block = MAX (block, 1) };
  /* as the fold computes a phase's angle (separation_accumulate.c), for the same bits */
  double angle = 2.0 * G_PI * (double) last_phase / (double) p->n_phases;
  j.last_c = cos (angle);
  j.last_s = sin (angle);
  DsRowConsts *c = &j.c;
  gboolean integer = set->type != DS_SAMPLE_F32;
  c->n = n;
  c->m_frames = m_frames;
  c->b = p->black_level;
  c->inv1b = 1.0 / (1.0 - p->black_level);
  c->m = ds_pattern_mean (p->pattern, p->duty, p->black_level);
  c->h = p->harmonic_gain > 0 ? p->harmonic_gain
                              : ds_harmonic_gain_theory (p->pattern, p->duty, p->black_level);
  c->model = model;
  c->gain = p->system_gain;
  c->read_var = p->read_noise_dn * p->read_noise_dn + (integer ? 1.0 / 12.0 : 0.0);
  c->data_sigma = set->data_noise_dn;
  c->floor = model ? sqrt (c->read_var) : set->data_noise_dn;
  c->sat = p->saturation_level > 0 ? p->saturation_level
           : integer              ? (double) ((1u << set->bit_depth) - 1)
                                  : NAN;
  c->range_q = set->range_quantile;
  c->rayleigh = DS_RAYLEIGH_999 * sqrt (2.0 / n);
  /* DARK_EXCEEDS compares the darkest of N phases with one dark value: each d - x_k is normal
   * with variance var(phase mean) + var(dark), so by the union bound over the N phases the
   * (1 - 1e-3/N) quantile keeps the false-alarm rate at most 1e-3 whatever the two variances
   * (docs/estimators.md, "Quality mask"). The dark frame is taken as one frame's noise. */
  c->exceed_q = ds_separation_normal_upper_quantile (DS_DARK_EXCEEDS_FALSE_ALARM / n);
  double dark_frame_var = set->dark ? 1.0 : 0.0;
  c->dark_var = dark_frame_var * c->read_var;
  c->data_exceed_var = isnan (c->data_sigma) ? 0.0
                       : c->data_sigma * c->data_sigma * (1.0 / m_frames + dark_frame_var);
  c->estimator = p->estimator;
  c->dark = set->dark != NULL;
  c->extrema = extrema;
  c->sigmas = model;
  c->len_hi = p->estimator == DS_ESTIMATOR_ROBUST ? set->robust_hi : 1;
  c->len_lo = p->estimator == DS_ESTIMATOR_ROBUST ? set->robust_lo : 1;
  /* MOTION needs a noise level: the model's per pixel, or the data's for the frame */
  /* integer samples carry at least their quantisation, 1/12 DN^2, whatever the frame showed */
  c->data_var_phase = (c->data_sigma * c->data_sigma + (integer ? 1.0 / 12.0 : 0.0)) / m_frames;
  c->motion = set->motion && (model || !isnan (c->data_var_phase));
  c->motion_kappa = set->motion_kappa;
  c->motion_chi2 = set->motion_chi2;

  j.use_fast = set->max16 && p->estimator == DS_ESTIMATOR_MAXMIN && !model && !extrema;
  if (j.use_fast) {
    DsMaxminFast *k = &j.fast;
    k->inv1b = (float) c->inv1b;
    k->b = (float) c->b;
    k->invm = (float) (1.0 / c->m);
    k->m = (float) c->m;
    k->sat = isnan (c->sat) ? INFINITY : (float) c->sat;
    k->floor = isnan (c->floor) ? -INFINITY : (float) c->floor;
    double lowmod = c->range_q * c->data_sigma / sqrt ((double) m_frames);
    k->lowmod = isnan (lowmod) ? -INFINITY : (float) lowmod;
    k->exceed = (float) (c->exceed_q * sqrt (c->data_exceed_var));
  }
  /* The general row works in double and makes the sigmas and extrema even when nobody asks
   * for them; without them (and without the motion test) integer sine takes a float row. */
  j.use_sine_fast = sine_fast_state (set) && !c->motion;
  /* a window's counts stand for max16 only on this row */
  g_assert (!set->sat_count || j.use_sine_fast);
  if (j.use_sine_fast) {
    DsSineFast *k = &j.sine_fast;
    k->two_n = (float) (2.0 / n);
    k->inv_n = (float) (1.0 / n);
    k->inv_h = (float) (1.0 / c->h);
    k->inv_m = (float) (1.0 / c->m);
    /* the maximum is an integer: max >= sat exactly when max >= ceil (sat), which float holds
     * exactly, so SATURATED is the general path's bit for bit */
    k->sat = isnan (c->sat) ? INFINITY : (float) ceil (c->sat);
    g_assert (isnan (c->sat) || (guint32) MIN (ceil (c->sat), 65536.0) == ds_phase_set_saturated_from (set));
    k->floor = isnan (c->floor) ? -INFINITY : (float) c->floor;
    double lowamp = c->rayleigh * c->data_sigma / sqrt ((double) m_frames);
    k->lowamp = isnan (lowamp) ? -INFINITY : (float) lowamp;
    k->exceed = (float) (c->exceed_q * sqrt (c->data_exceed_var));
  }
  g_autofree double *tab = NULL;
  if (p->estimator == DS_ESTIMATOR_ROBUST) {
    tab = g_new (double, 6 * (gsize) n);
    for (guint k = 0; k < n; k++) {
      tab[k] = cos (2 * G_PI * k / n);
      tab[n + k] = sin (2 * G_PI * k / n);
    }
    ds_robust_tables (n, set->robust_hi, set->robust_lo, tab + 2 * n, tab + 3 * n, tab + 4 * n, tab + 5 * n);
    j.tables = (DsRobustTables) { tab, tab + n, tab + 2 * n, tab + 3 * n, tab + 4 * n, tab + 5 * n,
                                  set->robust_hi, set->robust_lo };
  }
  /* Undersampled columns whose place could not be measured (no frame showed clear stripes):
   * every column may be one of them. */
  g_autofree guint8 *all_columns = NULL;
  j.column_flags = set->column_flags;
  if (set->flags_need_offset) {
    all_columns = g_malloc (set->width);
    memset (all_columns, DS_MASK_UNDERSAMPLED, set->width);
    j.column_flags = all_columns;
  }
  g_autofree double *row_sum = g_new0 (double, set->height);
  g_autofree guint64 *row_count = g_new0 (guint64, set->height);
  g_autofree guint64 *counts = g_new0 (guint64, (gsize) set->threads * (DS_MASK_N_BITS + 1));
  j.row_mean_sum = row_sum;
  j.row_mean_count = row_count;
  j.counts = counts;
  ds_phase_set_reserve_scratch (set, (gsize) DS_ROW_DOUBLES * set->width);
  ds_phase_set_run_rows_on (set, set->finalize_threads, finalize_rows, &j);

  DsSeparationMeta *meta = &sep->meta;
  memset (meta, 0, sizeof *meta);
  for (guint t = 0; t < set->threads; t++) {
    const guint64 *ct = counts + (gsize) t * (DS_MASK_N_BITS + 1);
    meta->valid_pixels += ct[0];
    for (guint bit = 0; bit < DS_MASK_N_BITS; bit++)
      meta->flagged[bit] += ct[1 + bit];
  }
  double mean_total = 0;
  guint64 mean_count = 0;
  for (guint y = 0; y < set->height; y++) {
    mean_total += row_sum[y];
    mean_count += row_count[y];
  }
  meta->n_phases = n;
  meta->frames_per_phase = m_frames;
  meta->estimator = p->estimator;
  meta->duty = p->duty;
  meta->black_level = p->black_level;
  meta->pattern_mean = c->m;
  meta->harmonic_gain = c->h;
  meta->dark_subtracted = set->dark != NULL;
  meta->saturation_level = c->sat;
  meta->phase_offset_cycles = set->column_flags && !set->flags_need_offset ? set->offset_used : NAN;
  meta->motion_checked = c->motion;
  if (model) {
    double s = mean_count ? mean_total / mean_count : 0;
    meta->noise_dn = sqrt (c->read_var + c->gain * (s > 0 ? s : 0));
  } else {
    meta->noise_dn = c->data_sigma;
  }
}

gboolean
ds_phase_set_finalize_into (DsPhaseSet *set, DsSeparation *sep, GError **error)
{
  guint m_frames;
  if (!finalize_prepare (set, sep, -1, &m_frames, error))
    return FALSE;
  ds_phase_set_fold_pending (set);
  finalize_run (set, sep, m_frames, NULL, 0, NULL, 0, NULL);
  return TRUE;
}

gboolean
ds_phase_set_finalize_prepared_into (DsPhaseSet *set, DsSeparation *sep, DsRowJob prepare, guint block,
                                     gpointer data, GError **error)
{
  guint m_frames;
  if (!finalize_prepare (set, sep, -1, &m_frames, error))
    return FALSE;
  ds_phase_set_fold_pending (set);
  finalize_run (set, sep, m_frames, NULL, 0, prepare, block, data);
  return TRUE;
}

/* The last frame can be folded on the finalize's way through the pixels when the finalize
 * reads nothing but the extrema and the motion sums (the integer maxmin path) and the frame
 * completes the set: one frame per phase, this phase's the last one missing. */
static gboolean
fusable (const DsPhaseSet *set, guint phase)
{
  const DsSeparationParams *p = &set->params;
  gboolean other_sums = (set->sum32 || set->cos_sum) && !set->sumsq;
  if (!set->max16 || other_sums || set->averaging || p->estimator != DS_ESTIMATOR_MAXMIN ||
      p->system_gain > 0 || p->keep_extrema || set->count[phase] != 0)
    return FALSE;
  for (guint k = 0; k < p->n_phases; k++)
    if (k != phase && set->count[k] != 1)
      return FALSE;
  return TRUE;
}

gboolean
ds_phase_set_accumulate_finalize_into (DsPhaseSet *set, guint phase, const DsImage *frame, DsSeparation *sep,
                                       gboolean *folded, GError **error)
{
  if (folded)
    *folded = FALSE;
  if (!sep) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_INVALID_ARGUMENT, "no result to finalize into");
    return FALSE;
  }
  if (!ds_phase_set_fold_begin (set, phase, frame, error))
    return FALSE;
  guint m_frames;
  /* When the result cannot be made (planes that do not fit), the frame is still folded and
   * the finalize below says why, as the two calls would. */
  if (fusable (set, phase) && finalize_prepare (set, sep, (int) phase, &m_frames, NULL)) {
    finalize_run (set, sep, m_frames, frame, phase, NULL, 0, NULL);
    ds_phase_set_fold_end (set, phase);
    ds_phase_set_fold_pending (set); /* nothing pending: the set is left as finalize leaves it */
    if (folded)
      *folded = TRUE;
    return TRUE;
  }
  ds_phase_set_fold_frame (set, phase, frame);
  ds_phase_set_fold_end (set, phase);
  if (folded)
    *folded = TRUE;
  return ds_phase_set_finalize_into (set, sep, error);
}
