/* Private to proc/separation_*.c: the phase set's state, shared by the accumulate and the
 * finalize halves. Not installed, not for other concerns. */
#pragma once
#include <glib.h>

#include "proc/separation.h"
#include "proc/worker_pool.h"

G_BEGIN_DECLS

/* Frames smaller than this are folded on the caller's thread alone: waking workers would cost
 * more than the rows. */
#define DS_THREADED_MIN_PIXELS (128u * 1024u)

struct DsPhaseSet {
  DsSeparationParams params;
  guint width, height;
  gsize npix;

  /* Decided by the first frame of a set (memory is reallocated only when these change). */
  gboolean typed;
  DsSampleType type;
  guint bit_depth;
  gboolean averaging;      /* the first phase got a second frame: phase means are folded */

  guint *count;            /* frames folded (or pending) per phase */
  guint frames;            /* all frames of the set */
  guint phases_folded;     /* phase means folded into the extrema */
  int current;             /* phase being received, -1 before the first frame */

  /* Integer input, one frame per phase (the fast path): raw extrema, exact sum. robust keeps
   * its N phase planes instead (planes16) and derives extrema and sum from them. */
  guint16 *max16, *min16;
  guint32 *sum32;          /* NULL when nothing needs the mean (maxmin without extrema) */
  /* Float input, or averaging: extrema of phase means, sum of phase means. */
  float *maxf, *minf;
  double *sumd;
  float *rawmax;           /* averaging only: largest raw sample (saturation) */
  double *psum;            /* averaging only: running sum of the current phase */
  guint8 *nonfinite;       /* float input only: some sample was NaN or Inf */
  gint64 *cos64, *sin64;   /* sine, integer fast path: the first harmonic in fixed point, sum of
                              ds_harmonic_fix_weights x sample; exact, so independent of the
                              order the frames came in (a sliding window adds and retires) */
  double *cos_sum, *sin_sum; /* first harmonic of the phase means: sine on float input or with
                                averaging, and any estimator's motion test (maxmin, sine) */
  double *sumsq;           /* motion (maxmin, sine): sum of squares of the phase values; exact for
                              integer samples (below 2^53 up to DS_MAX_PHASES frames of 16 bits) */
  const guint8 *sat_count; /* NULL, or (a sliding window's, proc/phase_window.c) per pixel how
                              many of the set's samples are >= ds_phase_set_saturated_from: the
                              integer sine's fast row then takes SATURATED from it, not from
                              max16, and reads min16 only with a dark frame (the only use of the
                              minimum there). Only while ds_phase_set_sine_fast holds. */
  guint16 *planes16;       /* robust, integer fast path: N planes of raw frames */
  float *planesf;          /* robust otherwise: N planes of phase means */
  guint robust_hi, robust_lo; /* robust's window lengths (ds_robust_windows) */

  float *dark;             /* dark frame as float, NULL if none */
  DsSampleType dark_type;
  guint dark_bit_depth;

  double data_noise_dn;    /* noise of one raw frame estimated from the first frame; NAN */
  double range_quantile;   /* 0.999 quantile of the range of N unit normals */

  /* Motion (separation_motion.c): checked when params.detect_motion and N >= 4. */
  gboolean motion;
  double motion_kappa;     /* largest pattern residual energy / first-harmonic energy */
  double motion_chi2;      /* chi-square quantile of N - 3 degrees of freedom at the false-alarm rate */

  /* Threads: the pool is made on the first frame large enough to share. */
  guint threads;           /* resolved from params.threads */
  guint fold_threads;      /* accumulate uses at most this many; 0: all */
  guint finalize_threads;  /* the finalize uses at most this many; 0: all */
  DsWorkerPool *pool;
  double *scratch;         /* threads x scratch_doubles, for row buffers */
  gsize scratch_doubles;

  /* Sampling precondition: columns never fully lit or dark (DS_MASK_UNDERSAMPLED or 0).
   * NULL when no column is affected or the check does not apply. */
  DsSamplingCheck sampling;
  guint8 *column_flags;
  gboolean flags_need_offset; /* flags are needed but the phase offset is not known yet */
  double offset_used;
};

/* Runs job over the set's rows on its threads (the pool is made on first use when the frame
 * is large enough). */
void ds_phase_set_run_rows (DsPhaseSet *set, DsRowJob job, gpointer data);
/* The same on at most max_threads of them (0: all). */
void ds_phase_set_run_rows_on (DsPhaseSet *set, guint max_threads, DsRowJob job, gpointer data);
/* Per-thread row scratch of at least `doubles` doubles, valid until the next call. */
double *ds_phase_set_scratch (DsPhaseSet *set, guint thread);
void ds_phase_set_reserve_scratch (DsPhaseSet *set, gsize doubles);

/* ds_phase_set_accumulate in three steps: begin checks the frame and prepares the state (on
 * failure nothing is folded), fold_frame folds its pixels (on the fold threads), end counts it. */
gboolean ds_phase_set_fold_begin (DsPhaseSet *set, guint phase, const DsImage *frame, GError **error);
void ds_phase_set_fold_frame (DsPhaseSet *set, guint phase, const DsImage *frame);
void ds_phase_set_fold_end (DsPhaseSet *set, guint phase);

