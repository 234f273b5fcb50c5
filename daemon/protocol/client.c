#include "daemon/protocol/client.h"

#include <string.h>

#include "daemon/protocol/json_text.h"

struct DsClient {
  GSocketConnection *conn;
  GDataInputStream *in;
  GOutputStream *out;
  guint64 next_id;
};

DsClient *
ds_client_connect (const char *address, GError **error)
{
  g_autoptr (GSocketAddress) addr = NULL;
  if (g_str_has_prefix (address, "tcp:")) {
    const char *hp = address + 4;
    const char *colon = strrchr (hp, ':');
    guint64 port;
    if (!colon || !g_ascii_string_to_unsigned (colon + 1, 10, 1, 65535, &port, NULL)) {
      g_set_error (error, G_IO_ERROR, G_IO_ERROR_INVALID_ARGUMENT,
                   "address \"%s\": expected tcp:HOST:PORT", address);
      return NULL;
    }
    g_autofree char *host = g_strndup (hp, (gsize) (colon - hp));
    g_autoptr (GInetAddress) ia = g_inet_address_new_from_string (host);
    if (!ia) {
      g_set_error (error, G_IO_ERROR, G_IO_ERROR_INVALID_ARGUMENT,
                   "address \"%s\": %s is not a numeric IP address", address, host);
      return NULL;
    }
    addr = g_inet_socket_address_new (ia, (guint16) port);
  } else {
    const char *path = g_str_has_prefix (address, "unix:") ? address + 5 : address;
    addr = g_unix_socket_address_new (path);
  }
  g_autoptr (GSocketClient) sc = g_socket_client_new ();
  GSocketConnection *conn = g_socket_client_connect (sc, G_SOCKET_CONNECTABLE (addr), NULL, error);
  if (!conn) {
    g_prefix_error (error, "connecting to %s: ", address);
    return NULL;
  }
  DsClient *c = g_new0 (DsClient, 1);
  c->conn = conn;
  c->in = g_data_input_stream_new (g_io_stream_get_input_stream (G_IO_STREAM (conn)));
  g_buffered_input_stream_set_buffer_size (G_BUFFERED_INPUT_STREAM (c->in), 1 << 20);
  c->out = g_io_stream_get_output_stream (G_IO_STREAM (conn));
  return c;
}

void
ds_client_free (DsClient *c)
{
  if (!c)
    return;
  g_clear_object (&c->in);
  g_io_stream_close (G_IO_STREAM (c->conn), NULL, NULL);
  g_clear_object (&c->conn);
  g_free (c);
}

void
ds_message_free (DsMessage *m)
{
  if (!m)
    return;
  if (m->payloads) {
    for (guint i = 0; m->reply && i < m->reply->n_payloads; i++)
      if (m->payloads[i])
        g_bytes_unref (m->payloads[i]);
    g_free (m->payloads);
  }
  ds_reply_free (m->reply);
  g_free (m);
}

DsMessage *
ds_client_read (DsClient *c, guint timeout_ms, GError **error)
{
  GSocket *sock = g_socket_connection_get_socket (c->conn);
  if (timeout_ms && g_buffered_input_stream_get_available (G_BUFFERED_INPUT_STREAM (c->in)) == 0 &&
      !g_socket_condition_timed_wait (sock, G_IO_IN, (gint64) timeout_ms * 1000, NULL, error)) {
    g_prefix_error (error, "waiting for the daemon: ");
    return NULL;
  }
  gsize len = 0;
  g_autofree char *line = g_data_input_stream_read_line (c->in, &len, NULL, error);
  if (!line) {
    if (error && !*error)
      g_set_error (error, G_IO_ERROR, G_IO_ERROR_CONNECTION_CLOSED, "the daemon closed the connection");
    return NULL;
  }
  DsReply *reply = ds_reply_parse (line, len, error);
  if (!reply)
    return NULL;
  DsMessage *m = g_new0 (DsMessage, 1);
  m->reply = reply;
  m->payloads = g_new0 (GBytes *, reply->n_payloads + 1);
  for (guint i = 0; i < reply->n_payloads; i++) {
    gsize n = reply->payloads[i].bytes;
    guint8 *buf = g_malloc (n ? n : 1);
    gsize got = 0;
    if (!g_input_stream_read_all (G_INPUT_STREAM (c->in), buf, n, &got, NULL, error) || got != n) {
      g_free (buf);
      if (error && !*error)
        g_set_error (error, G_IO_ERROR, G_IO_ERROR_CONNECTION_CLOSED,
                     "payload %s: connection closed after %" G_GSIZE_FORMAT " of %" G_GSIZE_FORMAT " bytes",
                     reply->payloads[i].name, got, n);
      ds_message_free (m);
      return NULL;
    }
    m->payloads[i] = g_bytes_new_take (buf, n);
  }
  return m;
}

DsMessage *
ds_client_call (DsClient *c, const char *cmd, JsonObject *args, DsClientEventFunc on_event,
                gpointer user_data, GError **error)
{
  guint64 id = ++c->next_id;
  g_autoptr (JsonBuilder) b = json_builder_new ();
  json_builder_begin_object (b);
  json_builder_set_member_name (b, "id");
  json_builder_add_int_value (b, (gint64) id);
  json_builder_set_member_name (b, "cmd");
  json_builder_add_string_value (b, cmd);
  if (args) {
    json_builder_set_member_name (b, "args");
    JsonNode *n = json_node_new (JSON_NODE_OBJECT);
    json_node_set_object (n, args);
    json_builder_add_value (b, n);
  }
  json_builder_end_object (b);
  g_autoptr (JsonNode) root = json_builder_get_root (b);
  GString *line = g_string_new (NULL);
  ds_json_write (line, root);
  g_string_append_c (line, '\n');
  gboolean sent = g_output_stream_write_all (c->out, line->str, line->len, NULL, NULL, error);
  g_string_free (line, TRUE);
  if (!sent) {
    g_prefix_error (error, "sending %s: ", cmd);
    return NULL;
  }
  for (;;) {
    DsMessage *m = ds_client_read (c, 0, error);
    if (!m)
      return NULL;
    if (m->reply->event) {
      if (on_event)
        on_event (m, user_data);
      ds_message_free (m);
      continue;
    }
    if (m->reply->id && JSON_NODE_HOLDS_VALUE (m->reply->id) &&
        (guint64) json_node_get_int (m->reply->id) == id)
      return m;
    ds_message_free (m); /* a reply to someone else's id cannot happen on our connection */
  }
}
