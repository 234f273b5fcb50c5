#include "drivers/labsim/modbus_server.h"

#include <errno.h>
#include <gio/gio.h>
#include <glib-unix.h>
#include <modbus.h>
#include <netinet/in.h>
#include <poll.h>
#include <string.h>
#include <sys/socket.h>
#include <unistd.h>

#include "drivers/modbus/registers.h"

/* One thread per connection, so that a delayed answer to one client (a fault knob) does not
 * hold up the others, as on a real multi-connection controller. */
typedef struct {
  DsModbusServer *server;
  int fd;
  modbus_t *ctx;
  GThread *thread;
  gboolean done;
} Client;

struct DsModbusServer {
  GMutex lock;
  DsModbusServerConfig cfg;
  modbus_mapping_t *map;   /* holding = what was written; input = filled before each read */
  char *address;
  modbus_t *listen_ctx;
  int listen_fd;
  guint port;
  int wake[2];             /* pipe written once at shutdown, never drained: wakes every thread */
  gboolean quit;
  GPtrArray *clients;      /* Client* */
  GThread *thread;         /* accepts connections */
  GRand *rand;

  /* The device model. */
  guint16 applied[DS_MB_HOLD_COUNT];
  gboolean pending;
  gint64 pending_at_us;
  guint16 apply_count;
  guint64 requests, connections;
};

void
ds_modbus_server_config_init (DsModbusServerConfig *config)
{
  memset (config, 0, sizeof *config);
  config->settle_us = 3000;
  config->seed = 1;
}

