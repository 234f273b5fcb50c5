/* `descatterctl calibrate`'s configuration lines for a reference's phase sets at two periods,
 * for tests that include daemon/operating/pattern_check.h (whose DsPatternCheck is not the
 * calibrator's). */
#pragma once
#include "proc/image.h"

/* phases[0..n) at period_px, second[0..n) at second_period_px (the same reference), one dark
 * frame; aborts on a calibration error. Returns the [illuminator] lines; *contrast gets the first
 * period's contrast. */
char *calibrate_lines (DsImage *const *phases, DsImage *const *second, guint n, const DsImage *dark,
                       double second_period_px, double *contrast);
