/* descatterd's HTTP side (libsoup 3): the live view's page at /, its WebSocket at /ws, and
 * /metrics for Prometheus. Off unless [http] listen is set; a non-loopback address needs a
 * token, and with a token every request must present it (?token=... or "Authorization: Bearer
 * ..."). A WebSocket from another origin than the page's is refused, so that a web site open in
 * the same browser cannot drive the daemon. Main thread; nothing blocks (libsoup is
 * asynchronous, the page is in memory). */
#pragma once
#include <glib.h>

#include "daemon/service/live_view.h"

G_BEGIN_DECLS

typedef struct DsHttpServer DsHttpServer;

/* /metrics' text (main thread); the caller frees it. */
typedef char *(*DsHttpMetricsFunc) (gpointer user_data);

/* host: a numeric address; port 0: any free one; token: NULL for none. A non-loopback host
 * without a token is refused (preflight refuses it earlier, with the configuration key). */
DsHttpServer *ds_http_server_new (const char *host, guint16 port, const char *token, DsLiveView *live,
                                  DsHttpMetricsFunc metrics, gpointer metrics_data, GError **error);
void ds_http_server_free (DsHttpServer *server);
G_DEFINE_AUTOPTR_CLEANUP_FUNC (DsHttpServer, ds_http_server_free)

/* The port bound and the page's address ("http://127.0.0.1:8420/"). */
guint16 ds_http_server_port (const DsHttpServer *server);
const char *ds_http_server_url (const DsHttpServer *server);
/* Requests served and refused for the token (the http_* fields of DsLiveStats). */
void ds_http_server_get_stats (const DsHttpServer *server, guint64 *requests, guint64 *unauthorized);

G_END_DECLS
