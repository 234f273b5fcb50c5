/* Phase-set separation: parameters, the streaming accumulator and its result.
 *
 * A phase set is N frames, frame k lit by the stripe pattern shifted by k/N of a period,
 * optionally M frames per phase (averaged), optionally with a dark frame (illuminator off).
 * Frames are folded in one at a time as they arrive; memory does not grow with N for the
 * maxmin and sine estimators. See docs/estimators.md for the physics and the choices.
 *
 * Threading: a DsPhaseSet is used by one thread at a time (the acquisition thread in the
 * daemon); none of these functions blocks on anything but memory and CPU. A set may split its
 * own per-pixel work over worker threads it owns (params.threads); results are bit-identical
 * for any thread count. */
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
  DS_MASK_DARK_EXCEEDS = 1 << 5,   /* the dark frame is brighter than the darkest phase beyond
                                      noise (1e-3 false-alarm rate) */
  DS_MASK_UNDERSAMPLED = 1 << 6,   /* no phase lit this pixel fully, or none left it fully dark
                                      (maxmin, robust: aN or (1-a)N too small for the pixel's
                                      aperture and the edge blur); the value is biased */
  DS_MASK_MOTION = 1 << 7,         /* the N phase samples depart from a still scene under the
                                      pattern by more than the noise allows (1e-3 false-alarm
                                      rate): the scene moved or changed during the set */
} DsMaskBit;
#define DS_MASK_N_BITS 8

/* Stable lower-case name of mask bit `bit` (0 = "saturated" ... 7 = "motion"), as used
 * in JSON metadata, and a one-line meaning for legends; NULL outside 0..DS_MASK_N_BITS-1. The
 * one list: clients and files use these names. */
const char *ds_mask_bit_name (guint bit);
const char *ds_mask_bit_meaning (guint bit);

/* Where the stripes fall on the sensor, as far as known. Stripes vary along x; phase k of N
 * lights stripes centred at x = (j + k/N + phase_offset_cycles) P, x the pixel centre's column
 * (the convention of proc/stripe_phase.h and the simulator). */
typedef struct {
  double period_px;          /* P; 0 = unknown: only aN >= 1 and (1-a)N >= 1 can be checked */
  double edge_blur_px;       /* Gaussian sigma of the stripe edges on the sensor (projector
                                defocus, lens), in pixels */
  gboolean edge_blur_known;  /* edge_blur_px was measured or calibrated (0 then means sharp);
                                FALSE: robust keeps at least one phase of margin per side,
                                the sampling check takes edge_blur_px as it is */
  double pixel_aperture;     /* sensitive width of a pixel along x, in pixels: 1 = full fill
                                factor (the default), 0 = point sampling */
  gboolean phase_offset_known;
  double phase_offset_cycles; /* where phase 0 falls, [0, 1); when unknown and needed (to flag
                                 undersampled pixels) it is measured on the first frame */
} DsStripeGeometry;

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
  guint threads;           /* threads for the per-pixel work, the caller's included; 0 = one per
                              processor, at most DS_MAX_THREADS. Small frames use one. */
  DsStripeGeometry geometry; /* for the sampling precondition and robust's windows */
  gboolean detect_motion;  /* flag DS_MASK_MOTION (N >= 4; docs/estimators.md, "MOTION"). Costs
                              maxmin and sine a plane of sums of squares (maxmin also the first
                              harmonic and the sum), robust nothing kept; off by default */
} DsSeparationParams;

#define DS_MAX_THREADS 16u

/* Largest amplification of noise an estimator may apply: 1/(1-b) for the black level, and
 * 1/m and 1/h (pattern mean, first-harmonic gain) for the scattered and sine outputs. */
#define DS_MAX_CONDITION 100.0
/* Largest N (and largest M): 32-bit integer sums stay exact for 16-bit samples up to here. */
#define DS_MAX_PHASES 65535u

/* The defaults that reproduce the ICCP 2013 authors' scripts: maxmin, square, a = 1/2, b = 0. */
void ds_separation_params_init (DsSeparationParams *params, guint n_phases);
/* Checks ranges, conditioning and the sampling precondition (ds_separation_check_sampling);
 * the error names the parameter and the allowed range or the failed condition. */
gboolean ds_separation_params_validate (const DsSeparationParams *params, GError **error);

/* A pixel counts as fully lit (dark) in a phase when the pattern it integrates is within this
 * fraction of the lit (dark) level. */
#define DS_SAMPLING_TOLERANCE 0.01

/* What the pattern sampling does to an estimator, noise aside (docs/estimators.md, "Sampling
 * precondition"). maxmin and robust assume every pixel is fully lit in some phase and fully
 * dark in another: with sharp stripes and point pixels aN >= 1 and (1-a)N >= 1; a pixel of
 * aperture w under edge blur sigma needs the stripe to overlap it by e = w + 2 z sigma
 * (z = 2.576: the blurred edge within DS_SAMPLING_TOLERANCE), so (a - e/P) N >= 1 and
 * (1 - a - e/P) N >= 1 for every pixel, and at some positions in the period for some. */