/* The sampling check's column flags wait for a frame with clear stripes: measures them on
 * `frame` (lit with `phase`) when they are still waiting; what ds_phase_set_fold_begin does for
 * every frame, for a caller that updates the state itself (proc/phase_window.c). */
void ds_phase_set_locate_columns (DsPhaseSet *set, guint phase, const DsImage *frame);

/* The integer sine's first-harmonic weights of `phase`: cos and sin of 2 pi phase / n times
 * 2^DS_HARMONIC_FIX_BITS, rounded. With samples below 2^16 and at most DS_MAX_PHASES frames
 * the 64-bit sums never overflow: |sum| < 2^16 * 2^16 * 2^30 = 2^62. The weights' rounding
 * moves the harmonic by at most 2^-31 of a sample per frame, far below one DN. */
#define DS_HARMONIC_FIX_BITS 30
void ds_harmonic_fix_weights (guint n, guint phase, gint32 *c, gint32 *s);

/* ds_phase_set_finalize_into, with prepare (data, y0, y1, thread) run on the finalize's thread
 * over each block of at most `block` rows just before the finalize reads them: a caller that
 * updates the state in place (proc/phase_window.c) does so while the rows are in cache. Every
 * set-wide input of the finalize (noise estimate, column flags, dark frame) must be final
 * before the call, and prepare may change only the state of its own rows. Fails as
 * ds_phase_set_finalize_into does, before prepare has run on any row. */
gboolean ds_phase_set_finalize_prepared_into (DsPhaseSet *set, DsSeparation *sep, DsRowJob prepare,
                                              guint block, gpointer data, GError **error);

/* Whether the finalize takes the integer sine's fast row (ds_sine_fast_row) for this set's
 * state and parameters whatever the frames' noise: integer frames, one per phase, no noise
 * model, no kept extrema, no motion test. */
gboolean ds_phase_set_sine_fast (const DsPhaseSet *set);
/* The integer sample value from which a sample counts as saturated (SATURATED when the
 * maximum is at least it), for a set of integer frames; above 65535 when none can be. */
guint32 ds_phase_set_saturated_from (const DsPhaseSet *set);

/* Averaging: folds the last phase's mean (finalize calls it once; idempotent). */
void ds_phase_set_fold_pending (DsPhaseSet *set);

/* Noise helpers (separation_noise.c). */
/* Robust sigma of one frame from the median absolute second difference along y (the stripes
 * vary along x only, so the pattern cancels), on a sample of DS_NOISE_SAMPLES differences;
 * NAN if the frame has fewer than 3 rows or no finite difference. */
#define DS_NOISE_SAMPLES 16384u
double ds_separation_frame_noise (const DsImage *frame);
/* Upper p-quantile of the range (max - min) of n independent unit normals, n >= 2. */
double ds_separation_range_quantile (guint n, double p);
/* z with P(unit normal > z) = p, 0 < p < 1/2. */
double ds_separation_normal_upper_quantile (double p);
/* Per-pixel false-alarm rate of DS_MASK_DARK_EXCEEDS (as LOW_MODULATION's). */
#define DS_DARK_EXCEEDS_FALSE_ALARM 1e-3

/* Motion (separation_motion.c). */
#define DS_MOTION_FALSE_ALARM 1e-3
/* x with P(chi-square of nu degrees of freedom > x) = p; nu >= 1, 0 < p < 1. */
double ds_chi2_upper_quantile (guint nu, double p);
/* The still pattern's own energy beyond the first harmonic, as a fraction of its first
 * harmonic's energy, the largest over pixel positions (docs/estimators.md, "MOTION"). */
double ds_motion_pattern_ratio (const DsSeparationParams *p);

/* Sampling model (separation_sampling.c). */
/* Lit fraction (0..1) seen by a pixel centred d pixels from a lit stripe's centre. */
double ds_sampling_profile (const DsSeparationParams *p, double d);
/* robust's window lengths: from the period, blur and aperture when the period is known. */
void ds_robust_windows (const DsSeparationParams *p, guint *len_hi, guint *len_lo);
/* Tables for ds_robust_start (n entries each). */
void ds_robust_tables (guint n, guint len_hi, guint len_lo, double *c_hi, double *s_hi, double *c_lo,
                       double *s_lo);
/* First phase of robust's window for a pixel whose first harmonic is (cs, sn): the window whose
 * centre is nearest the harmonic's phase (first one on a tie). */
guint ds_robust_start (double cs, double sn, const double *c_tab, const double *s_tab, guint n);
/* flags[x] = DS_MASK_UNDERSAMPLED where column x is undersampled; returns how many are. */
guint64 ds_sampling_column_flags (const DsSeparationParams *p, double offset_cycles, guint width,
                                  guint8 *flags);

