#include "daemon/service/http_input.h"

#include <string.h>

struct _DsHttpInput {
  GInputStream parent;
  GSocketConnection *conn;
  GInputStream *base;
  guint64 bytes, limit;
  char *limit_what;
  gboolean cut;         /* the limit was reached: answered and shut down */
  gint64 last_read_us;
  DsHttpInputClosedFunc closed;
  gpointer closed_data;
};

static void ds_http_input_pollable_init (GPollableInputStreamInterface *iface);

G_DEFINE_TYPE_WITH_CODE (DsHttpInput, ds_http_input, G_TYPE_INPUT_STREAM,
                         G_IMPLEMENT_INTERFACE (G_TYPE_POLLABLE_INPUT_STREAM, ds_http_input_pollable_init))

/* At the limit the peer is told, and the socket shut down both ways: libsoup, after the read
 * error, would otherwise answer 500 and wait for a next request on the same connection. */
static void
cut (DsHttpInput *in)
{
  if (in->cut)
    return;
  in->cut = TRUE;
  GSocket *sock = g_socket_connection_get_socket (in->conn);
  const char *what = in->limit_what ? in->limit_what : "over the limit";
  g_autofree char *resp = g_strdup_printf ("HTTP/1.1 431 Request Header Fields Too Large\r\nContent-Type: text/plain; "
                                           "charset=utf-8\r\nContent-Length: %zu\r\nConnection: close\r\n\r\n431 %s\n",
                                           strlen (what) + 5, what);
  g_socket_send_with_blocking (sock, resp, strlen (resp), FALSE, NULL, NULL);
  g_socket_shutdown (sock, TRUE, TRUE, NULL);
}

/* The bytes a read may take now; FALSE (with the error) at the limit. */
static gboolean
allowance (DsHttpInput *in, gsize *count, GError **error)
{
  if (in->bytes >= in->limit) {
    cut (in);
    g_set_error (error, G_IO_ERROR, G_IO_ERROR_MESSAGE_TOO_LARGE, "%s", in->limit_what ? in->limit_what : "over the limit");
    return FALSE;
  }
  *count = (gsize) MIN ((guint64) *count, in->limit - in->bytes);
  return TRUE;
}

static gssize
account (DsHttpInput *in, gssize n)
{
  if (n > 0) {
    in->bytes += (guint64) n;
    in->last_read_us = g_get_monotonic_time ();
  }
  return n;
}

static gssize
input_read (GInputStream *stream, void *buffer, gsize count, GCancellable *cancellable, GError **error)
{
  DsHttpInput *in = DS_HTTP_INPUT (stream);
  if (!allowance (in, &count, error))
    return -1;
  return account (in, g_input_stream_read (in->base, buffer, count, cancellable, error));
}

static gssize
input_read_nonblocking (GPollableInputStream *stream, void *buffer, gsize count, GError **error)
{
  DsHttpInput *in = DS_HTTP_INPUT (stream);
  if (!allowance (in, &count, error))
    return -1;
  return account (in, g_pollable_input_stream_read_nonblocking (G_POLLABLE_INPUT_STREAM (in->base), buffer, count,
                                                                NULL, error));
}

static gboolean
input_is_readable (GPollableInputStream *stream)
{
  DsHttpInput *in = DS_HTTP_INPUT (stream);
  /* At the limit a read fails at once: readable, so that libsoup learns it. */
  return in->bytes >= in->limit || g_pollable_input_stream_is_readable (G_POLLABLE_INPUT_STREAM (in->base));
}

static GSource *
input_create_source (GPollableInputStream *stream, GCancellable *cancellable)
{
  DsHttpInput *in = DS_HTTP_INPUT (stream);
  g_autoptr (GSource) base = g_pollable_input_stream_create_source (G_POLLABLE_INPUT_STREAM (in->base), cancellable);
  return g_pollable_source_new_full (stream, base, cancellable);
}

static gboolean
input_can_poll (GPollableInputStream *stream)
{
  (void) stream;
  return TRUE;
}

static void
notify_closed (DsHttpInput *in)
{
  DsHttpInputClosedFunc f = in->closed;
  in->closed = NULL;
  if (f)
    f (in->closed_data);
}

static gboolean
input_close (GInputStream *stream, GCancellable *cancellable, GError **error)
{
  DsHttpInput *in = DS_HTTP_INPUT (stream);
  /* The socket input's own close does nothing: the connection's closes the descriptor. */
  gboolean ok = g_io_stream_close (G_IO_STREAM (in->conn), cancellable, error);
  notify_closed (in);
  return ok;
}

static void
input_finalize (GObject *object)
{
  DsHttpInput *in = DS_HTTP_INPUT (object);
  if (!g_io_stream_is_closed (G_IO_STREAM (in->conn)))
    g_io_stream_close (G_IO_STREAM (in->conn), NULL, NULL);
  notify_closed (in);
  g_object_unref (in->conn);
  g_free (in->limit_what);
  G_OBJECT_CLASS (ds_http_input_parent_class)->finalize (object);
}

static void
ds_http_input_class_init (DsHttpInputClass *klass)
{
  G_OBJECT_CLASS (klass)->finalize = input_finalize;
  G_INPUT_STREAM_CLASS (klass)->read_fn = input_read;
  G_INPUT_STREAM_CLASS (klass)->close_fn = input_close;
}

static void
ds_http_input_pollable_init (GPollableInputStreamInterface *iface)
{
  iface->can_poll = input_can_poll;
  iface->is_readable = input_is_readable;
  iface->create_source = input_create_source;
  iface->read_nonblocking = input_read_nonblocking;
}

static void
ds_http_input_init (DsHttpInput *in)
{
  in->limit = G_MAXUINT64;
}

DsHttpInput *
ds_http_input_new (GSocketConnection *conn, DsHttpInputClosedFunc closed, gpointer user_data)
{
  DsHttpInput *in = g_object_new (DS_TYPE_HTTP_INPUT, NULL);
  in->conn = g_object_ref (conn);
  in->base = g_io_stream_get_input_stream (G_IO_STREAM (conn));
  in->closed = closed;
  in->closed_data = user_data;
  return in;
}

void
ds_http_input_forget (DsHttpInput *in)
{
  in->closed = NULL;
}

guint64
ds_http_input_bytes (const DsHttpInput *in)
{
  return in->bytes;
}

gint64
ds_http_input_last_read_us (const DsHttpInput *in)
{
  return in->last_read_us;
}

void
ds_http_input_set_limit (DsHttpInput *in, guint64 limit, const char *what)
{
  in->limit = limit;
  g_free (in->limit_what);
  in->limit_what = g_strdup (what);
}
