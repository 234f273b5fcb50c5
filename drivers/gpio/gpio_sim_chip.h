/* A simulated GPIO chip, in-process: the DsGpioLines implementation the tests (and machines
 * without /dev/gpiochip*) use. Records every bulk write with a monotonic timestamp and can
 * inject failures and stuck lines.
 *
 * Threads: not thread-safe; the chip must outlive its line sets only as long as they hold a
 * reference (each set does). */
#pragma once
#include "drivers/gpio/gpio_lines.h"

G_BEGIN_DECLS

typedef struct DsGpioSimChip DsGpioSimChip;

typedef struct {
  gint64 time_us;          /* g_get_monotonic_time () at the write */
  guint n_lines;
  guint offsets[DS_GPIO_MAX_LINES];
  int values[DS_GPIO_MAX_LINES];
} DsGpioSimWrite;

DsGpioSimChip *ds_gpio_sim_chip_new (const char *name, guint n_lines);
DsGpioSimChip *ds_gpio_sim_chip_ref (DsGpioSimChip *chip);
void ds_gpio_sim_chip_unref (DsGpioSimChip *chip); /* NULL-safe */
G_DEFINE_AUTOPTR_CLEANUP_FUNC (DsGpioSimChip, ds_gpio_sim_chip_unref)

/* Requests lines as outputs. Fails G_IO_ERROR_NOT_FOUND (offset beyond the chip) or
 * G_IO_ERROR_BUSY (a line already requested), like the kernel. */
DsGpioLines *ds_gpio_sim_chip_request (DsGpioSimChip *chip, const guint *offsets, guint n_lines,
                                       const int *initial, const char *consumer, GError **error);

guint ds_gpio_sim_chip_n_writes (const DsGpioSimChip *chip);
const DsGpioSimWrite *ds_gpio_sim_chip_get_write (const DsGpioSimChip *chip, guint i);
void ds_gpio_sim_chip_clear_writes (DsGpioSimChip *chip);
/* The line's level as a reader would see it (stuck lines included); -1 beyond the chip. */
int ds_gpio_sim_chip_value (const DsGpioSimChip *chip, guint offset);
/* Whether the line is requested and by whom (NULL: free). */
const char *ds_gpio_sim_chip_consumer (const DsGpioSimChip *chip, guint offset);

/* Fault knobs. The write after n_ok more successful writes fails with errno_value (e.g. EIO,
 * ENODEV, EBUSY), and so does every later one while `sticky`. */
void ds_gpio_sim_chip_fail_after (DsGpioSimChip *chip, guint n_ok, int errno_value, gboolean sticky);
void ds_gpio_sim_chip_clear_failure (DsGpioSimChip *chip);
/* The line reads `value` whatever is written (-1: unstick). */
void ds_gpio_sim_chip_stick_line (DsGpioSimChip *chip, guint offset, int value);

G_END_DECLS
