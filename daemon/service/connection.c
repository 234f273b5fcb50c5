#include "daemon/service/connection.h"

#include <poll.h>
#include <string.h>

#define READ_CHUNK 16384

struct DsConnection {
  gint ref;
  GIOStream *stream;
  GInputStream *in;
  GOutputStream *out;
  GCancellable *cancel;
  GMainContext *context; /* where the connection was created and its callbacks run */
  DsConnectionLimits limits;
  DsConnectionLineFunc on_line;
  DsConnectionClosedFunc on_closed;
  gpointer user_data;
  gpointer data;
  GDestroyNotify data_destroy;

  guint8 read_buf[READ_CHUNK];
  GByteArray *line;        /* the line being assembled */
  gboolean discarding;     /* inside an over-long line, skipping to its newline */

  GQueue out_queue;        /* GBytes, in order */
  gsize queued;            /* bytes in out_queue */
  /* The message queued with ds_connection_send_newest whose writing has not begun (its first
   * chunk's link, its chunks and bytes), or NULL: the one a newer such message replaces. */
  GList *newest;
  guint newest_chunks;
  gsize newest_bytes;
  gint64 progress_us;      /* last write completed, or output queued into an empty queue */
  gboolean writing;
  gboolean close_after_flush;
  gboolean peer_eof;
  guint holds;
  gboolean closed;
  gboolean closed_notified;
  guint64 dropped;
};

DsConnection *
ds_connection_new (GIOStream *stream, const DsConnectionLimits *limits, DsConnectionLineFunc on_line,
                   DsConnectionClosedFunc on_closed, gpointer user_data)
{
  DsConnection *c = g_new0 (DsConnection, 1);
  c->ref = 1;
  c->stream = g_object_ref (stream);
  c->in = g_io_stream_get_input_stream (stream);
  c->out = g_io_stream_get_output_stream (stream);
  c->cancel = g_cancellable_new ();
  c->context = g_main_context_ref_thread_default ();
  c->limits = *limits;
  c->on_line = on_line;
  c->on_closed = on_closed;
  c->user_data = user_data;
  c->line = g_byte_array_new ();
  g_queue_init (&c->out_queue);
  return c;
}

DsConnection *
ds_connection_ref (DsConnection *conn)
{
  g_atomic_int_inc (&conn->ref);
  return conn;
}

void
ds_connection_unref (DsConnection *conn)
{
  if (!conn || !g_atomic_int_dec_and_test (&conn->ref))
    return;
  g_queue_clear_full (&conn->out_queue, (GDestroyNotify) g_bytes_unref);
  g_byte_array_unref (conn->line);
  if (conn->data_destroy)
    conn->data_destroy (conn->data);
  g_object_unref (conn->cancel);
  g_main_context_unref (conn->context);
  g_object_unref (conn->stream);
  g_free (conn);
}

void
ds_connection_set_data (DsConnection *conn, gpointer data, GDestroyNotify destroy)
{
  if (conn->data_destroy)
    conn->data_destroy (conn->data);
  conn->data = data;
  conn->data_destroy = destroy;
}

gpointer
ds_connection_get_data (DsConnection *conn)
{
  return conn->data;
}

gsize
ds_connection_queued_bytes (const DsConnection *conn)
{
  return conn->queued;
}

guint64
ds_connection_dropped (const DsConnection *conn)
{
  return conn->dropped;
}

gboolean
ds_connection_is_busy (const DsConnection *conn)
{
  return conn->holds > 0 || conn->writing || conn->queued > 0;
}

gint64
ds_connection_stalled_us (const DsConnection *conn)
{
  return conn->queued ? g_get_monotonic_time () - conn->progress_us : 0;
}

gboolean
ds_connection_has_unread_input (const DsConnection *conn)
{
  if (conn->closed || conn->peer_eof || !G_IS_SOCKET_CONNECTION (conn->stream))
    return FALSE;
  return g_socket_get_available_bytes (g_socket_connection_get_socket (G_SOCKET_CONNECTION (conn->stream))) > 0;
}

gboolean
ds_connection_peer_gone (const DsConnection *conn)
{
  if (conn->closed || ds_connection_is_busy (conn) || ds_connection_has_unread_input (conn) ||
      !G_IS_SOCKET_CONNECTION (conn->stream))
    return FALSE;
  if (conn->peer_eof)
    return TRUE;
  /* POLLRDHUP: the peer shut its side down, even with our EOF read still in flight. */
  struct pollfd pfd = { .fd = g_socket_get_fd (g_socket_connection_get_socket (G_SOCKET_CONNECTION (conn->stream))),
                        .events = POLLRDHUP };
  return poll (&pfd, 1, 0) == 1 && (pfd.revents & (POLLRDHUP | POLLHUP | POLLERR));
}

