/* The controller's device model and its answer to one request PDU, whatever the transport.
 * The answers follow docs/registers.md, written out here rather than through libmodbus's
 * modbus_reply, so that every fault (short, silent, bad CRC) can be made on any answer. */
#include "drivers/labsim/modbus_server_private.h"

#include <gio/gio.h>
#include <glib-unix.h>
#include <poll.h>
#include <string.h>
#include <unistd.h>

/* Function codes and exception codes of the Modbus application protocol. */
enum { FC_READ_HOLDING = 0x03, FC_READ_INPUT = 0x04, FC_WRITE_SINGLE = 0x06, FC_WRITE_MULTIPLE = 0x10 };
enum { EX_ILLEGAL_FUNCTION = 1, EX_ILLEGAL_ADDRESS = 2, EX_ILLEGAL_VALUE = 3, EX_BUSY = 6 };

void
ds_modbus_server_config_init (DsModbusServerConfig *config)
{
  memset (config, 0, sizeof *config);
  config->settle_us = 3000;
  config->seed = 1;
  config->period_centipx = 600;
  config->period_min_centipx = DS_MB_CENTIPX_MIN;
  config->period_max_centipx = DS_MB_CENTIPX_MAX;
}

guint16
ds_modbus_crc16 (const guint8 *data, gsize len)
{
  guint16 crc = 0xFFFF;
  for (gsize i = 0; i < len; i++) {
    crc ^= data[i];
    for (int b = 0; b < 8; b++)
      crc = (crc & 1) ? (guint16) ((crc >> 1) ^ 0xA001) : (guint16) (crc >> 1);
  }
  return crc;
}

/* Applies a write whose settle time has passed. Called with the lock held. */
static void
advance (DsModbusServer *s, gint64 now)
{
  if (!s->pending || now < s->pending_at_us || s->cfg.stuck_not_ready || s->cfg.fault ||
      s->cfg.over_temperature)
    return;
  memcpy (s->applied, s->hold, sizeof s->applied);
  if (s->cfg.wrong_phase && s->applied[DS_MB_HOLD_ENABLE] == 1 && s->applied[DS_MB_HOLD_NUM_PHASES] > 0)
    s->applied[DS_MB_HOLD_PHASE] = (guint16) ((s->applied[DS_MB_HOLD_PHASE] + 1) %
                                              s->applied[DS_MB_HOLD_NUM_PHASES]);
  s->apply_count++;
  s->pending = FALSE;
}

static gboolean
lit (const DsModbusServer *s)
{
  return s->applied[DS_MB_HOLD_ENABLE] && !s->cfg.fault && !s->cfg.over_temperature;
}

static void
inputs (const DsModbusServer *s, guint16 *in)
{
  gboolean busy = s->pending || s->cfg.stuck_not_ready;
  guint16 status = 0;
  if (!busy && !s->cfg.fault && !s->cfg.over_temperature)
    status |= DS_MB_STATUS_READY;
  if (busy)
    status |= DS_MB_STATUS_APPLYING;
  if (s->cfg.fault)
    status |= DS_MB_STATUS_FAULT;
  if (s->cfg.over_temperature)
    status |= DS_MB_STATUS_OVER_TEMPERATURE;
  if (lit (s))
    status |= DS_MB_STATUS_ENABLED;
  in[DS_MB_INPUT_MAGIC] = DS_MB_MAGIC;
  in[DS_MB_INPUT_FIRMWARE_VERSION] = 0x0102;
  in[DS_MB_INPUT_STATUS] = status;
  in[DS_MB_INPUT_APPLIED_PHASE] = !lit (s)                            ? DS_MB_PHASE_OFF
                                  : s->applied[DS_MB_HOLD_ENABLE] == 2 ? DS_MB_PHASE_ALL
                                                                       : s->applied[DS_MB_HOLD_PHASE];
  in[DS_MB_INPUT_APPLY_COUNT] = s->apply_count;
  in[DS_MB_INPUT_TEMPERATURE] = (guint16) (s->cfg.over_temperature ? 850 : 352);
  in[DS_MB_INPUT_CAPABILITIES] = s->capabilities;
  in[DS_MB_INPUT_PERIOD_MIN_CENTIPX] = s->period_min;
  in[DS_MB_INPUT_PERIOD_MAX_CENTIPX] = s->period_max;
}

