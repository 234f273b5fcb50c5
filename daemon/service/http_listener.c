#include "daemon/service/http_listener.h"

#include <errno.h>
#include <string.h>
#include <sys/socket.h>
#include <unistd.h>

#include "daemon/service/http_input.h"

/* How often timeouts are checked; bounds how late one is noticed. */
#define SWEEP_MS 250
/* Out of descriptors: accepting resumes after this long (a timer, not a busy loop). */
#define RESUME_MS 250
/* A warning about a paused accept at most this often. */
#define PAUSE_LOG_US (10 * G_USEC_PER_SEC)

typedef enum { WAITING, READING, UPGRADED } ConnState;

typedef struct {
  DsHttpListener *listener;
  GSocket *socket;
  DsHttpInput *input;   /* borrowed: libsoup owns the stream, its close removes this record */
  char *key;            /* "address|port" of the peer: which connection a message is on */
  char *peer;           /* the peer's address: the per-peer count */
  ConnState state;
  gint64 since_us;      /* WAITING: since the last request ended; READING: its first byte seen */
  guint64 mark;         /* input bytes when the wait began */
  gboolean closing;     /* shut down by us; its count goes when libsoup closes it */
} Conn;

struct DsHttpListener {
  SoupServer *soup;
  DsHttpLimits limits;
  GSocket *listen;
  GSource *accept_source, *resume_source, *sweep;
  GHashTable *conns;    /* key -> Conn * (owned) */
  GHashTable *peers;    /* address -> count */
  guint16 port;
  gint64 last_pause_log_us;
  DsHttpListenerStats stats;
};

static void start_accepting (DsHttpListener *l);

static char *
address_key (GSocketAddress *addr, char **peer)
{
  if (!addr || !G_IS_INET_SOCKET_ADDRESS (addr))
    return NULL;
  GInetSocketAddress *ia = G_INET_SOCKET_ADDRESS (addr);
  g_autofree char *ip = g_inet_address_to_string (g_inet_socket_address_get_address (ia));
  char *key = g_strdup_printf ("%s|%u", ip, g_inet_socket_address_get_port (ia));
  if (peer)
    *peer = g_steal_pointer (&ip);
  return key;
}

static Conn *
conn_of (DsHttpListener *l, SoupServerMessage *msg)
{
  g_autofree char *key = address_key (soup_server_message_get_remote_address (msg), NULL);
  return key ? g_hash_table_lookup (l->conns, key) : NULL;
}

static void
conn_free (gpointer data)
{
  Conn *c = data;
  if (c->input)
    ds_http_input_forget (c->input);
  g_object_unref (c->socket);
  g_free (c->key);
  g_free (c->peer);
  g_free (c);
}

static void
peer_count_add (DsHttpListener *l, const char *peer, int delta)
{
  guint n = GPOINTER_TO_UINT (g_hash_table_lookup (l->peers, peer));
  n = (guint) ((int) n + delta);
  if (n)
    g_hash_table_insert (l->peers, g_strdup (peer), GUINT_TO_POINTER (n));
  else
    g_hash_table_remove (l->peers, peer);
}

static void
on_input_closed (gpointer data)
{
  Conn *c = data;
  DsHttpListener *l = c->listener;
  c->input = NULL;
  peer_count_add (l, c->peer, -1);
  g_hash_table_remove (l->conns, c->key);
}

/* A short answer written straight to the socket (it fits the empty send buffer of a new
 * connection; if not, the peer learns from the close). */
static void
send_raw (GSocket *sock, guint status, const char *text)
{
  g_autofree char *resp = g_strdup_printf ("HTTP/1.1 %u %s\r\nContent-Type: text/plain; charset=utf-8\r\n"
                                           "Content-Length: %zu\r\nConnection: close\r\nCache-Control: no-store\r\n\r\n%s",
                                           status, soup_status_get_phrase (status), strlen (text), text);
  g_socket_send_with_blocking (sock, resp, strlen (resp), FALSE, NULL, NULL);
}

static void
conn_shut (Conn *c)
{
  c->closing = TRUE;
  g_socket_shutdown (c->socket, TRUE, TRUE, NULL);
}

