/* The GPIO backends as the daemon's configuration names them: a chip (name, path, label or
 * number, as gpiod_chip_open_lookup takes it) and line offsets, over libgpiod v1. */
#pragma once
#include "drivers/gpio/gpio_illuminator.h"
#include "drivers/gpio/gpio_trigger.h"

G_BEGIN_DECLS

/* lines: "3,4,5,6" (one per stripe group); enable_line: offset or -1. Fails with
 * DS_ILLUMINATOR_ERROR: INVALID (list, offsets), DISCONNECTED (no such chip), BUSY (line
 * used by another consumer). */
DsIlluminator *ds_gpio_illuminator_open_from_config (const char *chip, const char *lines,
                                                     int enable_line, GError **error);
/* Fails with DS_TRIGGER_ERROR codes as above. */
DsTrigger *ds_gpio_trigger_open_from_config (const char *chip, int line, guint pulse_us,
                                             gboolean active_low, GError **error);

G_END_DECLS