gboolean
ds_connection_is_closed (const DsConnection *conn)
{
  return conn->closed;
}

static gboolean
notify_closed_idle (gpointer data)
{
  DsConnection *c = data;
  if (!c->closed_notified) {
    c->closed_notified = TRUE;
    if (c->on_closed)
      c->on_closed (c, c->user_data);
  }
  return G_SOURCE_REMOVE;
}

void
ds_connection_close (DsConnection *conn)
{
  if (conn->closed)
    return;
  conn->closed = TRUE;
  g_cancellable_cancel (conn->cancel);
  g_queue_clear_full (&conn->out_queue, (GDestroyNotify) g_bytes_unref);
  conn->queued = 0;
  conn->newest = NULL;
  /* Closing the stream while an async op runs is refused by GIO; the cancelled ops finish
   * first, so the close itself is left to the last unref. The peer sees EOF through shutdown. */
  if (G_IS_SOCKET_CONNECTION (conn->stream))
    g_socket_shutdown (g_socket_connection_get_socket (G_SOCKET_CONNECTION (conn->stream)), TRUE,
                       TRUE, NULL);
  /* The connection's own context, not the global default: the server may run elsewhere. */
  g_autoptr (GSource) idle = g_idle_source_new ();
  g_source_set_priority (idle, G_PRIORITY_DEFAULT);
  g_source_set_callback (idle, notify_closed_idle, ds_connection_ref (conn),
                         (GDestroyNotify) ds_connection_unref);
  g_source_attach (idle, conn->context);
}

void
ds_connection_close_after_flush (DsConnection *conn)
{
  conn->close_after_flush = TRUE;
  if (!conn->writing && g_queue_is_empty (&conn->out_queue))
    ds_connection_close (conn);
}

static void write_next (DsConnection *conn);

void
ds_connection_hold (DsConnection *conn)
{
  conn->holds++;
}

void
ds_connection_release (DsConnection *conn)
{
  g_return_if_fail (conn->holds > 0);
  if (--conn->holds == 0 && conn->peer_eof && !conn->closed)
    ds_connection_close_after_flush (conn);
}

static void
write_done (GObject *source, GAsyncResult *res, gpointer data)
{
  DsConnection *c = data;
  g_autoptr (GError) error = NULL;
  gssize n = g_output_stream_write_bytes_finish (G_OUTPUT_STREAM (source), res, &error);
  c->writing = FALSE;
  if (n < 0 || c->closed) {
    if (!c->closed)
      ds_connection_close (c);
    ds_connection_unref (c);
    return;
  }
  GBytes *head = g_queue_pop_head (&c->out_queue);
  gsize size = g_bytes_get_size (head);
  c->queued -= (gsize) n;
  c->progress_us = g_get_monotonic_time ();
  if ((gsize) n < size) /* partial write: keep the rest at the head */
    g_queue_push_head (&c->out_queue, g_bytes_new_from_bytes (head, (gsize) n, size - (gsize) n));
  g_bytes_unref (head);
  write_next (c);
  ds_connection_unref (c);
}

static void
write_next (DsConnection *c)
{
  if (c->closed || c->writing)
    return;
  GList *link = g_queue_peek_head_link (&c->out_queue);
  if (!link) {
    if (c->close_after_flush)
      ds_connection_close (c);
    return;
  }
  GBytes *head = link->data;
  /* Its writing begins: from now on it is written whole, whatever comes after it. */
  if (link == c->newest)
    c->newest = NULL;
  c->writing = TRUE;
  g_output_stream_write_bytes_async (c->out, head, G_PRIORITY_DEFAULT, c->cancel, write_done,
                                     ds_connection_ref (c));
}

static gsize
message_bytes (GBytes *line, GBytes *const *payloads, guint n_payloads)
{
  gsize total = g_bytes_get_size (line);
  for (guint i = 0; i < n_payloads; i++)
    total += g_bytes_get_size (payloads[i]);
  return total;
}

/* Appends a message's chunks (empty payloads have none) and returns its first chunk's link. The
 * caller starts the writing (write_next). */
static GList *
push_message (DsConnection *conn, GBytes *line, GBytes *const *payloads, guint n_payloads, gsize total,
              guint *chunks)
{
  if (conn->queued == 0)
    conn->progress_us = g_get_monotonic_time ();
  g_queue_push_tail (&conn->out_queue, g_bytes_ref (line));
  GList *first = g_queue_peek_tail_link (&conn->out_queue);
  *chunks = 1;
  for (guint i = 0; i < n_payloads; i++)
    if (g_bytes_get_size (payloads[i]) > 0) {
      g_queue_push_tail (&conn->out_queue, g_bytes_ref (payloads[i]));
      (*chunks)++;
    }
  conn->queued += total;
  return first;
}

