/* Calibration of the stripe illuminator as the camera sees it, from a phase set of a reference
 * with little scattering (a clear sample, or none): the stripe period, where phase 0 falls,
 * the duty a, the black level b, the first-harmonic gain h the sine estimator needs, and the
 * edge blur that explains h (docs/estimators.md, "Calibration").
 *
 * Frames are added one at a time (several per phase are averaged); memory is N phase planes
 * of doubles. Used by `descatterctl calibrate` offline and by the daemon's calibrate command.
 * A DsCalibrator is used by one thread at a time; it blocks on nothing but memory and CPU. */
#pragma once
#include <glib.h>

#include "proc/calibration_pattern.h"
#include "proc/calibration_scatter.h"
#include "proc/image.h"
#include "proc/separation.h"

G_BEGIN_DECLS

typedef struct {
  DsPatternKind pattern;      /* what the illuminator is configured to project (square unless
                                 known to be sine); the profile decides (calibration_pattern.h) */
  gboolean pattern_forced;    /* take pattern as it is, without looking (an explicit override) */
  double period_px;           /* known period; 0 = measure it */
  gboolean period_estimated;  /* period_px is a detector's estimate: refine it on the phase set
                                 (calibration_period.h), as a period measured here is */
  gboolean phase_offset_known;
  double phase_offset_cycles;
  double saturation_level;    /* DN at or above which samples are clipped: those pixels are left
                                 out; 0 = 2^bit_depth - 1 of the frames (none for float) */
  double pixel_aperture;      /* for the blur model; 0 = 1 pixel */
  double black_level;         /* sine stripes at one period: the black level taken as known (the
                                 configured one), since the profile cannot tell it from blur
                                 (calibration_sine.h); 0 unless known */
} DsCalibrationHints;

void ds_calibration_hints_init (DsCalibrationHints *hints);

typedef struct {
  guint n_phases, frames_per_phase;
  DsPatternKind pattern;      /* what the stripes show (or the forced hint) */
  DsPatternCheck pattern_check; /* both fits, and what was expected */
  double period_px;           /* measured (or the hint) */
  gboolean period_measured;
  double phase_offset_cycles; /* phase k lights stripes centred at (j + k/N + offset) P */
  double offset_spread;       /* rms scatter of the per-phase offsets, cycles */
  double duty;                /* a (square stripes; 0.5 for sine) */
  double black_level;         /* b: the illuminator's light where it is off, relative to where it
                                 is fully on (before blur) */
  gboolean black_level_measured; /* square: from the profile's shape; sine: only from two
                                 periods (calibration_sine.h), else it is hints->black_level */
  double contrast;            /* the first harmonic over the mean, c = h / m, as the reference
                                 shows it at period_px (blur, pixel, sampling and b all in it) */
  double second_period_px;    /* sine: the second period b was told at (0: none) */
  double second_contrast;     /* and the contrast there */
  double harmonic_gain;       /* h as the N-step first harmonic sees this rig (with b, blur,
                                 pixel integration and sampling): the sine estimator's gain */
  double harmonic_gain_theory;/* h for sharp stripes with this a and b */
  double edge_blur_px;        /* Gaussian sigma that makes the model's h match; 0 if the stripes
                                 are as sharp as pixels show (sine: from two periods, the pixel's
                                 own aperture taken out; 0 at one period) */
  guint64 pixels_used;        /* lit, unsaturated, finite pixels the numbers come from */
  double lit_level_dn;        /* a fully lit pixel's level, DN above the dark frame (a pixel's
                                 mean over the phases over the pattern's mean, the
                                 DS_LIT_LEVEL_QUANTILE quantile of the pixels, proc/lit_level.h); without a
                                 dark frame it holds the sensor's offset too */
  double open_field_dn_per_ms;/* lit_level_dn per ms of exposure at 0 dB gain, where the set's
                                 exposure and gain are known and it had a dark frame (the daemon's
                                 calibrate); 0 = not measured */
  char open_field_pixel_format[32]; /* the camera's pixel format those DN are in ("Mono8" holds a
                                 12-bit sensor's top 8 bits, "Mono16" all 12: the same light reads
                                 16 times apart); "" = not said */
  DsScatterCheck scatter;     /* does the reference scatter? (calibration_scatter.h): then b and h
                                 hold scattered light and are not to be used */
} DsCalibration;

/* The warning to print when the reference scatters (NULL when it does not seem to): what was
 * seen, that b and h are not to be trusted, and to calibrate on a clear reference. */
char *ds_calibration_scatter_warning (const DsCalibration *cal);

/* When the stripes are not what was expected (configured): what the fits showed and the remedy
 * (pattern=...); NULL when they agree or the pattern was forced. */
char *ds_calibration_pattern_notice (const DsCalibration *cal);

/* Sine stripes at one period: that the black level is assumed, not measured, and how to measure
 * it; NULL otherwise. */
char *ds_calibration_black_level_note (const DsCalibration *cal);

/* Sine stripes whose black level one period could not tell from their blur: the calibration
 * wants a second set of the same reference at twice the period (ds_calibration_add_second_period). */
gboolean ds_calibration_wants_second_period (const DsCalibration *cal);

/* The hints for that second set, from the first set's: the illuminator drew second_period_px
 * (about twice what the first set measured: refined on the set), sine stripes taken as such. */
void ds_calibration_hints_second_period (DsCalibrationHints *hints, double second_period_px);

/* Sine stripes: the black level and the harmonic gain at cal's period told apart with the
 * contrast the same reference shows at another period (second: a calibration of it,
 * calibration_sine.h). Fails INVALID_ARGUMENT when cal is not sine or the periods are too
 * close (a ratio under 1.25) or second shows no contrast. */
gboolean ds_calibration_add_second_period (DsCalibration *cal, const DsCalibration *second, double pixel_aperture,
                                           GError **error);

typedef struct DsCalibrator DsCalibrator;

/* n_phases >= 3 (the harmonic needs three). Fails INVALID_ARGUMENT, TOO_LARGE. */
DsCalibrator *ds_calibrator_new (guint n_phases, guint width, guint height, GError **error);
void ds_calibrator_free (DsCalibrator *cal);
G_DEFINE_AUTOPTR_CLEANUP_FUNC (DsCalibrator, ds_calibrator_free)

/* A frame lit with phase k; frames of one type and size (SIZE_MISMATCH names them). */
gboolean ds_calibrator_add (DsCalibrator *cal, guint phase, const DsImage *frame, GError **error);
/* The illuminator-off frame, subtracted from every phase. */
gboolean ds_calibrator_set_dark (DsCalibrator *cal, const DsImage *dark, GError **error);

/* Measures. Fails NOT_ENOUGH_PHASES (a phase without frames), EMPTY (no stripes found: give the
 * period; or no lit, unsaturated pixel), naming what is missing. */
gboolean ds_calibrator_finish (DsCalibrator *cal, const DsCalibrationHints *hints, DsCalibration *out,
                               GError **error);

G_END_DECLS
