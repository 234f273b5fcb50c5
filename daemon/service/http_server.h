/* descatterd's HTTP side (libsoup 3): the live view's page at /, its WebSocket at /ws, and
 * /metrics for Prometheus, and nothing else (an exact path table: /ws/ or /ws;x are 404). Off
 * unless [http] listen is set. Every request must present the token (?token=... or
 * "Authorization: Bearer ..."): on loopback the daemon generates one readable by the socket's
 * group (service.c), so that HTTP lets in nobody the socket would not. Its Host must be the
 * listen address or one of [http] server-names (a DNS-rebinding name is refused), and an
 * Origin, when sent, the page's own. A body over max_body_bytes is refused from its
 * Content-Length before any of it is read, before the token is checked. Connections are held
 * to the limits of http_listener.h. Main thread; nothing blocks (libsoup is asynchronous, the
 * page is in memory). */
#pragma once
#include <glib.h>

#include "daemon/service/http_listener.h"
#include "daemon/service/live_view.h"

G_BEGIN_DECLS

typedef struct DsHttpServer DsHttpServer;

/* /metrics' text (main thread); the caller frees it. */
typedef char *(*DsHttpMetricsFunc) (gpointer user_data);

typedef struct {
  const char *host;                 /* a numeric address */
  guint16 port;                     /* 0: any free one */
  const char *token;                /* required, at least 16 characters */
  const char *const *server_names;  /* further names for Host ("name" or "name:port"); NULL: none */
  DsHttpLimits limits;
  guint max_body_bytes;
} DsHttpOptions;

DsHttpServer *ds_http_server_new (const DsHttpOptions *options, DsLiveView *live, DsHttpMetricsFunc metrics,
                                  gpointer metrics_data, GError **error);
void ds_http_server_free (DsHttpServer *server);
G_DEFINE_AUTOPTR_CLEANUP_FUNC (DsHttpServer, ds_http_server_free)

/* The port bound and the page's address without the token ("http://127.0.0.1:8420/"). */
guint16 ds_http_server_port (const DsHttpServer *server);
const char *ds_http_server_url (const DsHttpServer *server);
/* Requests served and refused for the token (the http_* fields of DsLiveStats). */
void ds_http_server_get_stats (const DsHttpServer *server, guint64 *requests, guint64 *unauthorized);
void ds_http_server_get_listener_stats (const DsHttpServer *server, DsHttpListenerStats *stats);

G_END_DECLS