/* Input registers this controller has (a revision-1 map stops before CAPABILITIES). */
static guint
input_count (const DsModbusServer *s)
{
  return s->rev1 ? DS_MB_INPUT_REV1_COUNT : DS_MB_INPUT_COUNT;
}

/* The ranges of docs/registers.md, checked on the registers as they would be after the write;
 * the period's is the projector's. */
static gboolean
valid (const DsModbusServer *s, const guint16 *h)
{
  guint n = h[DS_MB_HOLD_NUM_PHASES];
  guint period_min = s->rev1 ? DS_MB_CENTIPX_MIN : s->period_min;
  guint period_max = s->rev1 ? DS_MB_CENTIPX_MAX : s->period_max;
  guint enable_max = s->capabilities & DS_MB_CAP_ALL_ON ? 2 : 1;
  return n >= 2 && n <= DS_MB_MAX_PHASES && h[DS_MB_HOLD_PHASE] < n && h[DS_MB_HOLD_ENABLE] <= enable_max &&
         h[DS_MB_HOLD_PATTERN_KIND] <= 1 && h[DS_MB_HOLD_PERIOD_CENTIPX] >= period_min &&
         h[DS_MB_HOLD_PERIOD_CENTIPX] <= period_max &&
         h[DS_MB_HOLD_DUTY_PERMILLE] >= 1 && h[DS_MB_HOLD_DUTY_PERMILLE] <= 999 &&
         h[DS_MB_HOLD_BLACK_PERMILLE] <= 999 && h[DS_MB_HOLD_INTENSITY_PERMILLE] <= 1000;
}

static DsMbVerdict
exception (const guint8 *pdu, guint code, DsMbAnswer *a)
{
  a->pdu[0] = (guint8) (pdu[0] | 0x80);
  a->pdu[1] = (guint8) code;
  a->len = 2;
  return DS_MB_VERDICT_REPLY;
}

static guint
be16 (const guint8 *p)
{
  return (guint) (p[0] << 8 | p[1]);
}

/* Reads: the registers asked for, or one fewer when `short_by_one` (a well-formed answer that
 * carries less than asked: the client must notice). */
static DsMbVerdict
answer_read (DsModbusServer *s, const guint8 *pdu, gsize len, gboolean short_by_one, DsMbAnswer *a)
{
  if (len != 5)
    return DS_MB_VERDICT_CLOSE;
  guint addr = be16 (pdu + 1), nb = be16 (pdu + 3);
  gboolean input = pdu[0] == FC_READ_INPUT;
  guint limit = input ? input_count (s) : DS_MB_HOLD_COUNT;
  if (nb < 1 || nb > 125)
    return exception (pdu, EX_ILLEGAL_VALUE, a);
  if (addr + nb > limit)
    return exception (pdu, EX_ILLEGAL_ADDRESS, a);
  guint16 in[DS_MB_INPUT_COUNT];
  inputs (s, in);
  const guint16 *regs = input ? in : s->hold;
  guint n = short_by_one && nb >= 2 ? nb - 1 : nb;
  a->pdu[0] = pdu[0];
  a->pdu[1] = (guint8) (2 * n);
  for (guint i = 0; i < n; i++) {
    a->pdu[2 + 2 * i] = (guint8) (regs[addr + i] >> 8);
    a->pdu[3 + 2 * i] = (guint8) (regs[addr + i] & 0xff);
  }
  a->len = 2 + 2 * n;
  return DS_MB_VERDICT_REPLY;
}

/* Writes: checked on the registers as they would be after the write; one apply is scheduled
 * per accepted write request. */
