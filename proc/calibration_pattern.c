/* Sine or square stripes (calibration_pattern.h). */
#include "proc/calibration_pattern.h"
#include "proc/calibration_scatter.h"

/* how much worse than the square's fit the sine's may be and still be taken: within the noise
 * of two fits of the same profile, not a harmonic the square explains */
#define SINE_VS_SQUARE 1.5

DsPatternKind
ds_calibration_pattern_decide (DsPatternCheck *c)
{
  gboolean sine_fits = ds_calibration_shape_fits (c->sine_residual, c->noise);
  c->square_fits = ds_calibration_shape_fits (c->square_residual, c->noise);
  if (sine_fits && c->sine_residual <= SINE_VS_SQUARE * c->square_residual)
    return DS_PATTERN_SINE;
  /* a square whose misfit the sine does not beat stays square: a scattering reference shows so */
  return DS_PATTERN_SQUARE;
}
