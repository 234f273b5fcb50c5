/* The GPIO illuminator: L output lines, line j driving stripe group j of every period (the
 * projector repeats the L groups across the field), plus an optional enable line.
 *
 * Mapping (docs/drivers.md, "GPIO illuminator"): group j is centred at j/L of the period;
 * phase k of N lights group j iff u = (j/L - k/N) wrapped to [-1/2, 1/2) satisfies
 * -duty/2 <= u < duty/2. L must be a multiple of N, so phase k is phase 0 shifted by k*L/N
 * lines, and the pattern must have at least one lit and one dark line. The convention is the
 * one of proc/stripe_phase.h: phase k of N is centred at x = k P / N.
 *
 * All stripe lines change in ONE bulk call; the enable line (if any) goes high after the
 * stripes are set and low when the illuminator is off (with every stripe line low too).
 * set_phase reads the lines back and fails FAULT if one differs. GPIO has no settle time and no
 * sensors: timeout_ms is not needed, ready is always TRUE, temperature NAN. The stripe period is
 * the optics': the first set_pattern's (the configuration's) is kept, another is refused
 * UNSUPPORTED (status: period_adjustable FALSE, range unknown).
 * Threads: the acquisition thread only. */
#pragma once
#include "drivers/core/illuminator.h"
#include "drivers/gpio/gpio_lines.h"

G_BEGIN_DECLS

/* Takes ownership of both line sets (also on failure). enable: NULL or a set of one line.
 * Sets every line low. Fails INVALID (enable set of more than one line) or as a failed write. */
DsIlluminator *ds_gpio_illuminator_new (DsGpioLines *stripes, DsGpioLines *enable, GError **error);

/* The mapping above: values[j] for j < n_lines. Fails INVALID (n_lines not a multiple of
 * n_phases, fewer than 2 phases, duty leaving no lit or no dark line, phase >= n_phases). */
gboolean ds_gpio_stripe_values (guint n_lines, guint n_phases, double duty, guint phase,
                                int *values, GError **error);

G_END_DECLS