static DsMbVerdict
answer_write (DsModbusServer *s, const guint8 *pdu, gsize len, gint64 now, DsMbAnswer *a)
{
  guint16 tentative[DS_MB_HOLD_COUNT];
  memcpy (tentative, s->hold, sizeof tentative);
  guint addr = len >= 3 ? be16 (pdu + 1) : 0;
  if (pdu[0] == FC_WRITE_SINGLE) {
    if (len != 5)
      return DS_MB_VERDICT_CLOSE;
    if (addr >= DS_MB_HOLD_COUNT)
      return exception (pdu, EX_ILLEGAL_ADDRESS, a);
    tentative[addr] = (guint16) be16 (pdu + 3);
  } else {
    if (len < 6)
      return DS_MB_VERDICT_CLOSE;
    guint nb = be16 (pdu + 3);
    if (nb < 1 || nb > 123 || pdu[5] != 2 * nb || len != 6 + 2 * (gsize) nb)
      return exception (pdu, EX_ILLEGAL_VALUE, a);
    if (addr + nb > DS_MB_HOLD_COUNT)
      return exception (pdu, EX_ILLEGAL_ADDRESS, a);
    for (guint i = 0; i < nb; i++)
      tentative[addr + i] = (guint16) be16 (pdu + 6 + 2 * i);
  }
  if (!valid (s, tentative))
    return exception (pdu, EX_ILLEGAL_VALUE, a);
  memcpy (s->hold, tentative, sizeof s->hold);
  s->pending = TRUE;
  s->pending_at_us = now + s->cfg.settle_us;
  /* Only a sync output needs the apply on the controller's own clock; without one every
   * request and state read applies it when due (advance), and waking the thread per write
   * would only take a core from the rate benchmark's camera (docs/benchmarks.md). */
  if (s->on_apply)
    g_cond_signal (&s->pending_cond);
  /* Both answers echo the first five bytes of the request (address and value or count). */
  memcpy (a->pdu, pdu, 5);
  a->len = 5;
  return DS_MB_VERDICT_REPLY;
}

/* Called with the lock held; releases it for the delay knob. */
static DsMbVerdict
answer_locked (DsModbusServer *s, const guint8 *pdu, gsize len, gboolean rtu, DsMbAnswer *a)
{
  guint64 n = ++s->requests;
  DsModbusServerConfig cfg = s->cfg;
  if (cfg.drop_every && n % cfg.drop_every == 0)
    /* A serial peer cannot hang up: it just does not answer. */
    return rtu ? DS_MB_VERDICT_SILENT : DS_MB_VERDICT_CLOSE;
  if (cfg.silent_every && n % cfg.silent_every == 0)
    return DS_MB_VERDICT_SILENT;
  if (cfg.delay_every && n % cfg.delay_every == 0 && cfg.delay_ms) {
    g_mutex_unlock (&s->lock);
    struct pollfd p = { .fd = s->wake[0], .events = POLLIN };
    (void) poll (&p, 1, (int) cfg.delay_ms);
    g_mutex_lock (&s->lock);
    if (s->quit)
      return DS_MB_VERDICT_CLOSE;
  }
  a->bad_crc = rtu && cfg.bad_crc_every && n % cfg.bad_crc_every == 0;
  if (cfg.exception_rate > 0 && g_rand_double (s->rand) < cfg.exception_rate)
    return exception (pdu, cfg.exception_code ? cfg.exception_code : EX_BUSY, a);
  gint64 now = g_get_monotonic_time ();
  advance (s, now);
  switch (pdu[0]) {
  case FC_READ_HOLDING:
  case FC_READ_INPUT:
    return answer_read (s, pdu, len, cfg.short_every && n % cfg.short_every == 0, a);
  case FC_WRITE_SINGLE:
  case FC_WRITE_MULTIPLE:
    return answer_write (s, pdu, len, now, a);
  default:
    return exception (pdu, EX_ILLEGAL_FUNCTION, a);
  }
}

