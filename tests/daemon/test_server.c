/* The socket server over real UNIX and TCP sockets: framing, limits, subscriptions, slow
 * subscribers, authentication. The server runs in its own thread and main context, the test
 * drives plain blocking sockets, as a client program would. */
#include "daemon/service/server.h"

#include <gio/gunixsocketaddress.h>
#include <glib/gstdio.h>
#include <string.h>
#include <sys/socket.h>

typedef struct {
  GMainContext *ctx;
  GMainLoop *loop;
  GThread *thread;
  DsServer *server;
  char *dir, *path;
  DsServerLimits limits;
  gboolean tcp;
  guint16 port;
  GMutex lock;
  GCond cond;
  gboolean ready;
  guint handled;
} Harness;

/* The daemon's command layer stand-in: "echo" answers its args with a payload of given size. */
static void
on_request (DsServer *server, DsConnection *conn, DsRequest *req, gpointer user_data)
{
  Harness *h = user_data;
  h->handled++;
  if (strcmp (req->cmd, "echo") != 0) {
    g_autoptr (GError) e = g_error_new (DS_PROTOCOL_ERROR, DS_PROTOCOL_ERROR_UNKNOWN_COMMAND,
                                        "unknown command \"%s\"", req->cmd);
    ds_server_reply_error (server, conn, req->id, e);
    return;
  }
  g_autoptr (JsonNode) args = json_node_new (JSON_NODE_OBJECT);
  json_node_set_object (args, req->args);
  ds_server_reply_ok (server, conn, req->id, args, NULL, NULL, 0);
}

static gpointer
server_main (gpointer data)
{
  Harness *h = data;
  g_main_context_push_thread_default (h->ctx);
  h->server = ds_server_new (&h->limits, on_request, h);
  g_autoptr (GError) error = NULL;
  if (h->tcp) {
    g_assert_true (ds_server_listen_tcp (h->server, "127.0.0.1", 0, &error));
    h->port = ds_server_tcp_port (h->server);
  } else {
    g_assert_true (ds_server_listen_unix (h->server, h->path, 0660, &error));
  }
  g_assert_no_error (error);
  g_mutex_lock (&h->lock);
  h->ready = TRUE;
  g_cond_broadcast (&h->cond);
  g_mutex_unlock (&h->lock);
  g_main_loop_run (h->loop);
  ds_server_free (h->server);
  /* Let closing connections finish their idle callbacks before the context goes. */
  while (g_main_context_iteration (h->ctx, FALSE))
    ;
  g_main_context_pop_thread_default (h->ctx);
  return NULL;
}

static Harness *
harness_start (gboolean tcp, const char *token, guint max_clients, gsize max_queued)
{
  Harness *h = g_new0 (Harness, 1);
  h->dir = g_dir_make_tmp ("ds-server-XXXXXX", NULL);
  h->path = g_build_filename (h->dir, "d.sock", NULL);
  h->limits.max_clients = max_clients;
  h->limits.max_line = 1024;
  h->limits.max_queued_bytes = max_queued;
  h->limits.token = (char *) token;
  /* Nobody is displaced to make room in these tests (test_connections.c covers that). */
  h->limits.evict_quiet_ms = 600000;
  h->tcp = tcp;
  h->ctx = g_main_context_new ();
  h->loop = g_main_loop_new (h->ctx, FALSE);
  g_mutex_init (&h->lock);
  g_cond_init (&h->cond);
  h->thread = g_thread_new ("server", server_main, h);
  g_mutex_lock (&h->lock);
  while (!h->ready)
    g_cond_wait (&h->cond, &h->lock);
  g_mutex_unlock (&h->lock);
  return h;
}

static gboolean
quit_loop (gpointer data)
{
  g_main_loop_quit (data);
  return G_SOURCE_REMOVE;
}