typedef struct {
  gboolean applies;          /* maxmin or robust on square stripes: the precondition matters */
  double lit_phases;         /* (a - e/P) N, or aN without a period */
  double unlit_phases;       /* (1 - a - e/P) N, or (1 - a) N */
  double affected_fraction;  /* share of pixel positions across a period that are undersampled
                                (never fully lit or never fully dark in the phases the estimator
                                uses); NAN without a period */
  guint robust_lit_window;   /* phases robust averages for the lit and the unlit level */
  guint robust_unlit_window;
  /* The estimator's systematic error over pixel positions across a period, noise-free, for a
   * pixel with Ld > 0 and Lg = 0, relative to Ld; NAN without a period. sine's comes from its
   * harmonic gain h against the blurred, pixel-integrated and sampled pattern. */
  double ld_error_mean, ld_error_worst;  /* (estimated Ld - Ld) / Ld; worst = largest |.| */
  double lg_error_mean, lg_error_worst;  /* estimated Lg / Ld */
  char refusal[256];         /* why the configuration is refused; "" when it is not */
  char warning[256];         /* estimator/pattern mismatch (maxmin or robust on sine stripes) */
} DsSamplingCheck;

/* Fills *out (always) and returns FALSE with DS_PROC_ERROR_PRECONDITION when a separation
 * with these parameters must be refused: without a period, maxmin or robust with aN < 1 or
 * (1-a)N < 1; with a period, when every pixel position is undersampled. When only some are,
 * it succeeds, and a phase set flags them DS_MASK_UNDERSAMPLED. The params must be otherwise
 * valid (ranges). Pure function, any thread. */
gboolean ds_separation_check_sampling (const DsSeparationParams *params, DsSamplingCheck *out,
                                       GError **error);

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
  double phase_offset_cycles; /* offset used to flag undersampled pixels; NAN if none was needed */
  gboolean motion_checked;  /* DS_MASK_MOTION was computed (detect_motion, N >= 4, a noise
                               estimate): a 0 count then means no motion seen */
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

/* An empty result (no planes) for ds_phase_set_finalize_into. */
DsSeparation *ds_separation_new (void);
/* Frees the planes (views: only the DsImage, see ds_image_new_view) and the result. */
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
 * and one sample type/bit depth. On error nothing is folded. The frame is only read, and not
 * after this returns: it may be a view of a buffer the caller does not own (ds_image_view_init,
 * ds_pixfmt_view: a camera buffer), folded without a copy.
 * Averaging is decided by the first phase: if it receives a second frame, every phase's frames
 * are summed and the phase mean folded when the phase changes (phases may then differ in M);
 * otherwise each frame is folded at once and a later phase may not take a second frame. */
gboolean ds_phase_set_accumulate (DsPhaseSet *set, guint phase, const DsImage *frame,
                                  GError **error);
/* How many of the set's threads (params.threads) the following ds_phase_set_accumulate calls
 * use, the caller's included; 0 (the default): all. Folding is per pixel, so the result is the
 * same bit for bit with any number. A caller folding while the same cores receive the next
 * frame (descatterd) folds on one, leaving the others to the transfer, and uses all for the
 * last frame, which nothing overlaps. */
void ds_phase_set_set_fold_threads (DsPhaseSet *set, guint threads);
/* The same for the finalize (every ds_phase_set_finalize* call, and the finalize of
 * ds_phase_set_accumulate_finalize_into); 0 (the default): all. The result, its flags and
 * counts are the same bit for bit with any number. descatterd finalizes on one thread when the
 * next set's first frame is being acquired meanwhile (continuous mode). */
void ds_phase_set_set_finalize_threads (DsPhaseSet *set, guint threads);

/* Computes the result; every phase must have at least one frame. The set can then be reset. */
DsSeparation *ds_phase_set_finalize (DsPhaseSet *set, GError **error);
/* As ds_phase_set_finalize, into `sep`, which the caller owns and keeps (a pool of results):
 * planes it already has are written in place and must have the set's size and the plane's
 * type (f32, mask u8), else INVALID_ARGUMENT names the plane and nothing is written; missing
 * planes are allocated; planes this configuration does not produce (max/min/mean without
 * keep_extrema, sigmas without a noise model) are freed, so none is left stale. A plane may
 * be a view over memory the caller owns (ds_image_new_view). meta is overwritten. On other
 * errors the planes' contents are unspecified. */
gboolean ds_phase_set_finalize_into (DsPhaseSet *set, DsSeparation *sep, GError **error);
/* As ds_phase_set_finalize, but takes ownership of `reuse` (a previous result nobody needs any
 * more; may be NULL) and writes into its planes where they have the right shape, sparing the
 * allocation and first-touch page faults of new ones (for continuous acquisition at a high
 * rate). `reuse` is freed in every case, also on error. */
DsSeparation *ds_phase_set_finalize_reusing (DsPhaseSet *set, DsSeparation *reuse, GError **error);
/* ds_phase_set_accumulate of `frame` followed by ds_phase_set_finalize_into `sep`, for a caller
 * that knows the frame is its set's last one (descatterd). Where the configuration allows
 * (maxmin on u8/u16 frames, one frame per phase, no noise model, no extrema kept) and the
 * frame completes the set, the frame is folded on the finalize's single pass over the pixels
 * instead of a pass of its own; the set, the result and every flag and count are the same as
 * the two calls give, bit for bit. *folded (may be NULL) says whether the frame was folded:
 * on a frame error nothing is; when only the finalize fails (a plane of the wrong shape, a
 * phase without frames) the frame is folded and the error is the finalize's. */
gboolean ds_phase_set_accumulate_finalize_into (DsPhaseSet *set, guint phase, const DsImage *frame,
                                                DsSeparation *sep, gboolean *folded, GError **error);
/* Forgets all frames (keeps dark, params and memory) for the next set. */
void ds_phase_set_reset (DsPhaseSet *set);

guint ds_phase_set_frames_folded (const DsPhaseSet *set);

G_END_DECLS
