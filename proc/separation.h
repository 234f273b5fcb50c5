/* Phase-set separation: parameters, the streaming accumulator and its result.
 *
 * A phase set is N frames, frame k lit by the stripe pattern shifted by k/N of a period,
 * optionally M frames per phase (averaged), optionally with a dark frame (illuminator off).
 * Frames are folded in one at a time as they arrive; memory does not grow with N for the
 * maxmin and sine estimators. See docs/estimators.md for the physics and the choices.
 *
 * Threading: a DsPhaseSet is used by one thread at a time (the acquisition thread in the
 * daemon); none of these functions blocks on anything but memory and CPU. */
#pragma once
#include <glib.h>

#include "proc/image.h"

G_BEGIN_DECLS

typedef enum {
  DS_ESTIMATOR_MAXMIN = 0, /* Nayar 2006 / Tanaka 2013: Ld = (max-min)/(1-b) */
  DS_ESTIMATOR_SINE = 1,   /* N-step first harmonic, N >= 3 */
  DS_ESTIMATOR_ROBUST = 2, /* order statistics that cut max/min's noise bias */
} DsEstimator;

const char *ds_estimator_name (DsEstimator estimator);
gboolean ds_estimator_from_name (const char *name, DsEstimator *out);

typedef enum {
  DS_PATTERN_SQUARE = 0,
  DS_PATTERN_SINE = 1,
} DsPatternKind;

/* Quality mask bits (u8, one per pixel). Stable: documented in docs/estimators.md and sent to
 * clients as is. */
typedef enum {
  DS_MASK_SATURATED = 1 << 0,      /* at or above the saturation level in some frame */
  DS_MASK_DARK = 1 << 1,           /* mean signal below the noise floor */
  DS_MASK_LOW_MODULATION = 1 << 2, /* modulation not distinguishable from noise */
  DS_MASK_NONFINITE = 1 << 3,      /* NaN or Inf in some (float) input frame */
  DS_MASK_NEGATIVE = 1 << 4,       /* a component came out below zero (noise); left unclipped */
  DS_MASK_DARK_EXCEEDS = 1 << 5,   /* the dark frame is brighter than some phase frame */
} DsMaskBit;
#define DS_MASK_N_BITS 6

/* Stable lower-case name of mask bit `bit` (0 = "saturated" ...), as used in JSON metadata,
 * and a one-line meaning for legends; NULL outside 0..DS_MASK_N_BITS-1. The one list: clients
 * and files use these names. */
const char *ds_mask_bit_name (guint bit);
const char *ds_mask_bit_meaning (guint bit);

typedef struct {
  DsEstimator estimator;
  DsPatternKind pattern;
  guint n_phases;          /* N: >= 2 (>= 3 for sine) */
  double duty;             /* a: lit fraction of a period, (0, 1) */
  double black_level;      /* b: off-stripe leakage relative to on, [0, 1); refused when 1/(1-b)
                              exceeds DS_MAX_CONDITION */
  double harmonic_gain;    /* h for sine; 0 = the theoretical value for pattern, duty, black */
  double saturation_level; /* DN at or above which a raw sample counts as saturated;
                              0 = 2^bit_depth - 1 of the first frame (never for float input) */
  double system_gain;      /* K in DN per electron; 0 = no noise model (no uncertainty output) */
  double read_noise_dn;    /* temporal dark noise in DN (EMVA 1288 sigma_d * K) */
  gboolean keep_extrema;   /* also output max, min and mean */
} DsSeparationParams;

/* Largest amplification of noise an estimator may apply: 1/(1-b) for the black level, and
 * 1/m and 1/h (pattern mean, first-harmonic gain) for the scattered and sine outputs. */
#define DS_MAX_CONDITION 100.0
/* Largest N (and largest M): 32-bit integer sums stay exact for 16-bit samples up to here. */
#define DS_MAX_PHASES 65535u

