/* The controller's Modbus RTU side: one serial line, a pseudo-terminal created here or a device
 * given (e.g. one end of a socat pty pair). libmodbus frames the requests (CRC, unit id); the
 * answers are written here, so a fault knob can send one with a corrupted CRC.
 *
 * A pty is a serial line whose far end is its slave device: the client opens the slave path.
 * This side keeps a slave descriptor open itself, so the line stays up while no client has it
 * open (the master would read EIO otherwise), and sets the slave raw so nothing is echoed. */
#include "drivers/labsim/modbus_server_private.h"

#include <errno.h>
#include <fcntl.h>
#include <gio/gio.h>
#include <modbus.h>
#include <poll.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <termios.h>
#include <unistd.h>

#include "drivers/modbus/modbus_illuminator.h"

struct DsModbusRtu {
  DsModbusServer *server;
  DsModbusRtuConfig cfg;
  char *device;            /* as given, NULL for a pty */
  char *link;              /* pty: symlink to keep pointing at the slave */
  char *path;              /* what clients open: the link, the slave or the device */
  DsModbusUri uri;         /* device: its serial parameters */
  modbus_t *ctx;           /* NULL while the line is away */
  int master, slave;       /* pty: both ends held here; -1 otherwise */
  guint64 requests;        /* on this line, for vanish_after */
  gboolean vanished_once;
  gint vanish_ms;          /* atomic: > 0 asks the thread to take the line away this long */
  gint times_away;         /* atomic: the line was closed by go_away this often */
  GThread *thread;
};

static void
line_close (DsModbusRtu *r)
{
  if (r->ctx) {
    if (r->device)
      modbus_close (r->ctx);
    modbus_free (r->ctx);
    r->ctx = NULL;
  }
  if (r->master >= 0)
    close (r->master);
  if (r->slave >= 0)
    close (r->slave);
  r->master = r->slave = -1;
  if (r->link)
    unlink (r->link);
}

/* A fresh pty; the link (if any) is replaced atomically so a client never sees it missing
 * while the line is up. */
static gboolean
open_pty (DsModbusRtu *r, GError **error)
{
  int m = posix_openpt (O_RDWR | O_NOCTTY | O_CLOEXEC);
  char name[128];
  if (m < 0 || grantpt (m) < 0 || unlockpt (m) < 0 || ptsname_r (m, name, sizeof name) != 0) {
    int e = errno;
    if (m >= 0)
      close (m);
    g_set_error (error, G_IO_ERROR, g_io_error_from_errno (e), "Modbus RTU: cannot create a pty: %s",
                 g_strerror (e));
    return FALSE;
  }
  int s = open (name, O_RDWR | O_NOCTTY | O_CLOEXEC);
  struct termios t;
  if (s < 0 || tcgetattr (s, &t) < 0) {
    int e = errno;
    close (m);
    if (s >= 0)
      close (s);
    g_set_error (error, G_IO_ERROR, g_io_error_from_errno (e), "Modbus RTU: cannot open %s: %s", name,
                 g_strerror (e));
    return FALSE;
  }
  cfmakeraw (&t);
  tcsetattr (s, TCSANOW, &t);
  r->master = m;
  r->slave = s;
  if (r->link) {
    g_autofree char *tmp = g_strdup_printf ("%s.new", r->link);
    unlink (tmp);
    if (symlink (name, tmp) < 0 || rename (tmp, r->link) < 0) {
      int e = errno;
      g_set_error (error, G_IO_ERROR, g_io_error_from_errno (e), "Modbus RTU: cannot link %s to %s: %s",
                   r->link, name, g_strerror (e));
      return FALSE;
    }
  } else {
    g_free (r->path);
    r->path = g_strdup (name);
  }
  /* libmodbus only needs the context for framing: the descriptor is ours. */
  r->ctx = modbus_new_rtu (name, 19200, 'N', 8, 1);
  modbus_set_socket (r->ctx, m);
  return TRUE;
}

static gboolean
open_device (DsModbusRtu *r, GError **error)
{
  r->ctx = modbus_new_rtu (r->uri.device, (int) r->uri.baud, r->uri.parity, (int) r->uri.data_bits,
                           (int) r->uri.stop_bits);
  if (!r->ctx || modbus_connect (r->ctx) < 0) {
    int e = errno;
    if (r->ctx)
      modbus_free (r->ctx);
    r->ctx = NULL;
    g_set_error (error, G_IO_ERROR, g_io_error_from_errno (e), "Modbus RTU: cannot open %s: %s",
                 r->uri.device, modbus_strerror (e));
    return FALSE;
  }
  return TRUE;
}

static gboolean
line_open (DsModbusRtu *r, GError **error)
{
  if (!(r->device ? open_device (r, error) : open_pty (r, error)))
    return FALSE;
  modbus_set_slave (r->ctx, (int) r->cfg.unit_id);
  /* A frame's bytes follow each other closely; a stalled one is given up after this. */
  modbus_set_byte_timeout (r->ctx, 0, 100000);
  return TRUE;
}

/* unit + PDU + CRC (low byte first), in one write. */
static void
send_frame (DsModbusRtu *r, guint8 unit, const DsMbAnswer *a)
{
  guint8 adu[1 + DS_MB_MAX_PDU + 2];
  adu[0] = unit;
  memcpy (adu + 1, a->pdu, a->len);
  guint16 crc = ds_modbus_crc16 (adu, 1 + a->len);
  if (a->bad_crc)
    crc ^= 0x5A5A;
  adu[1 + a->len] = (guint8) (crc & 0xff);
  adu[2 + a->len] = (guint8) (crc >> 8);
  gsize n = 3 + a->len;
  if (write (modbus_get_socket (r->ctx), adu, n) != (ssize_t) n)
    g_debug ("Modbus RTU %s: short write: %s", r->path, g_strerror (errno));
}

