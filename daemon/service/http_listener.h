/* The HTTP side's listening socket and the connections on it, held to limits before libsoup
 * sees a byte (docs/reliability.md, "HTTP"): at most max_connections at once and
 * max_per_peer from one address (refused with 503 beyond), request headers at most
 * max_header_bytes (read no further), a request's headers complete within header_timeout_ms of
 * its first byte, a connection without a request closed after idle_timeout_ms. When the process
 * runs out of descriptors, accepting pauses and resumes on a timer instead of spinning. A
 * connection upgraded to a WebSocket is exempt from the timeouts (the live view bounds it).
 * Main thread; nothing blocks. */
#pragma once
#include <libsoup/soup.h>

G_BEGIN_DECLS

typedef struct {
  guint max_connections;
  guint max_per_peer;
  guint max_header_bytes;
  guint header_timeout_ms;
  guint idle_timeout_ms;
} DsHttpLimits;

typedef struct {
  guint connections;        /* now */
  guint64 accepted;
  guint64 refused;          /* over max_connections or max_per_peer */
  guint64 timed_out;        /* closed for header_timeout_ms or idle_timeout_ms */
  guint64 accept_paused;    /* times accepting paused for want of descriptors */
} DsHttpListenerStats;

typedef struct DsHttpListener DsHttpListener;

/* Binds addr:port (0: any free port) and hands each connection within the limits to `soup`. */
DsHttpListener *ds_http_listener_new (SoupServer *soup, GInetAddress *addr, guint16 port, const DsHttpLimits *limits,
                                      GError **error);
void ds_http_listener_free (DsHttpListener *listener);
G_DEFINE_AUTOPTR_CLEANUP_FUNC (DsHttpListener, ds_http_listener_free)

guint16 ds_http_listener_port (const DsHttpListener *listener);
/* The socket under a request's connection (NULL if it is gone); borrowed. */
GSocket *ds_http_listener_socket (DsHttpListener *listener, SoupServerMessage *msg);
/* Answers `status` with `text` straight on the socket and closes the connection, reading
 * nothing more of the request (a body over the limit, say). */
void ds_http_listener_refuse (DsHttpListener *listener, SoupServerMessage *msg, guint status, const char *text);
void ds_http_listener_get_stats (const DsHttpListener *listener, DsHttpListenerStats *stats);

G_END_DECLS
