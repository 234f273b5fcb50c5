/* A detected stripe period refined on the whole phase set (calibration.h). The profile is
 * binned by position in the period, so a period off by 0.1 % over 20 periods (0.02 cycles at the
 * far edge) smears it: neither a sinusoid nor a blurred square fits, and the scattering check
 * cries wolf. Each column's first-harmonic phase over the N phases is where the stripes are
 * (sine or square alike); it advances by x / P, so the slope of its drift against x / P_estimate
 * corrects P. Pure function, any thread; CPU only (one pass over the N planes). */
#pragma once
#include <glib.h>

#include "proc/image.h"

G_BEGIN_DECLS

/* means: n float planes, phase k's stripes at (j + k/n + offset) P. Returns the refined period,
 * or period when the columns do not show enough stripes to tell (or the correction is more than
 * 2 %: then the estimate was not near enough to refine). */
double ds_calibration_period_refine (DsImage *const *means, guint n, double period);

G_END_DECLS
