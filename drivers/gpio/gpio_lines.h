/* A set of GPIO output lines requested together, behind a small ops struct so the illuminator
 * and trigger backends run unchanged over a real chip (libgpiod v1) or the in-process
 * simulated chip (gpio_sim_chip.h). All lines of a set change in ONE bulk call.
 *
 * Threads: one thread at a time per set (the acquisition thread). Errors: GIOError codes from
 * errno (G_IO_ERROR_BUSY, G_IO_ERROR_NOT_FOUND...), messages name the chip and offsets; the
 * backends map them onto DsDeviceError. */
#pragma once
#include <gio/gio.h>

#include "drivers/core/device_error.h"

G_BEGIN_DECLS

#define DS_GPIO_MAX_LINES 64 /* libgpiod v1's bulk limit */

typedef struct {
  const char *name;        /* "gpiod", "sim" */
  /* values[i] for offsets[i], 0 or 1, all in one request. Non-blocking (one ioctl). */
  gboolean (*set_values) (gpointer impl, const int *values, GError **error);
  /* Reads back the lines' values in one request. */
  gboolean (*get_values) (gpointer impl, int *values, GError **error);
  /* Releases and requests the same lines again (after a failure). */
  gboolean (*reopen) (gpointer impl, GError **error);
  /* Releases the lines and frees. */
  void (*free) (gpointer impl);
} DsGpioLinesOps;

typedef struct {
  const DsGpioLinesOps *ops;
  gpointer impl;
  guint n_lines;
  guint offsets[DS_GPIO_MAX_LINES];
  char *chip;              /* as given, for messages */
} DsGpioLines;

/* The libgpiod implementation: chip by name ("gpiochip0"), path ("/dev/gpiochip0"), label or
 * number (gpiod_chip_open_lookup); the lines are requested as outputs with initial values
 * (NULL: all 0). Fails G_IO_ERROR_NOT_FOUND (no chip, offset beyond the chip),
 * G_IO_ERROR_BUSY (line used by someone else), G_IO_ERROR_INVALID_ARGUMENT. */
DsGpioLines *ds_gpio_lines_request (const char *chip, const guint *offsets, guint n_lines,
                                    const int *initial, const char *consumer, GError **error);

gboolean ds_gpio_lines_set (DsGpioLines *lines, const int *values, GError **error);
gboolean ds_gpio_lines_get (DsGpioLines *lines, int *values, GError **error);
gboolean ds_gpio_lines_reopen (DsGpioLines *lines, GError **error);
void ds_gpio_lines_free (DsGpioLines *lines); /* NULL-safe */
G_DEFINE_AUTOPTR_CLEANUP_FUNC (DsGpioLines, ds_gpio_lines_free)

/* For implementations: a set with the common fields filled (offsets checked for duplicates:
 * G_IO_ERROR_INVALID_ARGUMENT naming the offset). */
DsGpioLines *ds_gpio_lines_new (const DsGpioLinesOps *ops, gpointer impl, const char *chip,
                                const guint *offsets, guint n_lines, GError **error);

/* "3,4,5,6" -> offsets. Fails G_IO_ERROR_INVALID_ARGUMENT naming the element. */
gboolean ds_gpio_parse_offsets (const char *list, guint *offsets, guint *n_lines, GError **error);

/* A line-layer GIOError as the device interfaces report it: BUSY, INVALID, DISCONNECTED (chip
 * or lines gone), TIMEOUT (a socket chip that did not answer) or FAULT (any other failure). */
DsDeviceError ds_gpio_device_error_code (const GError *io_error);
/* Moves a line-layer error into `domain` with that code, keeping the message. */
void ds_gpio_propagate_error (GError **dest, GError *io_error, GQuark domain);

G_END_DECLS
