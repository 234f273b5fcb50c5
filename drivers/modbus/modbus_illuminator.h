/* The Modbus illuminator backend (libmodbus): a stripe projector's controller reached over
 * Modbus TCP or RTU, with the register map of docs/registers.md (drivers/modbus/registers.h).
 *
 * Every register access is bounded: at most DS_MODBUS_MAX_ATTEMPTS attempts, each limited by
 * the response timeout, and at most DS_MODBUS_MAX_ATTEMPTS * response timeout + 100 ms in
 * all; a timeout or a lost connection reconnects before the next attempt. Errors are
 * DS_ILLUMINATOR_ERROR codes whose message names the URI, the register and what happened.
 * Threads: as drivers/core/illuminator.h (the acquisition thread only). */
#pragma once
#include <glib.h>

#include "drivers/core/illuminator.h"

G_BEGIN_DECLS

#define DS_MODBUS_MAX_ATTEMPTS 3

typedef enum {
  DS_MODBUS_TCP = 0,
  DS_MODBUS_RTU = 1,
} DsModbusTransport;

typedef struct {
  DsModbusTransport transport;
  char host[256];          /* tcp: host name or address */
  guint port;              /* tcp: 1..65535 (default 502) */
  char device[256];        /* rtu: serial device path */
  guint baud;              /* rtu: default 19200 */
  char parity;             /* rtu: 'N', 'E' or 'O' (default 'E', as the Modbus spec) */
  guint data_bits;         /* rtu: 5..8 (default 8) */
  guint stop_bits;         /* rtu: 1 or 2 (default 1) */
} DsModbusUri;

/* "tcp://HOST[:PORT]" or "rtu:/dev/ttyX[?baud=B&parity=N|E|O&data=D&stop=S]". Fails INVALID with
 * a message that names the part of the URI that is wrong. */
gboolean ds_modbus_uri_parse (const char *uri, DsModbusUri *out, GError **error);

/* Connects, checks the MAGIC register (a device with another register map is refused: INVALID),
 * reads what the projector can do (CAPABILITIES, PERIOD_MIN/MAX_CENTIPX: DsIlluminatorStatus's
 * period fields; a controller of map revision 1, which has none, is taken as a fixed period it
 * does not state) and returns the illuminator, dark. response_timeout_ms: per request (5 .. 10000).
 * Fails INVALID (URI, unit id, magic), DISCONNECTED (cannot connect), TIMEOUT. */
DsIlluminator *ds_modbus_illuminator_open (const char *uri, guint unit_id, guint response_timeout_ms,
                                           GError **error);

/* Pattern geometry to registers as set_pattern writes them (DS_MB_HOLD_NUM_PHASES ..
 * DS_MB_HOLD_INTENSITY_PERMILLE into regs[2..7]; regs[0..1] PHASE = 0, ENABLE = 0).
 * Fails INVALID naming the field and register when a value is outside the register's range. */
gboolean ds_modbus_pattern_to_registers (const DsStripePattern *pattern, guint16 regs[8],
                                         GError **error);

G_END_DECLS
