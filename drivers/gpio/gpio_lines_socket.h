/* The DsGpioLines implementation over descatter-labsim's simulated GPIO chip, reached on a UNIX
 * socket (protocol: gpio_wire.h). With it descatterd's GPIO trigger pulses a line that labsim's
 * camera, another process, sees on its Line0 input: the hardware-trigger path end to end on a
 * machine without /dev/gpiochip*.
 *
 * Kernel semantics where they matter: a line held by another connection fails
 * G_IO_ERROR_BUSY, an offset beyond the chip G_IO_ERROR_NOT_FOUND, no chip at the path
 * G_IO_ERROR_NOT_FOUND. Every exchange is bounded by DS_GPIO_SOCKET_TIMEOUT_MS: a chip that
 * stops answering fails G_IO_ERROR_TIMED_OUT, one that goes away G_IO_ERROR_CLOSED; the
 * connection is then dropped (its lines are released by the chip) and every later set or get
 * fails G_IO_ERROR_CLOSED until `reopen` requests the lines again with their last values.
 *
 * Threads: one thread at a time per set, as every DsGpioLines. Blocks at most the timeout. */
#pragma once
#include "drivers/gpio/gpio_lines.h"

G_BEGIN_DECLS

#define DS_GPIO_SOCKET_TIMEOUT_MS 1000

/* socket_path: the chip's socket; chip: how messages name the chip (e.g. "labsim:/run/x.sock"). */
DsGpioLines *ds_gpio_lines_request_socket (const char *chip, const char *socket_path, const guint *offsets,
                                           guint n_lines, const int *initial, const char *consumer,
                                           GError **error);

G_END_DECLS
