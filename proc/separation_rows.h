/* Private to proc/separation_*.c: the finalize's row kernels. One row of pixels at a time, in
 * double precision, written as straight-line loops over contiguous arrays so that they
 * vectorise (proc/CMakeLists.txt builds them for the auto-vectoriser; on x86-64 also for AVX2
 * and AVX-512, picked at load time). Every output pixel depends on its own inputs only, so
 * the result does not depend on how rows are split between threads. Arrays are never NULL:
 * callers pass a row of zeros for a missing dark frame and sink rows for unwanted outputs, so
 * that the loops have no branches. */
#pragma once
#include <glib.h>

#include "proc/separation.h"
#include "proc/simd.h"

G_BEGIN_DECLS

/* Per set: what the common tail of every estimator needs. Disabled tests carry NAN
 * thresholds, whose comparisons are always false. */
typedef struct {
  guint n, m_frames;
  double b, m, h, inv1b;
  gboolean model;
  double read_var, gain;   /* noise model: var = read_var + gain * max (signal, 0) */
  double data_sigma;       /* without a model: one frame's noise (NAN: no noise tests) */
  double floor;            /* DARK when mean <= floor */
  double sat;              /* SATURATED when the raw maximum >= sat */
  double range_q;          /* LOW_MODULATION of maxmin/robust: range < range_q sigma_phase */
  double rayleigh;         /* LOW_MODULATION of sine: amplitude < rayleigh sigma_phase */
  double exceed_q;         /* DARK_EXCEEDS: dark - min > exceed_q sqrt(var(min) + var(dark)) */
  double dark_var;         /* var(dark): one frame's read noise (model) or data noise; 0 without
                              a dark frame */
  double data_exceed_var;  /* without a model: var(min) + var(dark); 0 when unknown (NAN noise) */
  double len_hi, len_lo;   /* frames behind each level (robust windows; 1 for maxmin) */
  gboolean dark;           /* a dark frame is subtracted (its read noise enters Lg) */
  gboolean extrema, sigmas; /* outputs wanted (else written to sink rows) */
  DsEstimator estimator;
  gboolean motion;          /* MOTION is judged (separation_motion.c) */
  double motion_kappa, motion_chi2;
  double data_var_phase;    /* without a model: one phase value's noise variance (NAN: unknown) */
} DsRowConsts;

/* One row's buffers, w elements each. The load step fills hi_raw, lo_raw, mean_raw (NAN when
 * unknown), rmax, bad; the estimator fills ld, lg, lev_hi, lev_lo (the levels whose noise
 * enters the sigmas), amp (sine) and mean; the tail writes the outputs. */
typedef struct {
  double *hi_raw, *lo_raw, *mean_raw, *rmax;
  double *ld, *lg, *lev_hi, *lev_lo, *amp, *mean;
  double *cs, *sn;              /* robust: harmonic, then window sums */
  double *sumsq;                /* robust with motion: sum of squares of the phase values */
  double *best_hi, *best_lo;    /* robust: window scores */
  guint32 *start_hi, *start_lo; /* robust: window starts */
  float *dark_zero;             /* zeros: the dark row when there is none */
  float *sink[5];               /* outputs nobody wants */
  guint8 *bad, *flags_zero;     /* zeros: column flags when there are none */
  guint8 *motion, *flags;       /* MOTION per pixel; it or-ed with the column flags */
} DsRowBuffers;
/* doubles per pixel DsRowBuffers needs */
#define DS_ROW_DOUBLES 21
void ds_row_buffers_init (DsRowBuffers *rb, double *scratch, gsize w);

/* Load steps: state of one row into hi_raw, lo_raw, mean_raw, rmax and bad. */
void ds_row_load_fast (const guint16 *mx, const guint16 *mn, const guint32 *sum, guint n,
                       DsRowBuffers *rb, gsize w);
void ds_row_load_float (const float *mx, const float *mn, const double *sum, const float *rawmax,
                        const guint8 *nonfinite, guint n, const float *dark, DsRowBuffers *rb,
                        gsize w);

/* The integer sine's fixed-point harmonic (separation_internal.h, cos64/sin64) as doubles
 * into rb->cs and rb->sn: sum / 2^bits, one rounding per pixel. */
void ds_row_harmonic_from_fix (const gint64 *c64, const gint64 *s64, guint bits, DsRowBuffers *rb,
                               gsize w);

/* Estimators. */
void ds_row_maxmin (const DsRowConsts *c, const float *dark, DsRowBuffers *rb, gsize w);
void ds_row_sine (const DsRowConsts *c, const double *cs, const double *sn, const float *dark,
                  DsRowBuffers *rb, gsize w);
/* MOTION into rb->motion (DS_MASK_MOTION or 0) from the phase values' sum of squares, their
 * sum (sum_or_mean x mean_scale is the raw mean), first harmonic (cs, sn) and largest value
 * (rb->hi_raw, for the noise model's variance). */
void ds_row_motion (const DsRowConsts *c, const double *sumsq, const double *sum_or_mean,
                    double mean_scale, const double *cs, const double *sn, const float *dark,
                    DsRowBuffers *rb, gsize w);
/* The fast maxmin row's mask: motion (rb->motion) or-ed in where the pixel is neither SATURATED
 * nor DARK, the counts corrected. */
void ds_row_or_motion (const guint8 *motion, guint8 *mk, gsize w, guint64 counts[DS_MASK_N_BITS + 1]);
/* rb->flags = column_flags | rb->motion; returns rb->flags. */
const guint8 *ds_row_motion_flags (DsRowBuffers *rb, const guint8 *column_flags, gsize w);

/* robust from N phase planes (plane k's row at planes16/planesf + k * plane_stride; one of the
 * two is NULL); also fills hi_raw, lo_raw and mean_raw from the planes (rmax is the caller's).
 * The tables come from ds_robust_tables, cos_k/sin_k are the phase angles. */
typedef struct {
  const double *cos_k, *sin_k, *c_hi, *s_hi, *c_lo, *s_lo;
  guint len_hi, len_lo;
} DsRobustTables;
void ds_row_robust (const DsRowConsts *c, const DsRobustTables *t, const guint16 *planes16,
                    const float *planesf, gsize plane_stride, const float *dark, DsRowBuffers *rb,
                    gsize w);

/* The common tail: mask bits, sigmas, outputs; a pixel whose inputs are not finite, or whose
 * outputs do not fit float32, is NONFINITE with all outputs 0. column_flags are or-ed into
 * the mask, their MOTION bit only where the pixel is neither SATURATED nor DARK (a clipped or
 * noise-floor sample says nothing about the pattern). Adds the mean signal of measured pixels to *mean_sum / *mean_count and the mask's
 * bits to counts. */
typedef struct {
  float *t, *g, *mx, *mn, *me, *st, *sg;
  guint8 *mk;
} DsRowOutputs;
void ds_row_tail (const DsRowConsts *c, DsRowBuffers *rb, const float *dark,
                  const guint8 *column_flags, const DsRowOutputs *out, gsize w, double *mean_sum,
                  guint64 *mean_count, guint64 counts[DS_MASK_N_BITS + 1]);

G_END_DECLS