static void
harness_stop (Harness *h)
{
  g_main_context_invoke (h->ctx, quit_loop, h->loop);
  g_thread_join (h->thread);
  g_main_loop_unref (h->loop);
  g_main_context_unref (h->ctx);
  g_assert_false (g_file_test (h->path, G_FILE_TEST_EXISTS)); /* socket file removed */
  g_rmdir (h->dir);
  g_free (h->dir);
  g_free (h->path);
  g_mutex_clear (&h->lock);
  g_cond_clear (&h->cond);
  g_free (h);
}

typedef struct {
  Harness *h;
  GMutex lock;
  GCond cond;
  gboolean done;
  GSourceFunc fn;
  gpointer data;
  guint result;
} Call;

static gboolean
call_in_server (gpointer data)
{
  Call *c = data;
  c->result = (guint) c->fn (c->data);
  g_mutex_lock (&c->lock);
  c->done = TRUE;
  g_cond_signal (&c->cond);
  g_mutex_unlock (&c->lock);
  return G_SOURCE_REMOVE;
}

/* Runs fn on the server thread and waits for it. */
static guint
harness_call (Harness *h, GSourceFunc fn, gpointer data)
{
  Call c = { .h = h, .fn = fn, .data = data };
  g_mutex_init (&c.lock);
  g_cond_init (&c.cond);
  g_main_context_invoke (h->ctx, call_in_server, &c);
  g_mutex_lock (&c.lock);
  while (!c.done)
    g_cond_wait (&c.cond, &c.lock);
  g_mutex_unlock (&c.lock);
  g_mutex_clear (&c.lock);
  g_cond_clear (&c.cond);
  return c.result;
}

typedef struct {
  GSocketConnection *conn;
  GDataInputStream *in;
  GOutputStream *out;
} Client;

static Client *
client_connect (Harness *h)
{
  g_autoptr (GSocketClient) sc = g_socket_client_new ();
  g_autoptr (GSocketAddress) addr = h->tcp
    ? g_inet_socket_address_new_from_string ("127.0.0.1", h->port)
    : g_unix_socket_address_new (h->path);
  g_autoptr (GError) error = NULL;
  Client *c = g_new0 (Client, 1);
  c->conn = g_socket_client_connect (sc, G_SOCKET_CONNECTABLE (addr), NULL, &error);
  g_assert_no_error (error);
  c->in = g_data_input_stream_new (g_io_stream_get_input_stream (G_IO_STREAM (c->conn)));
  g_buffered_input_stream_set_buffer_size (G_BUFFERED_INPUT_STREAM (c->in), 1 << 20);
  c->out = g_io_stream_get_output_stream (G_IO_STREAM (c->conn));
  return c;
}

static void
client_free (Client *c)
{
  g_object_unref (c->in);
  g_object_unref (c->conn);
  g_free (c);
}

static void
client_send (Client *c, const char *text)
{
  g_autoptr (GError) error = NULL;
  g_assert_true (g_output_stream_write_all (c->out, text, strlen (text), NULL, NULL, &error));
  g_assert_no_error (error);
}

/* Reads one message; NULL at EOF. Payload bytes are read and returned concatenated. */
static DsReply *
client_read (Client *c, GBytes **payload)
{
  gsize len = 0;
  g_autoptr (GError) error = NULL;
  g_autofree char *line = g_data_input_stream_read_line (c->in, &len, NULL, &error);
  if (!line)
    return NULL;
  DsReply *r = ds_reply_parse (line, len, &error);
  g_assert_no_error (error);
  gsize total = 0;
  for (guint i = 0; i < r->n_payloads; i++)
    total += r->payloads[i].bytes;
  g_autofree guint8 *buf = g_malloc (total + 1);
  gsize got = 0;
  g_assert_true (g_input_stream_read_all (G_INPUT_STREAM (c->in), buf, total, &got, NULL, &error));
  g_assert_cmpuint (got, ==, total);
  if (payload)
    *payload = g_bytes_new (buf, total);
  return r;
}

