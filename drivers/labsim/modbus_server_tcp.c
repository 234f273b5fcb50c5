/* The controller's Modbus TCP side: a listener and one thread per connection, so that a delayed
 * answer to one client (a fault knob) does not hold up the others, as on a real
 * multi-connection controller. libmodbus frames the requests; the answers are written here. */
#include "drivers/labsim/modbus_server_private.h"

#include <errno.h>
#include <gio/gio.h>
#include <modbus.h>
#include <netinet/in.h>
#include <poll.h>
#include <string.h>
#include <sys/socket.h>
#include <unistd.h>

typedef struct {
  DsModbusTcp *tcp;
  int fd;
  modbus_t *ctx;
  GThread *thread;
  gboolean done;           /* under the server's lock */
} Client;

struct DsModbusTcp {
  DsModbusServer *server;
  char *address;
  modbus_t *listen_ctx;
  int listen_fd;
  guint port;
  GPtrArray *clients;      /* Client*, under the server's lock */
  GThread *thread;         /* accepts connections */
};

/* MBAP header (transaction, protocol 0, length, unit) + the answer's PDU, in one send. */
static gboolean
send_answer (int fd, const guint8 *query, const DsMbAnswer *a)
{
  guint8 adu[7 + DS_MB_MAX_PDU];
  memcpy (adu, query, 4); /* transaction and protocol ids, echoed */
  adu[4] = (guint8) ((a->len + 1) >> 8);
  adu[5] = (guint8) ((a->len + 1) & 0xff);
  adu[6] = query[6];      /* unit id */
  memcpy (adu + 7, a->pdu, a->len);
  return send (fd, adu, 7 + a->len, MSG_NOSIGNAL) == (ssize_t) (7 + a->len);
}

static gpointer
client_thread (gpointer data)
{
  Client *c = data;
  DsModbusServer *s = c->tcp->server;
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
    if (len < 8)
      continue; /* nothing for us */
    DsMbAnswer a;
    DsMbVerdict v = ds_modbus_server_answer (s, query + 7, (gsize) len - 7, FALSE, &a);
    if (v == DS_MB_VERDICT_CLOSE || (v == DS_MB_VERDICT_REPLY && !send_answer (c->fd, query, &a)))
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
  DsModbusTcp *t = data;
  DsModbusServer *s = t->server;
  for (;;) {
    struct pollfd fds[2] = { { .fd = s->wake[0], .events = POLLIN }, { .fd = t->listen_fd, .events = POLLIN } };
    if (poll (fds, 2, -1) < 0 && errno != EINTR)
      break;
    if (fds[0].revents)
      break;
    if (!(fds[1].revents & POLLIN))
      continue;
    int fd = accept4 (t->listen_fd, NULL, NULL, SOCK_CLOEXEC);
    if (fd < 0)
      continue;
    g_mutex_lock (&s->lock);
    /* Reap finished connections so a long run with dropped links stays bounded. */
    for (guint i = t->clients->len; i-- > 0;) {
      Client *old = g_ptr_array_index (t->clients, i);
      if (old->done)
        g_ptr_array_remove_index_fast (t->clients, i); /* joins: the thread has returned */
    }
    Client *c = g_new0 (Client, 1);
    c->tcp = t;
    c->fd = fd;
    c->ctx = modbus_new_tcp (t->address, (int) t->port);
    modbus_set_indication_timeout (c->ctx, 1, 0);
    modbus_set_socket (c->ctx, fd);
    s->connections++;
    g_ptr_array_add (t->clients, c);
    c->thread = g_thread_new ("modbus-client", client_thread, c);
    g_mutex_unlock (&s->lock);
  }
  return NULL;
}

DsModbusTcp *
ds_modbus_tcp_new (DsModbusServer *s, const char *address, guint port, GError **error)
{
  DsModbusTcp *t = g_new0 (DsModbusTcp, 1);
  t->server = s;
  t->listen_fd = -1;
  t->address = g_strdup (address);
  t->port = port;
  t->clients = g_ptr_array_new_with_free_func (client_free);
  t->listen_ctx = modbus_new_tcp (address, (int) port);
  if (!t->listen_ctx) {
    g_set_error (error, G_IO_ERROR, G_IO_ERROR_FAILED, "Modbus server %s:%u: %s", address, port,
                 modbus_strerror (errno));
    ds_modbus_tcp_free (t);
    return NULL;
  }
  t->listen_fd = modbus_tcp_listen (t->listen_ctx, 8);
  if (t->listen_fd < 0) {
    int e = errno;
    g_set_error (error, G_IO_ERROR, g_io_error_from_errno (e), "Modbus server %s:%u: cannot listen: %s",
                 address, port, g_strerror (e));
    ds_modbus_tcp_free (t);
    return NULL;
  }
  struct sockaddr_in sa;
  socklen_t sl = sizeof sa;
  if (getsockname (t->listen_fd, (struct sockaddr *) &sa, &sl) == 0)
    t->port = ntohs (sa.sin_port);
  t->thread = g_thread_new ("modbus-accept", accept_thread, t);
  return t;
}

guint
ds_modbus_tcp_port (const DsModbusTcp *t)
{
  return t->port;
}

void
ds_modbus_tcp_drop_clients (DsModbusTcp *t)
{
  DsModbusServer *s = t->server;
  g_mutex_lock (&s->lock);
  for (guint i = 0; i < t->clients->len; i++) {
    Client *c = g_ptr_array_index (t->clients, i);
    if (!c->done)
      shutdown (c->fd, SHUT_RDWR);
  }
  g_mutex_unlock (&s->lock);
}

void
ds_modbus_tcp_free (DsModbusTcp *t)
{
  if (!t)
    return;
  if (t->thread)
    g_thread_join (t->thread);
  g_ptr_array_unref (t->clients); /* joins every connection thread */
  if (t->listen_fd >= 0)
    close (t->listen_fd);
  if (t->listen_ctx)
    modbus_free (t->listen_ctx);
  g_free (t->address);
  g_free (t);
}