DsMbVerdict
ds_modbus_server_answer (DsModbusServer *s, const guint8 *pdu, gsize len, gboolean rtu, DsMbAnswer *a)
{
  a->len = 0;
  a->bad_crc = FALSE;
  if (len < 1)
    return DS_MB_VERDICT_CLOSE;
  g_mutex_lock (&s->lock);
  DsMbVerdict v = answer_locked (s, pdu, len, rtu, a);
  g_mutex_unlock (&s->lock);
  return v;
}

static gpointer sync_thread (gpointer data);

DsModbusServer *
ds_modbus_server_new (const char *address, guint port, const DsModbusServerConfig *config,
                      GError **error)
{
  DsModbusServer *s = g_new0 (DsModbusServer, 1);
  g_mutex_init (&s->lock);
  s->wake[0] = s->wake[1] = -1;
  if (config)
    s->cfg = *config;
  else
    ds_modbus_server_config_init (&s->cfg);
  s->rand = g_rand_new_with_seed ((guint32) s->cfg.seed);
  s->rev1 = s->cfg.map_revision_1;
  s->period_power_up = (guint16) CLAMP (s->cfg.period_centipx, DS_MB_CENTIPX_MIN, DS_MB_CENTIPX_MAX);
  if (s->cfg.period_fixed) {
    s->capabilities = s->rev1 ? 0 : DS_MB_CAP_ALL_ON;
    s->period_min = s->period_max = s->period_power_up;
  } else {
    s->capabilities = DS_MB_CAP_PERIOD_ADJUSTABLE | (s->rev1 ? 0 : DS_MB_CAP_ALL_ON);
    s->period_min = (guint16) CLAMP (s->cfg.period_min_centipx, DS_MB_CENTIPX_MIN, s->period_power_up);
    s->period_max = (guint16) CLAMP (s->cfg.period_max_centipx, s->period_power_up, DS_MB_CENTIPX_MAX);
  }
  if (!g_unix_open_pipe (s->wake, FD_CLOEXEC, error)) {
    ds_modbus_server_free (s);
    return NULL;
  }
  /* Power-up state: dark, four phases of square stripes at its own period, nothing applied yet. */
  s->hold[DS_MB_HOLD_NUM_PHASES] = 4;
  s->hold[DS_MB_HOLD_PERIOD_CENTIPX] = s->period_power_up;
  s->hold[DS_MB_HOLD_DUTY_PERMILLE] = 500;
  s->hold[DS_MB_HOLD_INTENSITY_PERMILLE] = 1000;
  memcpy (s->applied, s->hold, sizeof s->applied);
  g_cond_init (&s->pending_cond);
  s->sync_thread = g_thread_new ("modbus-sync", sync_thread, s);
  if (address) {
    s->tcp = ds_modbus_tcp_new (s, address, port, error);
    if (!s->tcp) {
      ds_modbus_server_free (s);
      return NULL;
    }
  }
  return s;
}

guint
ds_modbus_server_port (const DsModbusServer *server)
{
  return server->tcp ? ds_modbus_tcp_port (server->tcp) : 0;
}

gboolean
ds_modbus_server_add_rtu (DsModbusServer *s, const DsModbusRtuConfig *config, GError **error)
{
  if (s->rtu) {
    g_set_error (error, G_IO_ERROR, G_IO_ERROR_EXISTS, "Modbus server: already serving a serial line (%s)",
                 ds_modbus_rtu_path (s->rtu));
    return FALSE;
  }
  s->rtu = ds_modbus_rtu_new (s, config, error);
  return s->rtu != NULL;
}

const char *
ds_modbus_server_rtu_path (const DsModbusServer *server)
{
  return server->rtu ? ds_modbus_rtu_path (server->rtu) : NULL;
}

void
ds_modbus_server_set_config (DsModbusServer *server, const DsModbusServerConfig *config)
{
  g_mutex_lock (&server->lock);
  /* A fault that clears lets a pending write apply from now on. */
  server->cfg = *config;
  g_mutex_unlock (&server->lock);
}