static void
test_hello_and_errors_keep_sync (void)
{
  Harness *h = harness_start (FALSE, NULL, 8, 1 << 20);
  Client *c = client_connect (h);
  client_send (c, "{\"id\":1,\"cmd\":\"hello\"}\n");
  g_autoptr (DsReply) r1 = client_read (c, NULL);
  g_assert_true (r1->ok);
  g_assert_cmpint (json_object_get_int_member (json_node_get_object (r1->body), "protocol"), ==,
                   DS_PROTOCOL_VERSION);
  /* Malformed, too deep, over-long and unknown requests each get their error, in order, and the
   * connection keeps working. */
  client_send (c, "{broken\n");
  g_autoptr (DsReply) r2 = client_read (c, NULL);
  g_assert_false (r2->ok);
  g_assert_cmpint (r2->error_code, ==, DS_PROTOCOL_ERROR_BAD_JSON);
  g_autofree char *big = g_strnfill (5000, 'x');
  client_send (c, big);
  client_send (c, "\n{\"id\":\"after\",\"cmd\":\"nope\"}\r\n");
  g_autoptr (DsReply) r3 = client_read (c, NULL);
  g_assert_cmpint (r3->error_code, ==, DS_PROTOCOL_ERROR_LINE_TOO_LONG);
  g_autoptr (DsReply) r4 = client_read (c, NULL);
  g_assert_cmpint (r4->error_code, ==, DS_PROTOCOL_ERROR_UNKNOWN_COMMAND);
  g_assert_cmpstr (json_node_get_string (r4->id), ==, "after");
  client_send (c, "{\"id\":5,\"cmd\":\"echo\",\"args\":{\"v\":42}}\n");
  g_autoptr (DsReply) r5 = client_read (c, NULL);
  g_assert_true (r5->ok);
  g_assert_cmpint (json_object_get_int_member (json_node_get_object (r5->body), "v"), ==, 42);
  client_free (c);
  harness_stop (h);
}

static void
test_half_close_still_answered (void)
{
  Harness *h = harness_start (FALSE, NULL, 8, 1 << 20);
  Client *c = client_connect (h);
  client_send (c, "{\"id\":1,\"cmd\":\"echo\",\"args\":{\"a\":1}}\n");
  g_assert_true (g_socket_shutdown (g_socket_connection_get_socket (c->conn), FALSE, TRUE, NULL));
  g_autoptr (DsReply) r = client_read (c, NULL);
  g_assert_nonnull (r);
  g_assert_true (r->ok);
  g_assert_null (client_read (c, NULL)); /* then EOF */
  client_free (c);
  harness_stop (h);
}

typedef struct {
  Harness *h;
  gsize bytes;
  guint8 fill;
} Publish;

static gboolean
do_publish (gpointer data)
{
  Publish *p = data;
  guint8 *buf = g_malloc (p->bytes);
  memset (buf, p->fill, p->bytes);
  g_autoptr (GBytes) payload = g_bytes_new_take (buf, p->bytes);
  DsPayloadInfo info = { "transmissive", "u8", (guint) p->bytes, 1, p->bytes };
  GBytes *pl[] = { payload };
  return (gboolean) ds_server_publish (p->h->server, "result", NULL, &info, pl, 1);
}

typedef struct {
  Harness *h;
  DsServerStats stats;
} StatsCall;

static gboolean
do_stats (gpointer data)
{
  StatsCall *s = data;
  ds_server_get_stats (s->h->server, &s->stats);
  return TRUE;
}

/* Asks the server's loop for its stats until done () holds or `seconds` pass (a bound for a hang,
 * not a timing: the loop runs on its own thread, and a loaded machine can take seconds); the
 * caller asserts on sc->stats. */
static void
wait_stats (StatsCall *sc, gboolean (*done) (const DsServerStats *), double seconds)
{
  gint64 deadline = g_get_monotonic_time () + (gint64) (seconds * G_USEC_PER_SEC);
  for (;;) {
    harness_call (sc->h, do_stats, sc);
    if (done (&sc->stats) || g_get_monotonic_time () >= deadline)
      return;
    g_usleep (2000);
  }
}