static void
take (DsHttpListener *l, int fd)
{
  g_autoptr (GError) error = NULL;
  g_autoptr (GSocket) sock = g_socket_new_from_fd (fd, &error);
  if (!sock) {
    close (fd);
    return;
  }
  l->stats.accepted++;
  g_autoptr (GSocketAddress) remote = g_socket_get_remote_address (sock, NULL);
  g_autoptr (GSocketAddress) local = g_socket_get_local_address (sock, NULL);
  g_autofree char *peer = NULL;
  g_autofree char *key = address_key (remote, &peer);
  guint from_peer = peer ? GPOINTER_TO_UINT (g_hash_table_lookup (l->peers, peer)) : 0;
  if (!key || g_hash_table_size (l->conns) >= l->limits.max_connections || from_peer >= l->limits.max_per_peer) {
    l->stats.refused++;
    g_autofree char *text = g_strdup_printf (
        "503 too many connections (%u of max-connections %u, %u of max-connections-per-peer %u from %s)\n",
        g_hash_table_size (l->conns), l->limits.max_connections, from_peer, l->limits.max_per_peer,
        peer ? peer : "?");
    send_raw (sock, SOUP_STATUS_SERVICE_UNAVAILABLE, text);
    g_socket_close (sock, NULL);
    return;
  }
  g_autoptr (GSocketConnection) sc = g_socket_connection_factory_create_connection (sock);
  Conn *c = g_new0 (Conn, 1);
  c->listener = l;
  c->socket = g_object_ref (sock);
  c->key = g_steal_pointer (&key);
  c->peer = g_steal_pointer (&peer);
  c->state = WAITING;
  c->since_us = g_get_monotonic_time ();
  g_autoptr (DsHttpInput) in = ds_http_input_new (sc, on_input_closed, c);
  c->input = in;
  g_autofree char *what = g_strdup_printf ("request headers over %u bytes (max-header-bytes)", l->limits.max_header_bytes);
  ds_http_input_set_limit (in, l->limits.max_header_bytes, what);
  g_hash_table_insert (l->conns, c->key, c);
  peer_count_add (l, c->peer, +1);
  g_autoptr (GIOStream) io = g_simple_io_stream_new (G_INPUT_STREAM (in), g_io_stream_get_output_stream (G_IO_STREAM (sc)));
  if (!soup_server_accept_iostream (l->soup, io, local, remote, &error)) {
    g_warning ("HTTP: a connection could not be served: %s", error->message);
    g_io_stream_close (io, NULL, NULL);
  }
}

static gboolean
resume_accepting (gpointer data)
{
  DsHttpListener *l = data;
  g_clear_pointer (&l->resume_source, g_source_unref);
  start_accepting (l);
  return G_SOURCE_REMOVE;
}

/* Out of descriptors: nothing can be accepted until some close, and the pending connection
 * keeps the socket readable; accepting again at once would spin. */
static void
pause_accepting (DsHttpListener *l, int err)
{
  l->stats.accept_paused++;
  gint64 now = g_get_monotonic_time ();
  if (now - l->last_pause_log_us > PAUSE_LOG_US) {
    l->last_pause_log_us = now;
    g_warning ("HTTP: accepting paused for %d ms: %s (max-connections %u; see LimitNOFILE)", RESUME_MS,
               g_strerror (err), l->limits.max_connections);
  }
  if (l->accept_source) {
    g_source_destroy (l->accept_source);
    g_clear_pointer (&l->accept_source, g_source_unref);
  }
  l->resume_source = g_timeout_source_new (RESUME_MS);
  g_source_set_callback (l->resume_source, resume_accepting, l, NULL);
  g_source_attach (l->resume_source, g_main_context_get_thread_default ());
}

static gboolean
on_acceptable (GSocket *socket, GIOCondition condition, gpointer data)
{
  (void) socket;
  (void) condition;
  DsHttpListener *l = data;
  /* A few at a time: a burst of clients does not keep the loop from everything else. */
  for (guint i = 0; i < 32; i++) {
    int fd = accept4 (g_socket_get_fd (l->listen), NULL, NULL, SOCK_CLOEXEC | SOCK_NONBLOCK);
    if (fd >= 0) {
      take (l, fd);
      continue;
    }
    int err = errno;
    if (err == EINTR || err == ECONNABORTED || err == EPROTO)
      continue;
    if (err == EMFILE || err == ENFILE || err == ENOBUFS || err == ENOMEM) {
      pause_accepting (l, err);
      return G_SOURCE_REMOVE;
    }
    if (err != EAGAIN && err != EWOULDBLOCK)
      g_warning ("HTTP: accept: %s", g_strerror (err));
    break;
  }
  return G_SOURCE_CONTINUE;
}

static void
start_accepting (DsHttpListener *l)
{
  l->accept_source = g_socket_create_source (l->listen, G_IO_IN, NULL);
  g_source_set_callback (l->accept_source, (GSourceFunc) (void (*) (void)) on_acceptable, l, NULL);
  g_source_attach (l->accept_source, g_main_context_get_thread_default ());
}

static gboolean
sweep (gpointer data)
{
  DsHttpListener *l = data;
  gint64 now = g_get_monotonic_time ();
  GHashTableIter it;
  gpointer value;
  g_hash_table_iter_init (&it, l->conns);
  while (g_hash_table_iter_next (&it, NULL, &value)) {
    Conn *c = value;
    if (c->closing || c->state == UPGRADED || !c->input)
      continue;
    if (c->state == WAITING && ds_http_input_bytes (c->input) > c->mark) {
      c->state = READING;
      c->since_us = now;
    }
    guint limit_ms = c->state == WAITING ? l->limits.idle_timeout_ms : l->limits.header_timeout_ms;
    if (limit_ms && now - c->since_us > (gint64) limit_ms * 1000) {
      l->stats.timed_out++;
      if (c->state == READING)
        send_raw (c->socket, SOUP_STATUS_REQUEST_TIMEOUT, "408 the request took longer than header-timeout-ms\n");
      conn_shut (c);
    }
  }
  return G_SOURCE_CONTINUE;
}

