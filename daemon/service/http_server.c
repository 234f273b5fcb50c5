#include "daemon/service/http_server.h"

#include <string.h>

#include "build_info.h"
#include "daemon/service/live_page.h"
#include "daemon/service/token.h"

struct DsHttpServer {
  SoupServer *soup;
  DsHttpListener *listener;
  char *token;
  char **hosts;        /* what Host may say, lower case */
  guint max_body_bytes;
  DsLiveView *live;
  DsHttpMetricsFunc metrics;
  gpointer metrics_data;
  guint16 port;
  char *url;
  guint64 requests, unauthorized;
};

/* Every path served (the page, Prometheus, the page's WebSocket). Matched exactly: libsoup's
 * own handler lookup matches prefixes, which let /ws/ and /ws;x through. */
static const char *const served_paths[] = { "/", "/metrics", "/ws" };

static void
respond (SoupServerMessage *msg, guint status, const char *type, const char *body, gsize len)
{
  soup_server_message_set_status (msg, status, NULL);
  soup_message_headers_replace (soup_server_message_get_response_headers (msg), "Cache-Control", "no-store");
  soup_server_message_set_response (msg, type, SOUP_MEMORY_COPY, body, len);
}

static void
refuse (SoupServerMessage *msg, guint status, const char *text)
{
  respond (msg, status, "text/plain; charset=utf-8", text, strlen (text));
}

static const char *
bearer_token (SoupServerMessage *msg)
{
  const char *auth = soup_message_headers_get_one (soup_server_message_get_request_headers (msg), "Authorization");
  return auth && g_ascii_strncasecmp (auth, "Bearer ", 7) == 0 ? auth + 7 : NULL;
}

static gboolean
host_allowed (const DsHttpServer *s, const char *host)
{
  if (!host)
    return FALSE;
  for (guint i = 0; s->hosts[i]; i++)
    if (g_ascii_strcasecmp (s->hosts[i], host) == 0)
      return TRUE;
  return FALSE;
}

/* A body is refused from its announced length, before libsoup reads any of it: a chunked one
 * (no length) and one over the limit are answered 413 on the socket and the connection is
 * closed. TRUE when refused. */
static gboolean
refuse_body (DsHttpServer *s, SoupServerMessage *msg)
{
  SoupMessageHeaders *h = soup_server_message_get_request_headers (msg);
  SoupEncoding enc = soup_message_headers_get_encoding (h);
  goffset len = enc == SOUP_ENCODING_CONTENT_LENGTH ? soup_message_headers_get_content_length (h) : 0;
  if (enc != SOUP_ENCODING_CHUNKED && len <= (goffset) s->max_body_bytes)
    return FALSE;
  soup_message_body_set_accumulate (soup_server_message_get_request_body (msg), FALSE);
  g_autofree char *text = g_strdup_printf ("413 a request body may have at most %u bytes (max-body-bytes), "
                                           "with a Content-Length\n", s->max_body_bytes);
  ds_http_listener_refuse (s->listener, msg, SOUP_STATUS_REQUEST_ENTITY_TOO_LARGE, text);
  refuse (msg, SOUP_STATUS_REQUEST_ENTITY_TOO_LARGE, text);
  return TRUE;
}

/* Every request passes here first, at its headers (the early handler of every path): once a
 * status is set, libsoup calls no other handler, nor completes a WebSocket handshake. The
 * order: what costs memory (the body) before the token, so that an unauthenticated client
 * cannot make the daemon buffer anything. */
static void
early (SoupServer *soup, SoupServerMessage *msg, const char *path, GHashTable *query, gpointer data)
{
  (void) soup;
  DsHttpServer *s = data;
  s->requests++;
  if (refuse_body (s, msg))
    return;
  gboolean known = FALSE;
  for (guint i = 0; i < G_N_ELEMENTS (served_paths); i++)
    known = known || g_str_equal (path, served_paths[i]);
  if (!known) {
    refuse (msg, SOUP_STATUS_NOT_FOUND, "404 not found (the live view is at /, metrics at /metrics)\n");
    return;
  }
  SoupMessageHeaders *h = soup_server_message_get_request_headers (msg);
  const char *host = soup_message_headers_get_one (h, "Host");
  if (!host_allowed (s, host)) {
    /* A name that resolves here without being ours is DNS rebinding: a foreign web page's
     * requests, made same-origin by its own DNS. */
    refuse (msg, SOUP_STATUS_MISDIRECTED_REQUEST,
            "421 this Host is not descatterd's (its listen address, or a name in [http] server-names)\n");
    return;
  }
  const char *origin = soup_message_headers_get_one (h, "Origin");
  g_autofree char *own = g_strdup_printf ("http://%s", host);
  if (origin && g_ascii_strcasecmp (origin, own) != 0) {
    refuse (msg, SOUP_STATUS_FORBIDDEN, "403 forbidden: a request from another origin than the page's\n");
    return;
  }
  const char *given = query ? g_hash_table_lookup (query, "token") : NULL;
  if (!given)
    given = bearer_token (msg);
  if (!ds_token_equal (s->token, given)) {
    s->unauthorized++;
    refuse (msg, SOUP_STATUS_UNAUTHORIZED,
            "401 unauthorized: this descatterd needs its token (?token=... or Authorization: Bearer ...; "
            "`descatterctl live-url` prints the page's address with it)\n");
    return;
  }
  const char *method = soup_server_message_get_method (msg);
  gboolean ws = g_str_equal (path, "/ws");
  if (!g_str_equal (method, "GET") && (ws || !g_str_equal (method, "HEAD"))) {
    refuse (msg, SOUP_STATUS_METHOD_NOT_ALLOWED, "405 method not allowed (GET only)\n");
    return;
  }
  if (ws && ds_live_view_is_full (s->live))
    refuse (msg, SOUP_STATUS_SERVICE_UNAVAILABLE, "503 the live view has all the clients it takes "
                                                  "([http] max-live-clients)\n");
}