static gboolean
queue_drained (const DsServerStats *st)
{
  return st->queued_bytes == 0;
}

static gboolean
one_client (const DsServerStats *st)
{
  return st->clients == 1;
}

static void
test_slow_subscriber_loses_results_not_memory (void)
{
  const gsize cap = 256 * 1024, event = 64 * 1024;
  Harness *h = harness_start (FALSE, NULL, 8, cap);
  Client *fast = client_connect (h), *slow = client_connect (h);
  client_send (fast, "{\"id\":1,\"cmd\":\"subscribe\"}\n");
  client_send (slow, "{\"id\":1,\"cmd\":\"subscribe\"}\n");
  g_autoptr (DsReply) a = client_read (fast, NULL);
  g_autoptr (DsReply) b = client_read (slow, NULL);
  g_assert_true (a->ok && b->ok);
  /* Shrink the slow client's receive buffer so the kernel cannot absorb the backlog for it. */
  int small = 4096;
  setsockopt (g_socket_get_fd (g_socket_connection_get_socket (slow->conn)), SOL_SOCKET, SO_RCVBUF,
              &small, sizeof small);
  const guint n_events = 64;
  guint64 last_seq = 0;
  for (guint i = 0; i < n_events; i++) {
    Publish p = { .h = h, .bytes = event, .fill = (guint8) i };
    guint delivered = harness_call (h, do_publish, &p);
    g_assert_cmpuint (delivered, >=, 1); /* the fast client always gets it */
    GBytes *payload = NULL;
    g_autoptr (DsReply) ev = client_read (fast, &payload);
    g_assert_cmpstr (ev->event, ==, "result");
    g_assert_cmpuint (ev->seq, ==, last_seq + 1);
    last_seq = ev->seq;
    gsize n;
    const guint8 *d = g_bytes_get_data (payload, &n);
    g_assert_cmpuint (n, ==, event);
    g_assert_cmpuint (d[0], ==, (guint8) i);
    g_assert_cmpuint (d[n - 1], ==, (guint8) i);
    g_bytes_unref (payload);
    StatsCall sc = { .h = h };
    harness_call (h, do_stats, &sc);
    /* Memory held for any one client never exceeds its cap (the fast client's queue may lag
     * its reads by one write completion, so the total is not the measure). */
    g_assert_cmpuint (sc.stats.max_client_queued_bytes, <=, cap);
    g_assert_cmpuint (sc.stats.queued_bytes, <=, 2 * cap);
  }
  StatsCall sc = { .h = h };
  harness_call (h, do_stats, &sc);
  g_assert_cmpuint (sc.stats.dropped, >, 0);
  g_assert_cmpuint (sc.stats.subscribers, ==, 2);
  /* The slow client, once it reads, sees whole events with gaps in seq, never torn data. */
  guint64 prev = 0, seen = 0;
  for (;;) {
    GBytes *payload = NULL;
    /* Only what was queued remains; stop when the queued backlog is drained. */
    harness_call (h, do_stats, &sc);
    if (sc.stats.queued_bytes == 0 && !g_input_stream_has_pending (G_INPUT_STREAM (slow->in))) {
      gsize avail = g_buffered_input_stream_get_available (G_BUFFERED_INPUT_STREAM (slow->in));
      GSocket *sock = g_socket_connection_get_socket (slow->conn);
      if (avail == 0 && !g_socket_condition_timed_wait (sock, G_IO_IN, 200000, NULL, NULL))
        break;
    }
    g_autoptr (DsReply) ev = client_read (slow, &payload);
    g_assert_nonnull (ev);
    g_assert_cmpuint (ev->seq, >, prev);
    gsize n;
    const guint8 *d = g_bytes_get_data (payload, &n);
    g_assert_cmpuint (n, ==, event);
    g_assert_cmpuint (d[0], ==, (guint8) (ev->seq - 1));
    g_assert_cmpuint (d[n - 1], ==, (guint8) (ev->seq - 1));
    g_bytes_unref (payload);
    prev = ev->seq;
    seen++;
  }
  g_assert_cmpuint (seen + sc.stats.dropped, ==, n_events);
  g_assert_cmpuint (seen, <, n_events);
  client_free (fast);
  client_free (slow);
  harness_stop (h);
}