/* Row kernels (separation_kernels.c). */
#define DS_DECLARE_INT_KERNELS(T, NAME)                                                           \
  void ds_fold_first_##NAME (const T *in, guint16 *mx, guint16 *mn, guint32 *sum, gsize w);      \
  void ds_fold_extrema_##NAME (const T *in, guint16 *mx, guint16 *mn, gsize w);                  \
  void ds_fold_extrema_sum_##NAME (const T *in, guint16 *mx, guint16 *mn, guint32 *sum, gsize w);\
  void ds_fold_harmonic_fix_##NAME (const T *in, gint32 c, gint32 s, gint64 *cs, gint64 *sn,    \
                                    gboolean first, gsize w);                                    \
  void ds_fold_harmonic_##NAME (const T *in, double c, double s, double *cs, double *sn,         \
                                gboolean first, gsize w);                                        \
  void ds_fold_sumsq_##NAME (const T *in, double *sq, gboolean first, gsize w);                  \
  void ds_copy_plane_##NAME (const T *in, float *out, gsize w);                                   \
  void ds_widen_##NAME (const T *in, guint16 *out, gsize w);
DS_DECLARE_INT_KERNELS (guint8, u8)
DS_DECLARE_INT_KERNELS (guint16, u16)

/* Float rows: NaN/Inf replaced by 0 and flagged; extrema and sum; first harmonic. */
void ds_clean_row_f32 (const float *in, float *out, guint8 *nf, gboolean first, gsize w);
void ds_fold_float_row (const float *v, float *mx, float *mn, double *sum, gboolean first, gsize w);
void ds_fold_harmonic_f32 (const float *v, double c, double s, double *cs, double *sn,
                           gboolean first, gsize w);
void ds_fold_sumsq_f32 (const float *v, double *sq, gboolean first, gsize w);
/* Averaging: ps (+)= v, rm = max (rm, v). */
void ds_fold_average_row (const float *v, double *ps, float *rm, gboolean first_of_phase,
                          gboolean first_of_set, gsize w);

/* maxmin on the integer fast path, no noise model: thresholds prepared once per set
 * (a disabled test carries +-INFINITY so that its comparison is always false). */
typedef struct {
  float inv1b, b, invm, m;
  float sat;     /* SATURATED when max >= sat */
  float floor;   /* DARK when the model mean <= floor */
  float lowmod;  /* LOW_MODULATION when max - min < lowmod */
  float exceed;  /* DARK_EXCEEDS when dark - min > exceed */
} DsMaxminFast;
/* One row of it. hi/lo: the set's extrema; with a frame row (in16 or in8, at most one) the
 * frame is folded into them on the way and they are written back. dark: NULL for none.
 * flags: the column flags (DS_MASK_UNDERSAMPLED or 0), or-ed into the mask; NULL for none. */
typedef struct {
  guint16 *hi, *lo;
  const guint16 *in16;
  const guint8 *in8;
  const float *dark;
  const guint8 *flags;
  float *t, *g;
  guint8 *mk;
} DsMaxminFastRow;
/* Writes t, g and mk and adds the mask's counts (as ds_count_mask_row) to counts. */
void ds_maxmin_fast_row (const DsMaxminFastRow *r, gsize w, const DsMaxminFast *k,
                         guint64 counts[DS_MASK_N_BITS + 1]);
/* sine on the integer fast path (fixed-point harmonic cos64/sin64, one frame per phase), no
 * noise model, no extrema kept, no motion test: the general row's quantities in float
 * (docs/estimators.md): A = (2/N) |harmonic|, mean = sum / N - dark, Ld = A / h,
 * Lg = mean / m - A / h, and the same mask bits. Thresholds prepared once per set; a disabled
 * test carries +-INFINITY so that its comparison is always false. Needs N x full scale below
 * 2^31 (the sum is converted as a signed 32-bit integer). */
typedef struct {
  float two_n, inv_n, inv_h, inv_m;
  float sat;     /* SATURATED when max >= sat */
  float floor;   /* DARK when the mean <= floor */
  float lowamp;  /* LOW_MODULATION when A < lowamp (the Rayleigh rule) */
  float exceed;  /* DARK_EXCEEDS when dark - min > exceed */
} DsSineFast;
typedef struct {
  const gint64 *c64, *s64;
  const guint16 *hi, *lo;  /* lo read only with a dark frame (without one no sample is below
                              the dark level 0, so DARK_EXCEEDS never holds) */
  const guint8 *satn;      /* NULL, or per pixel the samples >= sat: SATURATED where nonzero,
                              and hi is not read */
  const guint32 *sum;
  const float *dark;   /* NULL: none */
  const guint8 *flags; /* column flags (DS_MASK_UNDERSAMPLED or 0); NULL: none */
  float *t, *g;
  guint8 *mk;
} DsSineFastRow;
/* Writes t, g and mk and adds the mask's counts (as ds_count_mask_row) to counts. A pixel
 * whose Ld or Lg is beyond float32 is NONFINITE with 0 outputs, as in the general tail. */
void ds_sine_fast_row (const DsSineFastRow *r, gsize w, const DsSineFast *k,
                       guint64 counts[DS_MASK_N_BITS + 1]);
/* counts[0] += pixels with no bit; counts[1 + bit] += pixels with that bit. */
void ds_count_mask_row (const guint8 *mk, gsize w, guint64 counts[DS_MASK_N_BITS + 1]);

G_END_DECLS