static void
state_locked (DsModbusServer *s, DsModbusServerState *st)
{
  st->enabled = lit (s);
  st->all_on = lit (s) && s->applied[DS_MB_HOLD_ENABLE] == 2;
  st->phase = s->applied[DS_MB_HOLD_PHASE];
  st->n_phases = s->applied[DS_MB_HOLD_NUM_PHASES];
  st->pattern_kind = s->applied[DS_MB_HOLD_PATTERN_KIND];
  st->period_centipx = s->rev1 ? s->period_power_up : s->applied[DS_MB_HOLD_PERIOD_CENTIPX];
  st->duty_permille = s->applied[DS_MB_HOLD_DUTY_PERMILLE];
  st->black_permille = s->applied[DS_MB_HOLD_BLACK_PERMILLE];
  st->intensity_permille = s->applied[DS_MB_HOLD_INTENSITY_PERMILLE];
  st->apply_count = s->apply_count;
  st->ready = !s->pending && !s->cfg.stuck_not_ready && !s->cfg.fault && !s->cfg.over_temperature;
  st->requests = s->requests;
  st->connections = s->connections;
}

void
ds_modbus_server_get_state (DsModbusServer *s, DsModbusServerState *st)
{
  g_mutex_lock (&s->lock);
  advance (s, g_get_monotonic_time ());
  state_locked (s, st);
  g_mutex_unlock (&s->lock);
}

/* Applies each write when its settle time is over, whether or not anyone asks, and tells the
 * sync output: a projector lights the pattern on its own clock. Without a sync output it only
 * wakes every 50 ms (knobs may change): requests and state reads apply what is due. */
static gpointer
sync_thread (gpointer data)
{
  DsModbusServer *s = data;
  g_mutex_lock (&s->lock);
  guint16 told = s->apply_count;
  while (!s->quit) {
    if (s->apply_count != told) {
      told = s->apply_count;
      DsModbusServerState st;
      state_locked (s, &st);
      DsModbusApplyFunc func = s->on_apply;
      gpointer user = s->on_apply_data;
      g_mutex_unlock (&s->lock);
      if (func)
        func (user, &st);
      g_mutex_lock (&s->lock);
      continue;
    }
    gint64 now = g_get_monotonic_time ();
    if (s->on_apply && s->pending && !s->cfg.stuck_not_ready && !s->cfg.fault && !s->cfg.over_temperature) {
      if (now >= s->pending_at_us)
        advance (s, now);
      else
        g_cond_wait_until (&s->pending_cond, &s->lock, s->pending_at_us);
    } else
      g_cond_wait_until (&s->pending_cond, &s->lock, now + 50000); /* knobs may change */
  }
  g_mutex_unlock (&s->lock);
  return NULL;
}

void
ds_modbus_server_set_apply_callback (DsModbusServer *s, DsModbusApplyFunc func, gpointer user_data)
{
  g_mutex_lock (&s->lock);
  s->on_apply = func;
  s->on_apply_data = user_data;
  g_cond_signal (&s->pending_cond); /* a write may be pending: time it now */
  g_mutex_unlock (&s->lock);
}

void
ds_modbus_server_drop_clients (DsModbusServer *s)
{
  if (s->tcp)
    ds_modbus_tcp_drop_clients (s->tcp);
}

void
ds_modbus_server_free (DsModbusServer *s)
{
  if (!s)
    return;
  g_mutex_lock (&s->lock);
  s->quit = TRUE;
  g_cond_broadcast (&s->pending_cond);
  g_mutex_unlock (&s->lock);
  if (s->sync_thread)
    g_thread_join (s->sync_thread);
  if (s->wake[1] >= 0)
    (void) !write (s->wake[1], "q", 1);
  g_clear_pointer (&s->tcp, ds_modbus_tcp_free);
  g_clear_pointer (&s->rtu, ds_modbus_rtu_free);
  for (int i = 0; i < 2; i++)
    if (s->wake[i] >= 0)
      close (s->wake[i]);
  if (s->rand)
    g_rand_free (s->rand);
  if (s->sync_thread)
    g_cond_clear (&s->pending_cond);
  g_mutex_clear (&s->lock);
  g_free (s);
}