static void
on_page (SoupServer *soup, SoupServerMessage *msg, const char *path, GHashTable *query, gpointer data)
{
  (void) soup;
  (void) query;
  (void) data;
  (void) path;
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
  (void) path;
  DsHttpServer *s = data;
  ds_live_view_add_client (s->live, ws, ds_http_listener_socket (s->listener, msg));
}

/* "host:port" as a Host header says it (IPv6 in brackets). */
static char *
host_port (const char *host, guint16 port)
{
  return strchr (host, ':') ? g_strdup_printf ("[%s]:%u", host, port) : g_strdup_printf ("%s:%u", host, port);
}

static char **
allowed_hosts (const char *host, gboolean loopback, guint16 port, const char *const *names)
{
  g_autoptr (GPtrArray) a = g_ptr_array_new ();
  g_ptr_array_add (a, host_port (host, port));
  if (loopback)
    g_ptr_array_add (a, host_port ("localhost", port));
  for (guint i = 0; names && names[i]; i++) {
    const char *bracket = strrchr (names[i], ']');
    gboolean has_port = strchr (bracket ? bracket : names[i], ':') != NULL;
    g_ptr_array_add (a, has_port ? g_strdup (names[i]) : host_port (names[i], port));
  }
  if (port == 80) /* a browser leaves the default port out */
    for (guint i = 0, n = a->len; i < n; i++)
      g_ptr_array_add (a, g_strndup (a->pdata[i], strlen (a->pdata[i]) - 3));
  g_ptr_array_add (a, NULL);
  return (char **) g_ptr_array_free (g_steal_pointer (&a), FALSE);
}

DsHttpServer *
ds_http_server_new (const DsHttpOptions *o, DsLiveView *live, DsHttpMetricsFunc metrics, gpointer metrics_data,
                    GError **error)
{
  g_autoptr (GInetAddress) ia = g_inet_address_new_from_string (o->host);
  if (!ia) {
    g_set_error (error, G_IO_ERROR, G_IO_ERROR_INVALID_ARGUMENT, "HTTP: \"%s\" is not an IP address", o->host);
    return NULL;
  }
  if (!o->token || strlen (o->token) < 16) {
    g_set_error (error, G_IO_ERROR, G_IO_ERROR_PERMISSION_DENIED, "HTTP on %s needs a token", o->host);
    return NULL;
  }
  g_autoptr (DsHttpServer) s = g_new0 (DsHttpServer, 1);
  s->token = g_strdup (o->token);
  s->max_body_bytes = o->max_body_bytes;
  s->live = live;
  s->metrics = metrics;
  s->metrics_data = metrics_data;
  s->soup = soup_server_new ("server-header", "descatterd/" DS_VERSION " ", NULL);
  /* libsoup runs the early callback of the handler it picked, the longest prefix of the path:
   * one on every handler's path, "/" included, so that every request passes `early`. */
  for (guint i = 0; i < G_N_ELEMENTS (served_paths); i++)
    soup_server_add_early_handler (s->soup, served_paths[i], early, s, NULL);
  soup_server_add_handler (s->soup, "/", on_page, s, NULL);
  soup_server_add_handler (s->soup, "/metrics", on_metrics, s, NULL);
  soup_server_add_websocket_handler (s->soup, "/ws", NULL, NULL, on_websocket, s, NULL);
  s->listener = ds_http_listener_new (s->soup, ia, o->port, &o->limits, error);
  if (!s->listener) {
    g_prefix_error (error, "HTTP %s:%u: ", o->host, o->port);
    return NULL;
  }
  s->port = ds_http_listener_port (s->listener);
  s->hosts = allowed_hosts (o->host, g_inet_address_get_is_loopback (ia), s->port, o->server_names);
  g_autofree char *hp = host_port (o->host, s->port);
  s->url = g_strdup_printf ("http://%s/", hp);
  return g_steal_pointer (&s);
}

void
ds_http_server_free (DsHttpServer *s)
{
  if (!s)
    return;
  /* libsoup ends its requests first, while the listener that follows them is there; the
   * listener then forgets the connections that outlive it (the live view's WebSockets). */
  if (s->soup)
    soup_server_disconnect (s->soup);
  ds_http_listener_free (s->listener);
  g_clear_object (&s->soup);
  g_free (s->token);
  g_strfreev (s->hosts);
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

void
ds_http_server_get_listener_stats (const DsHttpServer *s, DsHttpListenerStats *stats)
{
  ds_http_listener_get_stats (s->listener, stats);
}
