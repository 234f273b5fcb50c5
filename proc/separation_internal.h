/* Private to proc/separation_*.c: the phase set's state, shared by the accumulate and the
 * finalize halves. Not installed, not for other concerns. */
#pragma once
#include <glib.h>

#include "proc/separation.h"

G_BEGIN_DECLS

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

  /* Integer input, one frame per phase (the fast path): raw extrema, exact sum. */
  guint16 *max16, *min16;
  guint32 *sum32;          /* NULL when nothing needs the mean (maxmin without extrema) */
  /* Float input, or averaging: extrema of phase means, sum of phase means. */
  float *maxf, *minf;
  double *sumd;
  float *rawmax;           /* averaging only: largest raw sample (saturation) */
  double *psum;            /* averaging only: running sum of the current phase */
  guint8 *nonfinite;       /* float input only: some sample was NaN or Inf */
  double *cos_sum, *sin_sum; /* sine: first harmonic of the phase means */
  float *phase_means;      /* robust: N planes of phase means */
  gsize alloc_npix;        /* guards against reuse with another layout */

  float *dark;             /* dark frame as float, NULL if none */
  DsSampleType dark_type;
  guint dark_bit_depth;

  double data_noise_dn;    /* noise of one raw frame estimated from the first frame; NAN */
  double range_quantile;   /* 0.999 quantile of the range of N unit normals */
};

/* Averaging: folds the last phase's mean (finalize calls it once; idempotent). */
void ds_phase_set_fold_pending (DsPhaseSet *set);

/* Noise helpers (separation_noise.c). */
/* Robust sigma of one frame from the median absolute second difference along y (the stripes
 * vary along x only, so the pattern cancels); NAN if the frame has fewer than 3 rows. */
double ds_separation_frame_noise (const DsImage *frame);
/* Upper p-quantile of the range (max - min) of n independent unit normals, n >= 2. */
double ds_separation_range_quantile (guint n, double p);

/* Row kernels (separation_kernels.c). */
#define DS_DECLARE_INT_KERNELS(T, NAME)                                                           \
  void ds_fold_first_##NAME (const T *in, guint16 *mx, guint16 *mn, guint32 *sum, gsize w);      \
  void ds_fold_extrema_##NAME (const T *in, guint16 *mx, guint16 *mn, gsize w);                  \
  void ds_fold_extrema_sum_##NAME (const T *in, guint16 *mx, guint16 *mn, guint32 *sum, gsize w);\
  void ds_fold_harmonic_##NAME (const T *in, double c, double s, double *cs, double *sn,         \
                                gsize w);                                                        \
  void ds_copy_plane_##NAME (const T *in, float *out, gsize w);
DS_DECLARE_INT_KERNELS (guint8, u8)
DS_DECLARE_INT_KERNELS (guint16, u16)

/* maxmin on the integer fast path, no noise model: thresholds prepared once per set
 * (a disabled test carries +-INFINITY so that its comparison is always false). */
typedef struct {
  float inv1b, b, invm, m;
  float sat;     /* SATURATED when max >= sat */
  float floor;   /* DARK when the model mean <= floor */
  float lowmod;  /* LOW_MODULATION when max - min < lowmod */
} DsMaxminFast;
void ds_maxmin_fast_row (const guint16 *hi, const guint16 *lo, const float *dark, float *t,
                         float *g, guint8 *mk, gsize w, const DsMaxminFast *k);
/* counts[0] += pixels with no bit; counts[1 + bit] += pixels with that bit. */
void ds_count_mask_row (const guint8 *mk, gsize w, guint64 counts[DS_MASK_N_BITS + 1]);

G_END_DECLS
