/* Inside the lab's Modbus controller: the device model and the transport-independent request
 * handling (modbus_server.c), shared by the TCP listener (modbus_server_tcp.c) and the serial
 * line (modbus_server_rtu.c). Not for use outside drivers/labsim. */
#pragma once
#include <glib.h>

#include "drivers/labsim/modbus_server.h"
#include "drivers/modbus/registers.h"

G_BEGIN_DECLS

/* A PDU (function code + data) is at most 253 bytes (Modbus application protocol, 4.1). */
#define DS_MB_MAX_PDU 253

typedef enum {
  DS_MB_VERDICT_REPLY,  /* send answer->pdu */
  DS_MB_VERDICT_CLOSE,  /* TCP: close the connection instead of answering */
  DS_MB_VERDICT_SILENT, /* say nothing (the client times out) */
} DsMbVerdict;

typedef struct {
  guint8 pdu[DS_MB_MAX_PDU];
  gsize len;
  gboolean bad_crc;     /* RTU: send the frame with a corrupted CRC */
} DsMbAnswer;

typedef struct DsModbusTcp DsModbusTcp;
typedef struct DsModbusRtu DsModbusRtu;

struct DsModbusServer {
  GMutex lock;
  DsModbusServerConfig cfg;
  int wake[2];             /* pipe written once at shutdown, never drained: wakes every thread */
  gboolean quit;
  GRand *rand;
  /* What the projector can do: fixed when the server is made (the config's period fields). */
  gboolean rev1;
  guint16 capabilities, period_min, period_max, period_power_up;

  /* The device model. */
  guint16 hold[DS_MB_HOLD_COUNT];    /* as written */
  guint16 applied[DS_MB_HOLD_COUNT]; /* as lit */
  gboolean pending;
  gint64 pending_at_us;
  guint16 apply_count;
  guint64 requests, connections;

  /* The sync output: a thread that applies each write at the end of its settle time. */
  GCond pending_cond;
  DsModbusApplyFunc on_apply;
  gpointer on_apply_data;
  GThread *sync_thread;

  DsModbusTcp *tcp;        /* NULL: no TCP side */
  DsModbusRtu *rtu;        /* NULL: no serial side */
};

/* Answers one request PDU. Blocks for the configured delay (without the lock). Any thread;
 * takes the lock. `rtu`: the request came over the serial line (drops become silence). */
DsMbVerdict ds_modbus_server_answer (DsModbusServer *s, const guint8 *pdu, gsize len, gboolean rtu,
                                     DsMbAnswer *answer);

DsModbusTcp *ds_modbus_tcp_new (DsModbusServer *s, const char *address, guint port, GError **error);
guint ds_modbus_tcp_port (const DsModbusTcp *tcp);
void ds_modbus_tcp_drop_clients (DsModbusTcp *tcp);
void ds_modbus_tcp_free (DsModbusTcp *tcp); /* call after the wake pipe was written */

DsModbusRtu *ds_modbus_rtu_new (DsModbusServer *s, const DsModbusRtuConfig *config, GError **error);
const char *ds_modbus_rtu_path (const DsModbusRtu *rtu);
void ds_modbus_rtu_free (DsModbusRtu *rtu); /* call after the wake pipe was written */

/* The Modbus CRC-16 (polynomial 0xA001 reflected, initial value 0xFFFF) as sent low byte
 * first. */
guint16 ds_modbus_crc16 (const guint8 *data, gsize len);

G_END_DECLS
