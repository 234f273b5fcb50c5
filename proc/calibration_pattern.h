/* Sine or square stripes? (calibration.h) Both models are fitted to the reference's period
 * profile: a pure sinusoid (a mean and the first harmonic: the contrast is the only shape
 * parameter, as blur and pixel integration leave a sine a sine) and a square of duty a with a
 * black level and a Gaussian edge blur. The stripes are taken as sine when the sinusoid fits as
 * closely as a clear reference must fit (the same bound as the scattering check's shape test,
 * calibration_scatter.h: rms residual <= max(0.5 %, 5 x the profile's noise) of the stripe
 * contrast) and no worse than 1.5 x the blurred square: the profile then holds no harmonic
 * above the first that the data can show. A square blurred that far is indistinguishable from
 * a sine, and the sine estimator is what its separation should use (square_fits says so).
 * Pure functions, any thread. */
#pragma once
#include <glib.h>

#include "proc/separation.h"

G_BEGIN_DECLS

typedef struct {
  gboolean detected;          /* the pattern was decided from the profile (not given as override) */
  DsPatternKind expected;     /* what the configuration (or the folder's sidecar) said */
  double sine_residual;       /* rms residual of the sinusoid's fit over the profile's range */
  double square_residual;     /* same for the blurred square */
  double square_blur_px;      /* the blur the square's fit needed */
  double noise;               /* the profile's standard error over its range */
  gboolean square_fits;       /* the blurred square fits as well: indistinguishable from a sine */
} DsPatternCheck;

/* The pattern the residuals show (sets square_fits). */
DsPatternKind ds_calibration_pattern_decide (DsPatternCheck *check);

G_END_DECLS