static void
go_away (DsModbusRtu *r, guint ms)
{
  g_message ("Modbus RTU %s: line away for %u ms", r->path, ms);
  line_close (r);
  g_atomic_int_inc (&r->times_away);
  struct pollfd p = { .fd = r->server->wake[0], .events = POLLIN };
  (void) poll (&p, 1, (int) ms);
  g_autoptr (GError) error = NULL;
  if (!(p.revents & POLLIN) && !line_open (r, &error))
    g_warning ("Modbus RTU: the line cannot come back: %s", error->message);
  else if (r->ctx)
    g_message ("Modbus RTU %s: line back", r->path);
}

static gpointer
rtu_thread (gpointer data)
{
  DsModbusRtu *r = data;
  DsModbusServer *s = r->server;
  uint8_t query[MODBUS_RTU_MAX_ADU_LENGTH];
  gint64 retry_at = 0;
  for (;;) {
    gint away = g_atomic_int_and (&r->vanish_ms, 0);
    if (away > 0)
      go_away (r, (guint) away);
    if (!r->ctx && g_get_monotonic_time () >= retry_at) {
      /* The device went away under us (the far end of a socat pair exited): look for it
       * again, as a controller whose USB adapter was replugged. */
      g_autoptr (GError) error = NULL;
      if (!line_open (r, &error))
        retry_at = g_get_monotonic_time () + 200000;
    }
    struct pollfd fds[2] = { { .fd = s->wake[0], .events = POLLIN },
                             { .fd = r->ctx ? modbus_get_socket (r->ctx) : -1, .events = POLLIN } };
    if (poll (fds, 2, 20) < 0 && errno != EINTR)
      break;
    if (fds[0].revents)
      break;
    if (!r->ctx || !(fds[1].revents & (POLLIN | POLLHUP | POLLERR)))
      continue;
    int len = modbus_receive (r->ctx, query);
    if (len < 0) {
      if (errno == EIO || errno == ENXIO || errno == EBADF) {
        g_message ("Modbus RTU %s: the line is gone: %s", r->path, g_strerror (errno));
        line_close (r);
        retry_at = g_get_monotonic_time () + 200000;
      } else
        /* A garbled or truncated request: the line is out of step, drop what is pending. */
        modbus_flush (r->ctx);
      continue;
    }
    if (len < 4)
      continue; /* another unit's request */
    r->requests++;
    if (r->cfg.vanish_after && !r->vanished_once && r->requests == r->cfg.vanish_after) {
      r->vanished_once = TRUE;
      go_away (r, r->cfg.vanish_for_ms);
      continue;
    }
    DsMbAnswer a;
    DsMbVerdict v = ds_modbus_server_answer (s, query + 1, (gsize) len - 3, TRUE, &a);
    /* Broadcasts (unit 0) are executed and never answered. */
    if (v == DS_MB_VERDICT_REPLY && query[0] != 0)
      send_frame (r, query[0], &a);
  }
  return NULL;
}

DsModbusRtu *
ds_modbus_rtu_new (DsModbusServer *s, const DsModbusRtuConfig *config, GError **error)
{
  DsModbusRtu *r = g_new0 (DsModbusRtu, 1);
  r->server = s;
  r->cfg = *config;
  r->cfg.device = r->cfg.link = NULL; /* copied below */
  r->master = r->slave = -1;
  if (config->unit_id < 1 || config->unit_id > 247) {
    g_set_error (error, G_IO_ERROR, G_IO_ERROR_INVALID_ARGUMENT, "Modbus RTU: unit id %u outside 1..247",
                 config->unit_id);
    ds_modbus_rtu_free (r);
    return NULL;
  }
  if (config->device && strcmp (config->device, "pty") != 0) {
    g_autofree char *uri = g_str_has_prefix (config->device, "rtu:") ? g_strdup (config->device)
                                                                     : g_strdup_printf ("rtu:%s", config->device);
    GError *e = NULL;
    if (!ds_modbus_uri_parse (uri, &r->uri, &e)) {
      g_set_error (error, G_IO_ERROR, G_IO_ERROR_INVALID_ARGUMENT, "%s", e->message);
      g_error_free (e);
      ds_modbus_rtu_free (r);
      return NULL;
    }
    r->device = g_strdup (r->uri.device);
    r->path = g_strdup (r->uri.device);
  } else if (config->link) {
    r->link = g_strdup (config->link);
    r->path = g_strdup (config->link);
  }
  if (!line_open (r, error)) {
    ds_modbus_rtu_free (r);
    return NULL;
  }
  r->thread = g_thread_new ("modbus-rtu", rtu_thread, r);
  return r;
}

const char *
ds_modbus_rtu_path (const DsModbusRtu *r)
{
  return r->path;
}

void
ds_modbus_server_rtu_vanish (DsModbusServer *s, guint ms)
{
  if (s->rtu)
    g_atomic_int_set (&s->rtu->vanish_ms, (gint) MAX (ms, 1u));
}

guint
ds_modbus_server_rtu_times_away (DsModbusServer *s)
{
  return s->rtu ? (guint) g_atomic_int_get (&s->rtu->times_away) : 0;
}

void
ds_modbus_rtu_free (DsModbusRtu *r)
{
  if (!r)
    return;
  if (r->thread)
    g_thread_join (r->thread);
  line_close (r);
  g_free (r->device);
  g_free (r->link);
  g_free (r->path);
  g_free (r);
}