typedef struct {
  Harness *h;
  gsize bytes;
  guint8 fill;
  gboolean result; /* a per-frame result (newest only), else a `device` event */
} PublishNewest;

static gboolean
do_publish_newest (gpointer data)
{
  PublishNewest *p = data;
  if (!p->result)
    return (gboolean) ds_server_publish (p->h->server, "device", NULL, NULL, NULL, 0);
  guint8 *buf = g_malloc (p->bytes);
  memset (buf, p->fill, p->bytes);
  g_autoptr (GBytes) payload = g_bytes_new_take (buf, p->bytes);
  DsPayloadInfo info = { "transmissive", "u8", 1024, (guint) (p->bytes / 1024), p->bytes };
  GBytes *pl[] = { payload };
  g_autoptr (JsonBuilder) b = json_builder_new ();
  json_builder_begin_object (b);
  json_builder_set_member_name (b, "n");
  json_builder_add_int_value (b, p->fill);
  json_builder_end_object (b);
  g_autoptr (JsonNode) body = json_builder_get_root (b);
  return (gboolean) ds_server_publish_result (p->h->server, body, &info, pl, 1, TRUE);
}

/* Per-frame results to a client that does not read: it is sent the result being written when it
 * stopped reading and the newest, whole, with `skipped` the results in between; an event
 * published meanwhile keeps its place; the memory held for it stays at two results whatever the
 * number published. A client that reads each one gets every one, skipped 0. */