/* ---- libsoup's view of each request ---- */

static void
on_got_headers (SoupServerMessage *msg, gpointer data)
{
  Conn *c = conn_of (data, msg);
  if (c && c->input)
    ds_http_input_set_limit (c->input, G_MAXUINT64, NULL); /* the body's limit is the server's */
}

static void
on_wrote_informational (SoupServerMessage *msg, gpointer data)
{
  Conn *c = conn_of (data, msg);
  if (c && soup_server_message_get_status (msg) == SOUP_STATUS_SWITCHING_PROTOCOLS)
    c->state = UPGRADED;
}

static void
on_finished (SoupServerMessage *msg, gpointer data)
{
  DsHttpListener *l = data;
  Conn *c = conn_of (l, msg);
  if (!c || !c->input || c->state == UPGRADED)
    return;
  c->state = WAITING;
  c->since_us = g_get_monotonic_time ();
  c->mark = ds_http_input_bytes (c->input);
  g_autofree char *what = g_strdup_printf ("request headers over %u bytes (max-header-bytes)", l->limits.max_header_bytes);
  ds_http_input_set_limit (c->input, c->mark + l->limits.max_header_bytes, what);
}

static void
on_request_started (SoupServer *soup, SoupServerMessage *msg, gpointer data)
{
  (void) soup;
  g_signal_connect (msg, "got-headers", G_CALLBACK (on_got_headers), data);
  g_signal_connect (msg, "wrote-informational", G_CALLBACK (on_wrote_informational), data);
  g_signal_connect (msg, "finished", G_CALLBACK (on_finished), data);
}

DsHttpListener *
ds_http_listener_new (SoupServer *soup, GInetAddress *addr, guint16 port, const DsHttpLimits *limits, GError **error)
{
  g_autoptr (GSocket) sock = g_socket_new (g_inet_address_get_family (addr), G_SOCKET_TYPE_STREAM,
                                           G_SOCKET_PROTOCOL_TCP, error);
  if (!sock)
    return NULL;
  g_socket_set_blocking (sock, FALSE);
  g_autoptr (GSocketAddress) sa = g_inet_socket_address_new (addr, port);
  if (!g_socket_bind (sock, sa, TRUE, error))
    return NULL;
  g_socket_set_listen_backlog (sock, 128);
  if (!g_socket_listen (sock, error))
    return NULL;
  g_autoptr (GSocketAddress) bound = g_socket_get_local_address (sock, error);
  if (!bound)
    return NULL;
  DsHttpListener *l = g_new0 (DsHttpListener, 1);
  l->soup = g_object_ref (soup);
  l->limits = *limits;
  l->listen = g_steal_pointer (&sock);
  l->port = g_inet_socket_address_get_port (G_INET_SOCKET_ADDRESS (bound));
  l->conns = g_hash_table_new_full (g_str_hash, g_str_equal, NULL, conn_free);
  l->peers = g_hash_table_new_full (g_str_hash, g_str_equal, g_free, NULL);
  g_signal_connect (soup, "request-started", G_CALLBACK (on_request_started), l);
  start_accepting (l);
  l->sweep = g_timeout_source_new (SWEEP_MS);
  g_source_set_callback (l->sweep, sweep, l, NULL);
  g_source_attach (l->sweep, g_main_context_get_thread_default ());
  return l;
}

void
ds_http_listener_free (DsHttpListener *l)
{
  if (!l)
    return;
  g_signal_handlers_disconnect_by_data (l->soup, l);
  GSource *sources[] = { l->accept_source, l->resume_source, l->sweep };
  for (guint i = 0; i < G_N_ELEMENTS (sources); i++)
    if (sources[i]) {
      g_source_destroy (sources[i]);
      g_source_unref (sources[i]);
    }
  g_socket_close (l->listen, NULL);
  g_object_unref (l->listen);
  /* Connections libsoup still holds outlive us: they no longer report to us. */
  g_hash_table_destroy (l->conns);
  g_hash_table_destroy (l->peers);
  g_object_unref (l->soup);
  g_free (l);
}

guint16
ds_http_listener_port (const DsHttpListener *l)
{
  return l->port;
}

GSocket *
ds_http_listener_socket (DsHttpListener *l, SoupServerMessage *msg)
{
  Conn *c = conn_of (l, msg);
  return c ? c->socket : NULL;
}

void
ds_http_listener_refuse (DsHttpListener *l, SoupServerMessage *msg, guint status, const char *text)
{
  Conn *c = conn_of (l, msg);
  if (!c || c->closing)
    return;
  send_raw (c->socket, status, text);
  conn_shut (c);
}

void
ds_http_listener_get_stats (const DsHttpListener *l, DsHttpListenerStats *stats)
{
  *stats = l->stats;
  stats->connections = g_hash_table_size (l->conns);
}
