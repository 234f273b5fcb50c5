/* The GPIO backends as the daemon's configuration names them: a chip and line offsets. The chip
 * is a real one (name, path, label or number, as gpiod_chip_open_lookup takes it, over libgpiod
 * v1), or descatter-labsim's simulated chip as "labsim:/absolute/socket/path"
 * (gpio_lines_socket.h), which another process's camera can see. */
#pragma once
#include "drivers/gpio/gpio_illuminator.h"
#include "drivers/gpio/gpio_trigger.h"

G_BEGIN_DECLS

/* The line set for `chip` in either form. Errors as ds_gpio_lines_request (GIOError); a
 * "labsim:" chip without an absolute path fails G_IO_ERROR_INVALID_ARGUMENT. */
DsGpioLines *ds_gpio_lines_open (const char *chip, const guint *offsets, guint n_lines, const int *initial,
                                 const char *consumer, GError **error);

/* lines: "3,4,5,6" (one per stripe group); enable_line: offset or -1. Fails with
 * DS_ILLUMINATOR_ERROR: INVALID (list, offsets), DISCONNECTED (no such chip), BUSY (line
 * used by another consumer). */
DsIlluminator *ds_gpio_illuminator_open_from_config (const char *chip, const char *lines,
                                                     int enable_line, GError **error);
/* Fails with DS_TRIGGER_ERROR codes as above. */
DsTrigger *ds_gpio_trigger_open_from_config (const char *chip, int line, guint pulse_us,
                                             gboolean active_low, GError **error);

G_END_DECLS