/* The defaults that reproduce the ICCP 2013 authors' scripts: maxmin, square, a = 1/2, b = 0. */
void ds_separation_params_init (DsSeparationParams *params, guint n_phases);
/* Checks ranges and conditioning; the error names the parameter and the allowed range. */
gboolean ds_separation_params_validate (const DsSeparationParams *params, GError **error);

typedef struct {
  guint n_phases;
  guint frames_per_phase;   /* M (the smallest over phases if they differ) */
  DsEstimator estimator;
  double duty, black_level;
  double pattern_mean;      /* m used by the estimator */
  double harmonic_gain;     /* h used by the estimator (sine) */
  gboolean dark_subtracted;
  guint64 flagged[DS_MASK_N_BITS]; /* pixels carrying each mask bit */
  guint64 valid_pixels;     /* pixels with no bit set */
  double noise_dn;          /* per-set noise estimate (DN, one frame): from the model if given,
                               otherwise from the data; NAN if neither is possible */
  double saturation_level;  /* the level applied (DN); NAN when none applies (float input) */
} DsSeparationMeta;

typedef struct {
  DsImage *transmissive;   /* f32, Ld */
  DsImage *scattered;      /* f32, Lg */
  DsImage *mask;           /* u8, DsMaskBit flags */
  DsImage *max, *min, *mean;            /* f32, dark-subtracted; NULL unless keep_extrema */
  DsImage *sigma_transmissive;          /* f32 1-sigma per pixel; NULL without a noise model */
  DsImage *sigma_scattered;
  DsSeparationMeta meta;
} DsSeparation;

void ds_separation_free (DsSeparation *sep);
G_DEFINE_AUTOPTR_CLEANUP_FUNC (DsSeparation, ds_separation_free)

typedef struct DsPhaseSet DsPhaseSet;

/* Allocates accumulators for width x height frames. Fails on invalid params. */
DsPhaseSet *ds_phase_set_new (const DsSeparationParams *params, guint width, guint height,
                              GError **error);
void ds_phase_set_free (DsPhaseSet *set);
G_DEFINE_AUTOPTR_CLEANUP_FUNC (DsPhaseSet, ds_phase_set_free)

/* Dark frame (illuminator off), subtracted in signed arithmetic. Optional; set before finalize
 * (before or after the frames). It must have the set's size and the frames' sample type.
 * The set keeps a copy across ds_phase_set_reset; dark NULL forgets it. */
gboolean ds_phase_set_set_dark (DsPhaseSet *set, const DsImage *dark, GError **error);

/* Folds one frame lit with phase k (0 <= k < N). Frames of one phase arrive consecutively
 * (M averages); a phase once left cannot be revisited. Frames must all have the set's size
 * and one sample type/bit depth. On error nothing is folded.
 * Averaging is decided by the first phase: if it receives a second frame, every phase's frames
 * are summed and the phase mean folded when the phase changes (phases may then differ in M);
 * otherwise each frame is folded at once and a later phase may not take a second frame. */
gboolean ds_phase_set_accumulate (DsPhaseSet *set, guint phase, const DsImage *frame,
                                  GError **error);

/* Computes the result; every phase must have at least one frame. The set can then be reset. */
DsSeparation *ds_phase_set_finalize (DsPhaseSet *set, GError **error);
/* As ds_phase_set_finalize, but takes ownership of `reuse` (a previous result nobody needs any
 * more; may be NULL) and writes into its planes where they have the right shape, sparing the
 * allocation and first-touch page faults of new ones (for continuous acquisition at a high
 * rate). `reuse` is freed in every case, also on error. */
DsSeparation *ds_phase_set_finalize_reusing (DsPhaseSet *set, DsSeparation *reuse, GError **error);
/* Forgets all frames (keeps dark, params and memory) for the next set. */
void ds_phase_set_reset (DsPhaseSet *set);

guint ds_phase_set_frames_folded (const DsPhaseSet *set);

G_END_DECLS