static void
test_newest_result (void)
{
  /* Larger than the socket's buffer many times over: a result stays in the middle of being
   * written while the client does not read. */
  gsize size = 512 * 1024;
  g_autofree char *wmem = NULL;
  if (g_file_get_contents ("/proc/sys/net/core/wmem_default", &wmem, NULL, NULL))
    size = MAX (size, (g_ascii_strtoull (wmem, NULL, 10) * 4 + 1023) / 1024 * 1024);
  const gsize cap = 64 << 20;
  Harness *h = harness_start (FALSE, NULL, 8, cap);
  Client *fast = client_connect (h), *slow = client_connect (h);
  client_send (fast, "{\"id\":1,\"cmd\":\"subscribe\"}\n");
  client_send (slow, "{\"id\":1,\"cmd\":\"subscribe\"}\n");
  g_autoptr (DsReply) a = client_read (fast, NULL);
  g_autoptr (DsReply) b = client_read (slow, NULL);
  g_assert_true (a->ok && b->ok);
  const guint n_results = 40, event_after = 10;
  guint64 seq = 0;
  for (guint i = 0; i < n_results; i++) {
    PublishNewest p = { .h = h, .bytes = size, .fill = (guint8) i, .result = TRUE };
    g_assert_cmpuint (harness_call (h, do_publish_newest, &p), ==, 2);
    GBytes *payload = NULL;
    g_autoptr (DsReply) ev = client_read (fast, &payload);
    g_assert_cmpstr (ev->event, ==, "result");
    g_assert_cmpuint (ev->seq, ==, ++seq);
    g_assert_cmpuint (ev->skipped, ==, 0);
    gsize n;
    const guint8 *d = g_bytes_get_data (payload, &n);
    g_assert_cmpuint (n, ==, size);
    g_assert_cmpuint (d[0], ==, i);
    g_assert_cmpuint (d[n - 1], ==, i);
    g_bytes_unref (payload);
    if (i == event_after) {
      PublishNewest e = { .h = h };
      g_assert_cmpuint (harness_call (h, do_publish_newest, &e), ==, 2);
      g_autoptr (DsReply) dev = client_read (fast, NULL);
      g_assert_cmpstr (dev->event, ==, "device");
      g_assert_cmpuint (dev->seq, ==, ++seq);
    }
    StatsCall sc = { .h = h };
    harness_call (h, do_stats, &sc);
    /* The slow client: the result being written and the newest, line and all. */
    g_assert_cmpuint (sc.stats.max_client_queued_bytes, <=, 2 * (size + 1024));
  }
  /* seq: results 0..10 are 1..11, the event 12, results 11..39 are 13..41. Result 0 went out at
   * once; the event stays behind the result waiting then (10), which a newer one replaced; the
   * last one waits. */
  struct {
    const char *event;
    guint64 seq, skipped;
    gint fill;
  } want[] = { { "result", 1, 0, 0 }, { "device", 12, 0, -1 }, { "result", 41, n_results - 2, n_results - 1 } };
  for (guint k = 0; k < G_N_ELEMENTS (want); k++) {
    GBytes *payload = NULL;
    g_autoptr (DsReply) ev = client_read (slow, &payload);
    g_assert_nonnull (ev);
    g_assert_cmpstr (ev->event, ==, want[k].event);
    g_assert_cmpuint (ev->seq, ==, want[k].seq);
    g_assert_cmpuint (ev->skipped, ==, want[k].skipped);
    gsize n;
    const guint8 *d = g_bytes_get_data (payload, &n);
    if (want[k].fill >= 0) {
      g_assert_cmpuint (n, ==, size);
      g_assert_cmpint (json_object_get_int_member (json_node_get_object (ev->body), "n"), ==, want[k].fill);
      for (gsize j = 0; j < n; j += 4096)
        g_assert_cmpuint (d[j], ==, (guint8) want[k].fill);
      g_assert_cmpuint (d[n - 1], ==, (guint8) want[k].fill);
    } else {
      g_assert_cmpuint (n, ==, 0);
    }
    g_bytes_unref (payload);
  }
  /* The client can read a write's last byte before the server's loop runs that write's
   * completion, which is when the bytes leave the queue: wait for the loop, not a clock. */
  StatsCall sc = { .h = h };
  wait_stats (&sc, queue_drained, 10);
  g_assert_cmpuint (sc.stats.dropped, ==, n_results - 2);
  g_assert_cmpuint (sc.stats.queued_bytes, ==, 0);
  /* Nothing else was queued for it. */
  GSocket *sock = g_socket_connection_get_socket (slow->conn);
  g_assert_cmpuint (g_buffered_input_stream_get_available (G_BUFFERED_INPUT_STREAM (slow->in)), ==, 0);
  g_assert_false (g_socket_condition_timed_wait (sock, G_IO_IN, 200000, NULL, NULL));
  client_free (fast);
  client_free (slow);
  harness_stop (h);
}

static void
test_client_limit (void)
{
  Harness *h = harness_start (FALSE, NULL, 2, 1 << 20);
  Client *a = client_connect (h), *b = client_connect (h);
  client_send (a, "{\"cmd\":\"hello\"}\n");
  client_send (b, "{\"cmd\":\"hello\"}\n");
  g_autoptr (DsReply) ra = client_read (a, NULL);
  g_autoptr (DsReply) rb = client_read (b, NULL);
  Client *c = client_connect (h);
  g_autoptr (DsReply) rc = client_read (c, NULL);
  g_assert_false (rc->ok);
  g_assert_cmpint (rc->error_code, ==, DS_PROTOCOL_ERROR_LIMIT);
  g_assert_null (client_read (c, NULL));
  client_free (c);
  /* A place freed is a place available again. */
  client_free (a);
  /* The server's loop frees the place when it reads the EOF, on its own thread: asked until it
   * has (a bound for a hang, not a timing: a loaded machine can take seconds). */
  StatsCall sc = { .h = h };
  wait_stats (&sc, one_client, 30);
  g_assert_cmpuint (sc.stats.clients, ==, 1);
  Client *d = client_connect (h);
  client_send (d, "{\"cmd\":\"hello\"}\n");
  g_autoptr (DsReply) rd = client_read (d, NULL);
  g_assert_true (rd->ok);
  client_free (b);
  client_free (d);
  harness_stop (h);
}

