#include "daemon/service/live_bridge.h"

#include <errno.h>
#include <gio/gunixsocketaddress.h>
#include <string.h>
#include <sys/socket.h>
#include <unistd.h>

#include "daemon/protocol/protocol.h"

/* The bridge's state lives as long as an asynchronous operation needs it: each holds a
 * reference, and ds_live_bridge_free only cancels and drops the owner's. */
struct DsLiveBridge {
  gint ref;
  GSocketConnection *conn;
  GDataInputStream *in;
  GOutputStream *out;
  GCancellable *cancel;
  GQueue lines;        /* char *, waiting to be written */
  gsize skip_left;     /* payload bytes of the last reply still to skip */
  gboolean writing;
  guint unanswered;    /* request lines written and not replied to yet */
  gboolean closed;     /* the daemon's side went away */
  DsLiveBridgeLineFunc on_line;
  gpointer user_data;
};

static DsLiveBridge *
bridge_ref (DsLiveBridge *b)
{
  b->ref++;
  return b;
}

static void
bridge_unref (DsLiveBridge *b)
{
  if (--b->ref > 0)
    return;
  g_queue_clear_full (&b->lines, g_free);
  g_object_unref (b->in);
  g_io_stream_close (G_IO_STREAM (b->conn), NULL, NULL);
  g_object_unref (b->conn);
  g_object_unref (b->cancel);
  g_free (b);
}

static void read_next (DsLiveBridge *b);
static void skip_next (DsLiveBridge *b);

static void
on_skipped (GObject *src, GAsyncResult *res, gpointer data)
{
  DsLiveBridge *b = data;
  g_autoptr (GError) error = NULL;
  gssize n = g_input_stream_skip_finish (G_INPUT_STREAM (src), res, &error);
  if (n > 0 && !g_cancellable_is_cancelled (b->cancel)) {
    b->skip_left -= MIN ((gsize) n, b->skip_left);
    if (b->skip_left)
      skip_next (b);
    else
      read_next (b);
  }
  bridge_unref (b);
}

/* The payloads follow the line; skipped in as many reads as the stream needs. */
static void
skip_next (DsLiveBridge *b)
{
  g_input_stream_skip_async (G_INPUT_STREAM (b->in), b->skip_left, G_PRIORITY_DEFAULT, b->cancel, on_skipped,
                             bridge_ref (b));
}

static void
on_line (GObject *src, GAsyncResult *res, gpointer data)
{
  DsLiveBridge *b = data;
  g_autoptr (GError) error = NULL;
  gsize len = 0;
  g_autofree char *line = g_data_input_stream_read_line_finish (G_DATA_INPUT_STREAM (src), res, &len, &error);
  if (!line)
    b->closed = TRUE;
  if (!line || g_cancellable_is_cancelled (b->cancel)) {
    bridge_unref (b);
    return;
  }
  g_autoptr (DsReply) reply = ds_reply_parse (line, len, NULL);
  gsize payload = 0;
  for (guint i = 0; reply && i < reply->n_payloads; i++)
    payload += reply->payloads[i].bytes;
  /* Every reply answers one request, in order, and the daemon says nothing else unasked but
   * events and, on a connection with no request waiting, why it closes it (idleness): a reply
   * while requests wait is the page's even without an id (a line refused before its id was
   * read). */
  gboolean is_reply = reply && !reply->event;
  gboolean for_page = reply && (reply->event || b->unanswered > 0);
  if (is_reply && b->unanswered > 0)
    b->unanswered--;
  if (for_page)
    b->on_line (line, b->user_data);
  b->skip_left = payload;
  if (payload > 0 && !g_cancellable_is_cancelled (b->cancel))
    skip_next (b);
  else if (!g_cancellable_is_cancelled (b->cancel))
    read_next (b);
  bridge_unref (b);
}

static void
read_next (DsLiveBridge *b)
{
  g_data_input_stream_read_line_async (b->in, G_PRIORITY_DEFAULT, b->cancel, on_line, bridge_ref (b));
}

static void write_next (DsLiveBridge *b);

static void
on_written (GObject *src, GAsyncResult *res, gpointer data)
{
  DsLiveBridge *b = data;
  g_autoptr (GError) error = NULL;
  gboolean ok = g_output_stream_write_all_finish (G_OUTPUT_STREAM (src), res, NULL, &error);
  g_free (g_queue_pop_head (&b->lines));
  b->writing = FALSE;
  if (ok && !g_cancellable_is_cancelled (b->cancel))
    write_next (b);
  bridge_unref (b);
}

static void
write_next (DsLiveBridge *b)
{
  const char *line = g_queue_peek_head (&b->lines);
  if (b->writing || !line)
    return;
  b->writing = TRUE;
  g_output_stream_write_all_async (b->out, line, strlen (line), G_PRIORITY_DEFAULT, b->cancel, on_written,
                                   bridge_ref (b));
}

static GSocketConnection *
connection_from_fd (int fd, GError **error)
{
  g_autoptr (GSocket) sock = g_socket_new_from_fd (fd, error);
  if (!sock) {
    close (fd);
    return NULL;
  }
  return g_socket_connection_factory_create_connection (sock);
}

DsLiveBridge *
ds_live_bridge_new (DsServer *server, DsLiveBridgeLineFunc on_line_func, gpointer user_data, GError **error)
{
  int fds[2];
  if (socketpair (AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0, fds) != 0) {
    int e = errno;
    g_set_error (error, G_IO_ERROR, g_io_error_from_errno (e), "live view controls: socketpair: %s", g_strerror (e));
    return NULL;
  }
  g_autoptr (GSocketConnection) daemon_side = connection_from_fd (fds[0], error);
  if (!daemon_side) {
    close (fds[1]);
    return NULL;
  }
  GSocketConnection *ours = connection_from_fd (fds[1], error);
  if (!ours)
    return NULL;
  ds_server_add_stream (server, G_IO_STREAM (daemon_side));
  DsLiveBridge *b = g_new0 (DsLiveBridge, 1);
  b->ref = 1;
  b->conn = ours;
  b->in = g_data_input_stream_new (g_io_stream_get_input_stream (G_IO_STREAM (ours)));
  g_data_input_stream_set_newline_type (b->in, G_DATA_STREAM_NEWLINE_TYPE_LF);
  b->out = g_io_stream_get_output_stream (G_IO_STREAM (ours));
  b->cancel = g_cancellable_new ();
  g_queue_init (&b->lines);
  b->on_line = on_line_func;
  b->user_data = user_data;
  read_next (b);
  return b;
}

void
ds_live_bridge_free (DsLiveBridge *b)
{
  if (!b)
    return;
  g_cancellable_cancel (b->cancel);
  bridge_unref (b);
}

gboolean
ds_live_bridge_is_open (const DsLiveBridge *b)
{
  return !b->closed;
}

void
ds_live_bridge_send (DsLiveBridge *b, const char *line)
{
  b->unanswered++;
  g_queue_push_tail (&b->lines, g_strconcat (line, "\n", NULL));
  write_next (b);
}
