/* descatter-labsim's simulated GPIO chip, served on a UNIX socket so that another process
 * (descatterd's GPIO trigger or illuminator) can request its lines and drive them; the protocol
 * is drivers/gpio/gpio_wire.h. A level change of any line is reported to the edge callback,
 * which labsim wires to its camera's line inputs.
 *
 * Threads: new/free on any one thread; the chip serves all its connections on a thread of its
 * own, which is where the edge callback runs (it must not block). Getters from any thread. */
#pragma once
#include <gio/gio.h>

G_BEGIN_DECLS

typedef struct DsGpioChipServer DsGpioChipServer;

#define DS_GPIO_CHIP_SERVER_MAX_LINES 64
#define DS_GPIO_CHIP_SERVER_MAX_CLIENTS 32

/* A line changed level: rising is TRUE for 0 -> 1. Runs on the chip's thread. */
typedef void (*DsGpioChipEdgeFunc) (gpointer user_data, guint offset, gboolean rising);

typedef struct {
  guint64 requests_ok;     /* line requests granted */
  guint64 refused;         /* requests answered "err" */
  guint64 edges;           /* level changes of any line */
} DsGpioChipStats;

/* Listens on `path` (a stale socket file there is replaced; any other file is refused) with
 * n_lines lines, all low. Fails G_IO_ERROR naming the path. */
DsGpioChipServer *ds_gpio_chip_server_new (const char *path, guint n_lines, const char *label,
                                           DsGpioChipEdgeFunc edge, gpointer user_data, GError **error);
/* 0 or 1; -1 beyond the chip. */
int ds_gpio_chip_server_level (DsGpioChipServer *chip, guint offset);
void ds_gpio_chip_server_stats (DsGpioChipServer *chip, DsGpioChipStats *stats);
/* Closes every connection (their lines released), stops the thread and removes the socket. */
void ds_gpio_chip_server_free (DsGpioChipServer *chip);
G_DEFINE_AUTOPTR_CLEANUP_FUNC (DsGpioChipServer, ds_gpio_chip_server_free)

G_END_DECLS