static void
test_tcp_token (void)
{
  Harness *h = harness_start (TRUE, "s3cret-token", 8, 1 << 20);
  Client *c = client_connect (h);
  client_send (c, "{\"id\":1,\"cmd\":\"echo\"}\n");
  g_autoptr (DsReply) r1 = client_read (c, NULL);
  g_assert_cmpint (r1->error_code, ==, DS_PROTOCOL_ERROR_UNAUTHORIZED);
  /* A token of another type is refused as such, not compared as an empty string. */
  client_send (c, "{\"id\":1,\"cmd\":\"hello\",\"args\":{\"token\":12345678901234567}}\n");
  g_autoptr (DsReply) r0 = client_read (c, NULL);
  g_assert_cmpint (r0->error_code, ==, DS_PROTOCOL_ERROR_BAD_ARGUMENT);
  client_send (c, "{\"id\":2,\"cmd\":\"hello\",\"args\":{\"token\":\"s3cret-tokeX\"}}\n");
  g_autoptr (DsReply) r2 = client_read (c, NULL);
  g_assert_cmpint (r2->error_code, ==, DS_PROTOCOL_ERROR_UNAUTHORIZED);
  g_assert_null (client_read (c, NULL)); /* closed after a wrong token */
  client_free (c);
  Client *d = client_connect (h);
  client_send (d, "{\"id\":3,\"cmd\":\"hello\",\"args\":{\"token\":\"s3cret-token\"}}\n");
  g_autoptr (DsReply) r3 = client_read (d, NULL);
  g_assert_true (r3->ok);
  client_send (d, "{\"id\":4,\"cmd\":\"echo\"}\n");
  g_autoptr (DsReply) r4 = client_read (d, NULL);
  g_assert_true (r4->ok);
  client_free (d);
  harness_stop (h);
}

static void
test_listen_refusals (void)
{
  DsServerLimits limits = { .max_clients = 4, .max_queued_bytes = 1024 };
  g_autoptr (DsServer) s = ds_server_new (&limits, on_request, NULL);
  g_autoptr (GError) error = NULL;
  /* Not loopback and no token: refused before binding anything. */
  g_assert_false (ds_server_listen_tcp (s, "0.0.0.0", 0, &error));
  g_assert_error (error, G_IO_ERROR, G_IO_ERROR_PERMISSION_DENIED);
  g_clear_error (&error);
  g_assert_false (ds_server_listen_tcp (s, "localhost-ish", 0, &error));
  g_clear_error (&error);
  /* A regular file where the socket should go is never replaced. */
  g_autofree char *dir = g_dir_make_tmp ("ds-server-XXXXXX", NULL);
  g_autofree char *path = g_build_filename (dir, "not-a-socket", NULL);
  g_assert_true (g_file_set_contents (path, "keep me", -1, NULL));
  g_assert_false (ds_server_listen_unix (s, path, 0660, &error));
  g_assert_error (error, G_IO_ERROR, G_IO_ERROR_EXISTS);
  g_autofree char *contents = NULL;
  g_assert_true (g_file_get_contents (path, &contents, NULL, NULL));
  g_assert_cmpstr (contents, ==, "keep me");
  g_unlink (path);
  g_rmdir (dir);
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  g_test_add_func ("/server/hello-and-errors-keep-sync", test_hello_and_errors_keep_sync);
  g_test_add_func ("/server/half-close", test_half_close_still_answered);
  g_test_add_func ("/server/slow-subscriber", test_slow_subscriber_loses_results_not_memory);
  g_test_add_func ("/server/newest-result", test_newest_result);
  g_test_add_func ("/server/client-limit", test_client_limit);
  g_test_add_func ("/server/tcp-token", test_tcp_token);
  g_test_add_func ("/server/listen-refusals", test_listen_refusals);
  return g_test_run ();
}
