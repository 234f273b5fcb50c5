/* The lab's illuminator controller: the register map of drivers/modbus/registers.h and
 * docs/registers.md served over Modbus TCP, over Modbus RTU on a serial line (a pseudo-terminal
 * it creates, or a device it is given), or both at once (one register state, as a controller
 * with an Ethernet and an RS-485 port), with a settle time between a write and the pattern
 * being lit, and fault knobs that act on either transport. Used by descatter-labsim and,
 * in-process, by the Modbus backend's tests.
 *
 * Threads: the server answers from its own threads (one per TCP connection, one for the serial
 * line). Every function here may be called from any thread; the state is behind one mutex. */
#pragma once
#include <glib.h>

G_BEGIN_DECLS

typedef struct DsModbusServer DsModbusServer;

typedef struct {
  guint settle_us;          /* write -> pattern lit; default 3000 */
  guint delay_ms;           /* extra response delay ... */
  guint delay_every;        /* ... on every Nth request (0: never, 1: all) */
  double exception_rate;    /* fraction of requests answered with exception_code instead */
  guint exception_code;     /* MODBUS_EXCEPTION_*; 0 means SLAVE_OR_SERVER_BUSY */
  guint drop_every;         /* close the connection instead of answering every Nth request */
  guint short_every;        /* answer every Nth read of 2+ registers with one register short */
  guint silent_every;       /* say nothing to every Nth request (the client's response timeout) */
  guint bad_crc_every;      /* RTU: every Nth answer goes out with a corrupted CRC */
  gboolean stuck_not_ready; /* writes are accepted and never applied: APPLYING forever */
  gboolean wrong_phase;     /* applies PHASE + 1 (mod NUM_PHASES) instead of PHASE */
  gboolean fault;           /* STATUS.FAULT set, nothing is applied */
  gboolean over_temperature;/* STATUS.OVER_TEMPERATURE set, TEMPERATURE 85 degC, nothing applied */
  guint64 seed;             /* for exception_rate */
  /* What the projector can do (docs/registers.md, CAPABILITIES). Read by ds_modbus_server_new:
   * later changes of these fields are ignored. */
  guint period_centipx;     /* PERIOD_CENTIPX at power-up; default 600 */
  gboolean period_fixed;    /* the period is its optics': PERIOD_MIN = MAX = period_centipx and
                             * any other is refused (exception 03); else adjustable in
                             * period_min_centipx .. period_max_centipx */
  guint period_min_centipx, period_max_centipx; /* default 200 .. 65535 */
  gboolean map_revision_1;  /* a controller of the first map: no CAPABILITIES .. PERIOD_MAX_CENTIPX
                             * (exception 02); it keeps any PERIOD_CENTIPX written but projects
                             * period_centipx (the register was information then) */
} DsModbusServerConfig;

void ds_modbus_server_config_init (DsModbusServerConfig *config);

/* What is lit now (the settle time is taken into account at the moment of the call). */
typedef struct {
  gboolean enabled;         /* a pattern is lit */
  gboolean all_on;          /* ... every stripe at once (ENABLE = 2) */
  guint phase, n_phases;    /* the lit phase; n_phases as applied */
  guint pattern_kind;
  guint period_centipx;     /* the period projected (revision 1: the power-up one) */
  guint duty_permille, black_permille, intensity_permille;
  guint apply_count;        /* mod 2^16, as the register */
  gboolean ready;
  guint64 requests;         /* requests received (answered, refused or dropped) */
  guint64 connections;      /* connections accepted */
} DsModbusServerState;

/* Listens for Modbus TCP on address:port (port 0: any free port; see ds_modbus_server_port);
 * address NULL: no TCP side (add a serial one). Fails with a G_IO_ERROR naming the address. */
DsModbusServer *ds_modbus_server_new (const char *address, guint port,
                                      const DsModbusServerConfig *config, GError **error);
guint ds_modbus_server_port (const DsModbusServer *server); /* 0 without a TCP side */

typedef struct {
  /* NULL or "pty": a pseudo-terminal created here (its slave is the device clients open);
   * otherwise a serial device as the backend's URI has it, "rtu:/dev/ttyX?baud=..&parity=.."
   * (docs/drivers.md), e.g. one end of a socat pty pair. */
  const char *device;
  /* pty only, may be NULL: a symlink kept pointing at the current slave, so a client finds the
   * line again after it went away and came back (as udev's /dev/serial/by-id links do). */
  const char *link;
  guint unit_id;            /* 1..247; requests for other units are not answered */
  /* Fault: after this many requests on the line (0: never) the line goes away (the pty is
   * closed, or the device released) for vanish_for_ms, then comes back (once). */
  guint vanish_after;
  guint vanish_for_ms;
} DsModbusRtuConfig;

/* Serves the same registers over Modbus RTU as well. One serial line per server. Fails with a
 * G_IO_ERROR naming the device. */
gboolean ds_modbus_server_add_rtu (DsModbusServer *server, const DsModbusRtuConfig *config,
                                   GError **error);
/* The device path a client opens (the link when one was asked for); NULL without a serial side. */
const char *ds_modbus_server_rtu_path (const DsModbusServer *server);
/* The serial line goes away now for ms milliseconds, then comes back (a cable pulled and
 * plugged back). */
void ds_modbus_server_rtu_vanish (DsModbusServer *server, guint ms);
/* How often the serial line has gone away so far (0 without a serial side): a caller waits for
 * it to count a vanish instead of watching for the short time the device path is missing. */
guint ds_modbus_server_rtu_times_away (DsModbusServer *server);
/* Changes the knobs at run time (the register state is kept). */
void ds_modbus_server_set_config (DsModbusServer *server, const DsModbusServerConfig *config);
void ds_modbus_server_get_state (DsModbusServer *server, DsModbusServerState *state);
/* The projector's sync output: called on the server's own thread each time a write is applied
 * (the pattern lit, changed or turned dark), at the end of its settle time, with what is lit
 * now. NULL to disconnect. Set it before clients write. */
typedef void (*DsModbusApplyFunc) (gpointer user_data, const DsModbusServerState *state);
void ds_modbus_server_set_apply_callback (DsModbusServer *server, DsModbusApplyFunc func, gpointer user_data);
/* Closes every TCP client connection now (the listener stays): a "dropped connection". */
void ds_modbus_server_drop_clients (DsModbusServer *server);
/* Stops the thread, closes every socket. NULL-safe. */
void ds_modbus_server_free (DsModbusServer *server);
G_DEFINE_AUTOPTR_CLEANUP_FUNC (DsModbusServer, ds_modbus_server_free)

G_END_DECLS
