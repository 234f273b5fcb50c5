#include "daemon/service/http_server.h"

#include <string.h>

#include "build_info.h"
#include "daemon/service/live_page.h"
#include "daemon/service/token.h"

struct DsHttpServer {
  SoupServer *soup;
  char *token;
  DsLiveView *live;
  DsHttpMetricsFunc metrics;
  gpointer metrics_data;
  guint16 port;
  char *url;
  guint64 requests, unauthorized;
};

static void
respond (SoupServerMessage *msg, guint status, const char *type, const char *body, gsize len)
{
  soup_server_message_set_status (msg, status, NULL);
  soup_message_headers_replace (soup_server_message_get_response_headers (msg), "Cache-Control", "no-store");
  soup_server_message_set_response (msg, type, SOUP_MEMORY_COPY, body, len);
}

static const char *
bearer_token (SoupServerMessage *msg)
{
  const char *auth = soup_message_headers_get_one (soup_server_message_get_request_headers (msg), "Authorization");
  return auth && g_ascii_strncasecmp (auth, "Bearer ", 7) == 0 ? auth + 7 : NULL;
}

/* A WebSocket's Origin must be the page's own (scheme, host and port of the request). */
static gboolean
same_origin (SoupServerMessage *msg)
{
  SoupMessageHeaders *h = soup_server_message_get_request_headers (msg);
  const char *origin = soup_message_headers_get_one (h, "Origin");
  if (!origin)
    return TRUE; /* not a browser: the token (if any) decides */
  const char *host = soup_message_headers_get_one (h, "Host");
  g_autofree char *expected = host ? g_strdup_printf ("http://%s", host) : NULL;
  return expected && g_ascii_strcasecmp (origin, expected) == 0;
}

/* Every request passes here first (the early handler of its path): once a status is set,
 * libsoup calls no other handler, nor completes a WebSocket handshake. */
static void
early (SoupServer *soup, SoupServerMessage *msg, const char *path, GHashTable *query, gpointer data)
{
  (void) soup;
  DsHttpServer *s = data;
  s->requests++;
  if (s->token) {
    const char *given = query ? g_hash_table_lookup (query, "token") : NULL;
    if (!given)
      given = bearer_token (msg);
    if (!ds_token_equal (s->token, given)) {
      s->unauthorized++;
      static const char text[] = "401 unauthorized: this descatterd needs its token (?token=... or "
                                 "Authorization: Bearer ...)\n";
      respond (msg, SOUP_STATUS_UNAUTHORIZED, "text/plain; charset=utf-8", text, sizeof text - 1);
      return;
    }
  }
  if (g_str_equal (path, "/ws") && !same_origin (msg)) {
    static const char text[] = "403 forbidden: WebSocket from another origin\n";
    respond (msg, SOUP_STATUS_FORBIDDEN, "text/plain; charset=utf-8", text, sizeof text - 1);
  }
}

static void
on_page (SoupServer *soup, SoupServerMessage *msg, const char *path, GHashTable *query, gpointer data)
{
  (void) soup;
  (void) query;
  (void) data;
  if (strcmp (soup_server_message_get_method (msg), "GET") != 0 && strcmp (soup_server_message_get_method (msg), "HEAD") != 0) {
    respond (msg, SOUP_STATUS_METHOD_NOT_ALLOWED, "text/plain", "405\n", 4);
    return;
  }
  if (!g_str_equal (path, "/")) {
    static const char text[] = "404 not found (the live view is at /, metrics at /metrics)\n";
    respond (msg, SOUP_STATUS_NOT_FOUND, "text/plain; charset=utf-8", text, sizeof text - 1);
    return;
  }
  respond (msg, SOUP_STATUS_OK, "text/html; charset=utf-8", ds_live_page_text, strlen (ds_live_page_text));
}

static void
on_metrics (SoupServer *soup, SoupServerMessage *msg, const char *path, GHashTable *query, gpointer data)
{
  (void) soup;
  (void) path;
  (void) query;
  DsHttpServer *s = data;
  g_autofree char *text = s->metrics (s->metrics_data);
  respond (msg, SOUP_STATUS_OK, "text/plain; version=0.0.4; charset=utf-8", text, strlen (text));
}

static void
on_websocket (SoupServer *soup, SoupServerMessage *msg, const char *path, SoupWebsocketConnection *ws, gpointer data)
{
  (void) soup;
  (void) msg;
  (void) path;
  DsHttpServer *s = data;
  ds_live_view_add_client (s->live, ws);
}

DsHttpServer *
ds_http_server_new (const char *host, guint16 port, const char *token, DsLiveView *live, DsHttpMetricsFunc metrics,
                    gpointer metrics_data, GError **error)
{
  g_autoptr (GInetAddress) ia = g_inet_address_new_from_string (host);
  if (!ia) {
    g_set_error (error, G_IO_ERROR, G_IO_ERROR_INVALID_ARGUMENT, "HTTP: \"%s\" is not an IP address", host);
    return NULL;
  }
  if (!g_inet_address_get_is_loopback (ia) && !token) {
    g_set_error (error, G_IO_ERROR, G_IO_ERROR_PERMISSION_DENIED, "HTTP on %s (not loopback) requires a token", host);
    return NULL;
  }
  g_autoptr (DsHttpServer) s = g_new0 (DsHttpServer, 1);
  s->token = g_strdup (token);
  s->live = live;
  s->metrics = metrics;
  s->metrics_data = metrics_data;
  s->soup = soup_server_new ("server-header", "descatterd/" DS_VERSION " ", NULL);
  /* libsoup picks one handler per request, the longest path that matches: the early check goes
   * on every path that has a handler. */
  static const char *const paths[] = { "/", "/metrics", "/ws" };
  for (guint i = 0; i < G_N_ELEMENTS (paths); i++)
    soup_server_add_early_handler (s->soup, paths[i], early, s, NULL);
  soup_server_add_handler (s->soup, "/", on_page, s, NULL);
  soup_server_add_handler (s->soup, "/metrics", on_metrics, s, NULL);
  soup_server_add_websocket_handler (s->soup, "/ws", NULL, NULL, on_websocket, s, NULL);
  g_autoptr (GSocketAddress) addr = g_inet_socket_address_new (ia, port);
  if (!soup_server_listen (s->soup, addr, 0, error)) {
    g_prefix_error (error, "HTTP %s:%u: ", host, port);
    return NULL;
  }
  GSList *uris = soup_server_get_uris (s->soup);
  if (uris) {
    s->port = (guint16) g_uri_get_port (uris->data);
    s->url = g_uri_to_string (uris->data);
  }
  g_slist_free_full (uris, (GDestroyNotify) g_uri_unref);
  return g_steal_pointer (&s);
}

void
ds_http_server_free (DsHttpServer *s)
{
  if (!s)
    return;
  if (s->soup) {
    soup_server_disconnect (s->soup);
    g_object_unref (s->soup);
  }
  g_free (s->token);
  g_free (s->url);
  g_free (s);
}

guint16
ds_http_server_port (const DsHttpServer *s)
{
  return s->port;
}

const char *
ds_http_server_url (const DsHttpServer *s)
{
  return s->url;
}

void
ds_http_server_get_stats (const DsHttpServer *s, guint64 *requests, guint64 *unauthorized)
{
  *requests = s->requests;
  *unauthorized = s->unauthorized;
}
