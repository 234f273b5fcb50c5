/* The GPIO trigger: one output line wired to the camera's trigger input, pulsed for a
 * configurable width and polarity (active-high: idle low, pulse high; active-low: the
 * reverse). The line idles at its inactive level from the moment it is requested.
 * Threads: the acquisition thread only. fire blocks for the pulse width. */
#pragma once
#include "drivers/core/trigger.h"
#include "drivers/gpio/gpio_lines.h"

G_BEGIN_DECLS

/* Takes ownership of line (a set of exactly one line, also on failure). pulse_us: 1..1000000.
 * Fails INVALID. */
DsTrigger *ds_gpio_trigger_new (DsGpioLines *line, guint pulse_us, gboolean active_low, GError **error);

G_END_DECLS