/* Applies a write whose settle time has passed. Called with the lock held. */
static void
advance (DsModbusServer *s, gint64 now)
{
  if (!s->pending || now < s->pending_at_us || s->cfg.stuck_not_ready || s->cfg.fault ||
      s->cfg.over_temperature)
    return;
  memcpy (s->applied, s->map->tab_registers, sizeof s->applied);
  if (s->cfg.wrong_phase && s->applied[DS_MB_HOLD_ENABLE] && s->applied[DS_MB_HOLD_NUM_PHASES] > 0)
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
fill_inputs (DsModbusServer *s)
{
  guint16 *in = s->map->tab_input_registers;
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
  in[DS_MB_INPUT_APPLIED_PHASE] = lit (s) ? s->applied[DS_MB_HOLD_PHASE] : DS_MB_PHASE_OFF;
  in[DS_MB_INPUT_APPLY_COUNT] = s->apply_count;
  in[DS_MB_INPUT_TEMPERATURE] = (guint16) (s->cfg.over_temperature ? 850 : 352);
}

/* The ranges of docs/registers.md, checked on the registers as they would be after the write. */
static gboolean
valid (const guint16 *h)
{
  guint n = h[DS_MB_HOLD_NUM_PHASES];
  return n >= 2 && n <= DS_MB_MAX_PHASES && h[DS_MB_HOLD_PHASE] < n && h[DS_MB_HOLD_ENABLE] <= 1 &&
         h[DS_MB_HOLD_PATTERN_KIND] <= 1 && h[DS_MB_HOLD_PERIOD_CENTIPX] >= 200 &&
         h[DS_MB_HOLD_DUTY_PERMILLE] >= 1 && h[DS_MB_HOLD_DUTY_PERMILLE] <= 999 &&
         h[DS_MB_HOLD_BLACK_PERMILLE] <= 999 && h[DS_MB_HOLD_INTENSITY_PERMILLE] <= 1000;
}

/* A well-formed Modbus TCP answer carrying one register fewer than asked for. */
static gboolean
send_short_answer (DsModbusServer *s, modbus_t *ctx, const uint8_t *q, int hl)
{
  guint addr = (guint) (q[hl + 1] << 8 | q[hl + 2]);
  guint nb = (guint) (q[hl + 3] << 8 | q[hl + 4]);
  gboolean input = q[hl] == MODBUS_FC_READ_INPUT_REGISTERS;
  guint limit = input ? DS_MB_INPUT_COUNT : DS_MB_HOLD_COUNT;
  if (nb < 2 || addr + nb > limit)
    return modbus_reply_exception (ctx, q, MODBUS_EXCEPTION_ILLEGAL_DATA_ADDRESS) >= 0;
  if (input)
    fill_inputs (s);
  const guint16 *regs = input ? s->map->tab_input_registers : s->map->tab_registers;
  guint8 rsp[7 + 2 + 2 * 125];
  guint n = nb - 1, len = 0;
  rsp[len++] = q[0]; /* transaction id */
  rsp[len++] = q[1];
  rsp[len++] = 0;    /* protocol id */
  rsp[len++] = 0;
  rsp[len++] = (guint8) ((3 + 2 * n) >> 8);
  rsp[len++] = (guint8) ((3 + 2 * n) & 0xff);
  rsp[len++] = q[6]; /* unit id */
  rsp[len++] = q[hl];
  rsp[len++] = (guint8) (2 * n);
  for (guint i = 0; i < n; i++) {
    rsp[len++] = (guint8) (regs[addr + i] >> 8);
    rsp[len++] = (guint8) (regs[addr + i] & 0xff);
  }
  return send (modbus_get_socket (ctx), rsp, len, MSG_NOSIGNAL) == (ssize_t) len;
}

/* Answers one request on the current socket. Returns FALSE when the connection must close. */
static gboolean
handle_request (DsModbusServer *s, modbus_t *ctx, const uint8_t *q, int len)
{
  int hl = modbus_get_header_length (ctx);
  if (len < hl + 1)
    return FALSE;
  guint8 fc = q[hl];
  guint n = (guint) ++s->requests;
  DsModbusServerConfig cfg = s->cfg;
  if (cfg.drop_every && n % cfg.drop_every == 0)
    return FALSE;
  if (cfg.delay_every && n % cfg.delay_every == 0 && cfg.delay_ms) {
    g_mutex_unlock (&s->lock);
    struct pollfd p = { .fd = s->wake[0], .events = POLLIN };
    (void) poll (&p, 1, (int) cfg.delay_ms);
    g_mutex_lock (&s->lock);
    if (s->quit)
      return FALSE;
  }
  if (cfg.exception_rate > 0 && g_rand_double (s->rand) < cfg.exception_rate) {
    modbus_reply_exception (ctx, q, cfg.exception_code ? cfg.exception_code
                                                          : MODBUS_EXCEPTION_SLAVE_OR_SERVER_BUSY);
    return TRUE;
  }
  gint64 now = g_get_monotonic_time ();
  advance (s, now);
  if (cfg.short_every && n % cfg.short_every == 0 && len >= hl + 5 &&
      (fc == MODBUS_FC_READ_HOLDING_REGISTERS || fc == MODBUS_FC_READ_INPUT_REGISTERS) &&
      modbus_get_header_length (ctx) == 7)
    return send_short_answer (s, ctx, q, hl);
  guint16 tentative[DS_MB_HOLD_COUNT];
  memcpy (tentative, s->map->tab_registers, sizeof tentative);
  gboolean is_write = FALSE;
  switch (fc) {
  case MODBUS_FC_READ_HOLDING_REGISTERS:
    break;
  case MODBUS_FC_READ_INPUT_REGISTERS:
    fill_inputs (s);
    break;
  case MODBUS_FC_WRITE_SINGLE_REGISTER: {
    if (len < hl + 5)
      return FALSE;
    guint addr = (guint) (q[hl + 1] << 8 | q[hl + 2]);
    if (addr < DS_MB_HOLD_COUNT) {
      tentative[addr] = (guint16) (q[hl + 3] << 8 | q[hl + 4]);
      is_write = TRUE;
    }
    break;
  }
  case MODBUS_FC_WRITE_MULTIPLE_REGISTERS: {
    if (len < hl + 6)
      return FALSE;
    guint addr = (guint) (q[hl + 1] << 8 | q[hl + 2]);
    guint nb = (guint) (q[hl + 3] << 8 | q[hl + 4]);
    if (addr + nb <= DS_MB_HOLD_COUNT && len >= hl + 6 + (int) (2 * nb)) {
      for (guint i = 0; i < nb; i++)
        tentative[addr + i] = (guint16) (q[hl + 6 + 2 * i] << 8 | q[hl + 7 + 2 * i]);
      is_write = TRUE;
    }
    break;
  }
  default:
    modbus_reply_exception (ctx, q, MODBUS_EXCEPTION_ILLEGAL_FUNCTION);
    return TRUE;
  }
  if (is_write && !valid (tentative)) {
    modbus_reply_exception (ctx, q, MODBUS_EXCEPTION_ILLEGAL_DATA_VALUE);
    return TRUE;
  }
  /* Out-of-range addresses and counts are refused by libmodbus (exception 02). */
  if (modbus_reply (ctx, q, len, s->map) < 0)
    return FALSE;
  if (is_write) {
    s->pending = TRUE;
    s->pending_at_us = now + cfg.settle_us;
  }
  return TRUE;
}

static gpointer
client_thread (gpointer data)
{
  Client *c = data;
  DsModbusServer *s = c->server;
  uint8_t query[MODBUS_TCP_MAX_ADU_LENGTH];
  for (;;) {
    struct pollfd fds[2] = { { .fd = s->wake[0], .events = POLLIN }, { .fd = c->fd, .events = POLLIN } };
    if (poll (fds, 2, -1) < 0 && errno != EINTR)
      break;
    if (fds[0].revents)
      break;
    if (!fds[1].revents)
      continue;
    int len = modbus_receive (c->ctx, query);
    if (len < 0)
      break;
    if (len == 0)
      continue; /* a request for another unit: ignored */
    g_mutex_lock (&s->lock);
    gboolean keep = !s->quit && handle_request (s, c->ctx, query, len);
    g_mutex_unlock (&s->lock);
    if (!keep)
      break;
  }
  /* Closed here, so the peer sees the drop at once. */
  shutdown (c->fd, SHUT_RDWR);
  g_mutex_lock (&s->lock);
  c->done = TRUE;
  g_mutex_unlock (&s->lock);
  return NULL;
}

static void
client_free (gpointer data)
{
  Client *c = data;
  g_thread_join (c->thread);
  modbus_free (c->ctx);
  close (c->fd);
  g_free (c);
}

static gpointer
accept_thread (gpointer data)
{
  DsModbusServer *s = data;
  for (;;) {
    struct pollfd fds[2] = { { .fd = s->wake[0], .events = POLLIN }, { .fd = s->listen_fd, .events = POLLIN } };
    if (poll (fds, 2, -1) < 0 && errno != EINTR)
      break;
    if (fds[0].revents)
      break;
    if (!(fds[1].revents & POLLIN))
      continue;
    int fd = accept4 (s->listen_fd, NULL, NULL, SOCK_CLOEXEC);
    if (fd < 0)
      continue;
    /* Reap finished connections so a long run with dropped links stays bounded. */
    g_mutex_lock (&s->lock);
    for (guint i = s->clients->len; i-- > 0;) {
      Client *old = g_ptr_array_index (s->clients, i);
      if (old->done)
        g_ptr_array_remove_index_fast (s->clients, i); /* joins: the thread has returned */
    }
    Client *c = g_new0 (Client, 1);
    c->server = s;
    c->fd = fd;
    c->ctx = modbus_new_tcp (s->address, (int) s->port);
    modbus_set_indication_timeout (c->ctx, 1, 0);
    modbus_set_socket (c->ctx, fd);
    s->connections++;
    g_ptr_array_add (s->clients, c);
    c->thread = g_thread_new ("modbus-client", client_thread, c);
    g_mutex_unlock (&s->lock);
  }
  return NULL;
}

DsModbusServer *
ds_modbus_server_new (const char *address, guint port, const DsModbusServerConfig *config,
                      GError **error)
{
  DsModbusServer *s = g_new0 (DsModbusServer, 1);
  g_mutex_init (&s->lock);
  s->listen_fd = -1;
  s->wake[0] = s->wake[1] = -1;
  s->address = g_strdup (address);
  s->clients = g_ptr_array_new_with_free_func (client_free);
  if (config)
    s->cfg = *config;
  else
    ds_modbus_server_config_init (&s->cfg);
  s->rand = g_rand_new_with_seed ((guint32) s->cfg.seed);
  s->listen_ctx = modbus_new_tcp (address, (int) port);
  s->map = modbus_mapping_new (0, 0, DS_MB_HOLD_COUNT, DS_MB_INPUT_COUNT);
  if (!s->listen_ctx || !s->map) {
    g_set_error (error, G_IO_ERROR, G_IO_ERROR_FAILED, "Modbus server %s:%u: %s", address, port,
                 modbus_strerror (errno));
    ds_modbus_server_free (s);
    return NULL;
  }
  s->listen_fd = modbus_tcp_listen (s->listen_ctx, 8);
  if (s->listen_fd < 0) {
    int e = errno;
    g_set_error (error, G_IO_ERROR, g_io_error_from_errno (e), "Modbus server %s:%u: cannot listen: %s",
                 address, port, g_strerror (e));
    ds_modbus_server_free (s);
    return NULL;
  }
  struct sockaddr_in sa;
  socklen_t sl = sizeof sa;
  if (getsockname (s->listen_fd, (struct sockaddr *) &sa, &sl) == 0)
    s->port = ntohs (sa.sin_port);
  if (!g_unix_open_pipe (s->wake, FD_CLOEXEC, error)) {
    ds_modbus_server_free (s);
    return NULL;
  }
  /* Power-up state: dark, four phases of 6 px square stripes, nothing applied yet. */
  guint16 *h = s->map->tab_registers;
  h[DS_MB_HOLD_NUM_PHASES] = 4;
  h[DS_MB_HOLD_PERIOD_CENTIPX] = 600;
  h[DS_MB_HOLD_DUTY_PERMILLE] = 500;
  h[DS_MB_HOLD_INTENSITY_PERMILLE] = 1000;
  memcpy (s->applied, h, sizeof s->applied);
  s->thread = g_thread_new ("modbus-accept", accept_thread, s);
  return s;
}

guint
ds_modbus_server_port (const DsModbusServer *server)
{
  return server->port;
}

void
ds_modbus_server_set_config (DsModbusServer *server, const DsModbusServerConfig *config)
{
  g_mutex_lock (&server->lock);
  /* A fault that clears lets a pending write apply from now on. */
  server->cfg = *config;
  g_mutex_unlock (&server->lock);
}

void
ds_modbus_server_get_state (DsModbusServer *s, DsModbusServerState *st)
{
  g_mutex_lock (&s->lock);
  advance (s, g_get_monotonic_time ());
  st->enabled = lit (s);
  st->phase = s->applied[DS_MB_HOLD_PHASE];
  st->n_phases = s->applied[DS_MB_HOLD_NUM_PHASES];
  st->pattern_kind = s->applied[DS_MB_HOLD_PATTERN_KIND];
  st->period_centipx = s->applied[DS_MB_HOLD_PERIOD_CENTIPX];
  st->duty_permille = s->applied[DS_MB_HOLD_DUTY_PERMILLE];
  st->black_permille = s->applied[DS_MB_HOLD_BLACK_PERMILLE];
  st->intensity_permille = s->applied[DS_MB_HOLD_INTENSITY_PERMILLE];
  st->apply_count = s->apply_count;
  st->ready = !s->pending && !s->cfg.stuck_not_ready && !s->cfg.fault && !s->cfg.over_temperature;
  st->requests = s->requests;
  st->connections = s->connections;
  g_mutex_unlock (&s->lock);
}

void
ds_modbus_server_drop_clients (DsModbusServer *s)
{
  g_mutex_lock (&s->lock);
  for (guint i = 0; i < s->clients->len; i++) {
    Client *c = g_ptr_array_index (s->clients, i);
    if (!c->done)
      shutdown (c->fd, SHUT_RDWR);
  }
  g_mutex_unlock (&s->lock);
}

void
ds_modbus_server_free (DsModbusServer *s)
{
  if (!s)
    return;
  g_mutex_lock (&s->lock);
  s->quit = TRUE;
  g_mutex_unlock (&s->lock);
  if (s->wake[1] >= 0)
    (void) !write (s->wake[1], "q", 1);
  if (s->thread)
    g_thread_join (s->thread);
  g_ptr_array_unref (s->clients); /* joins every connection thread */
  if (s->listen_fd >= 0)
    close (s->listen_fd);
  for (int i = 0; i < 2; i++)
    if (s->wake[i] >= 0)
      close (s->wake[i]);
  if (s->map)
    modbus_mapping_free (s->map);
  if (s->listen_ctx)
    modbus_free (s->listen_ctx);
  if (s->rand)
    g_rand_free (s->rand);
  g_free (s->address);
  g_mutex_clear (&s->lock);
  g_free (s);
}