gboolean
ds_connection_send (DsConnection *conn, GBytes *line, GBytes *const *payloads, guint n_payloads,
                    gboolean droppable)
{
  if (conn->closed)
    return FALSE;
  gsize total = message_bytes (line, payloads, n_payloads);
  if (droppable && conn->queued + total > conn->limits.max_queued_bytes) {
    conn->dropped++;
    return FALSE;
  }
  if (!droppable && conn->queued + total > 2 * conn->limits.max_queued_bytes + total) {
    /* The client stopped reading its own replies: holding more would grow without bound. */
    ds_connection_close (conn);
    return FALSE;
  }
  guint chunks;
  push_message (conn, line, payloads, n_payloads, total, &chunks);
  write_next (conn);
  return TRUE;
}

gboolean
ds_connection_has_newest_waiting (const DsConnection *conn)
{
  return conn->newest != NULL;
}

/* Removes the waiting newest message, whole: none of its chunks has been handed to the stream
 * (write_next forgets it as soon as its first chunk is). */
static void
remove_newest (DsConnection *conn)
{
  GList *l = conn->newest;
  for (guint i = 0; i < conn->newest_chunks; i++) {
    GList *next = l->next;
    g_bytes_unref (l->data);
    g_queue_delete_link (&conn->out_queue, l);
    l = next;
  }
  conn->queued -= conn->newest_bytes;
  conn->newest = NULL;
  conn->dropped++;
}

gboolean
ds_connection_send_newest (DsConnection *conn, GBytes *line, GBytes *const *payloads, guint n_payloads)
{
  if (conn->closed)
    return FALSE;
  gsize total = message_bytes (line, payloads, n_payloads);
  gsize replaced = conn->newest ? conn->newest_bytes : 0;
  if (conn->queued - replaced + total > conn->limits.max_queued_bytes) {
    /* Even in the waiting one's place it would not fit: the waiting one stays. */
    conn->dropped++;
    return FALSE;
  }
  if (conn->newest)
    remove_newest (conn);
  guint chunks;
  conn->newest = push_message (conn, line, payloads, n_payloads, total, &chunks);
  conn->newest_chunks = chunks;
  conn->newest_bytes = total;
  write_next (conn); /* begins it at once when nothing was queued before it */
  return TRUE;
}

static void read_next (DsConnection *c);

static void
deliver (DsConnection *c, const guint8 *data, gsize n)
{
  gsize start = 0;
  for (gsize i = 0; i < n && !c->closed; i++) {
    if (data[i] != '\n')
      continue;
    if (c->discarding) {
      c->discarding = FALSE;
    } else if (c->line->len + (i - start) > c->limits.max_line + 1) {
      /* + 1: a CR before the newline does not count against the limit. */
      c->on_line (c, NULL, 0, TRUE, c->user_data);
    } else {
      g_byte_array_append (c->line, data + start, (guint) (i - start));
      gsize len = c->line->len;
      /* A CR before the newline is tolerated: telnet-style clients send CRLF. */
      if (len > 0 && c->line->data[len - 1] == '\r')
        len--;
      g_byte_array_append (c->line, (const guint8 *) "", 1); /* NUL for convenience */
      c->on_line (c, (const char *) c->line->data, len, FALSE, c->user_data);
    }
    g_byte_array_set_size (c->line, 0);
    start = i + 1;
  }
  if (c->closed || start >= n)
    return;
  if (c->discarding)
    return;
  g_byte_array_append (c->line, data + start, (guint) (n - start));
  if (c->line->len > c->limits.max_line + 1) {
    g_byte_array_set_size (c->line, 0);
    c->discarding = TRUE;
    c->on_line (c, NULL, 0, TRUE, c->user_data);
  }
}

static void
read_done (GObject *source, GAsyncResult *res, gpointer data)
{
  DsConnection *c = data;
  g_autoptr (GError) error = NULL;
  gssize n = g_input_stream_read_finish (G_INPUT_STREAM (source), res, &error);
  if (c->closed) {
    ds_connection_unref (c);
    return;
  }
  if (n < 0) {
    ds_connection_close (c);
    ds_connection_unref (c);
    return;
  }
  if (n == 0) {
    /* EOF may be a half-close: answer what was asked, then close. */
    c->peer_eof = TRUE;
    if (c->holds == 0)
      ds_connection_close_after_flush (c);
    ds_connection_unref (c);
    return;
  }
  deliver (c, c->read_buf, (gsize) n);
  read_next (c);
  ds_connection_unref (c);
}

static void
read_next (DsConnection *c)
{
  if (c->closed)
    return;
  g_input_stream_read_async (c->in, c->read_buf, sizeof c->read_buf, G_PRIORITY_DEFAULT, c->cancel,
                             read_done, ds_connection_ref (c));
}

void
ds_connection_start (DsConnection *conn)
{
  read_next (conn);
}
