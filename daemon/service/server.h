/* The socket side of descatterd: listeners (UNIX, optional TCP, systemd socket activation),
 * client limits, request dispatch and fan-out of results to subscribers. Main thread only;
 * nothing here blocks. */
#pragma once
#include <gio/gio.h>

#include "daemon/service/connection.h"
#include "daemon/protocol/protocol.h"

G_BEGIN_DECLS

typedef struct DsServer DsServer;

/* The connection policy (docs/protocol.md, "Connections"): a full table makes room by closing
 * the connection that has been quiet longest (unauthenticated TCP first, never a subscriber
 * nor one being answered); a connection without a complete request for idle_timeout_ms is
 * closed; a TCP connection that owes the token has auth_timeout_ms to send it; TCP never
 * takes more than max_tcp_clients places, so local UNIX clients always find room. */
typedef struct {
  guint max_clients;        /* connections at once; beyond, room is made or `limit` refused */
  guint max_tcp_clients;    /* of which TCP at most (0: half of max_clients) */
  gsize max_line;           /* request line bytes (<= DS_PROTOCOL_MAX_LINE) */
  gsize max_queued_bytes;   /* per client; a subscriber over it loses results */
  char *token;              /* required from TCP clients when set (hello {"token": ...}) */
  guint idle_timeout_ms;    /* 0: never; subscribers and connections being answered are exempt */
  guint auth_timeout_ms;    /* 0: never */
  guint evict_quiet_ms;     /* quiet at least this long before a connection may make room
                             * (0: 1000); a newcomer gets this long to send its request */
} DsServerLimits;

/* Called for each well-formed request. The handler answers exactly once, now or later, with
 * ds_server_reply_ok/error (holding the connection with ds_connection_hold when later).
 * `hello`, `subscribe` and `unsubscribe` are handled by the server itself. */
typedef void (*DsServerRequestFunc) (DsServer *server, DsConnection *conn, DsRequest *request,
                                     gpointer user_data);

DsServer *ds_server_new (const DsServerLimits *limits, DsServerRequestFunc on_request,
                         gpointer user_data);
/* Appends the names of the commands the server answers itself (for a message listing every
 * command the daemon knows); static strings. */
void ds_server_add_own_commands (GPtrArray *names);
void ds_server_free (DsServer *server);
G_DEFINE_AUTOPTR_CLEANUP_FUNC (DsServer, ds_server_free)

/* Binds a UNIX socket, replacing a stale socket file but never a live one or a non-socket. */
gboolean ds_server_listen_unix (DsServer *server, const char *path, guint mode, GError **error);
/* Binds TCP. A non-loopback address is refused unless a token is configured. */
gboolean ds_server_listen_tcp (DsServer *server, const char *address, guint16 port, GError **error);
/* Adopts sockets passed by systemd (sd_listen_fds); returns how many. */
guint ds_server_adopt_systemd_sockets (DsServer *server, GError **error);
/* A client that is already authenticated, on a stream of the daemon's own (the live view's
 * bridge for the browser's controls, which checked the HTTP token). It takes no place of
 * max-clients and is never closed to make room (the live view limits browsers itself, so that no
 * number of pages locks a socket client out); the other limits apply as to any client. */
void ds_server_add_stream (DsServer *server, GIOStream *stream);
/* The port actually bound by the last TCP listen (useful with port 0 in tests). */
guint16 ds_server_tcp_port (const DsServer *server);

void ds_server_reply_ok (DsServer *server, DsConnection *conn, JsonNode *id, JsonNode *result,
                         const DsPayloadInfo *infos, GBytes *const *payloads, guint n_payloads);
void ds_server_reply_error (DsServer *server, DsConnection *conn, JsonNode *id, const GError *error);

/* Sends a `result` event to every subscribed connection, with `skipped`: how many results it
 * was not sent since the last one it was (docs/protocol.md, "Events"). newest_only (per-frame
 * results): a client still writing an earlier result gets only the newest, which replaces one
 * that waits unbegun; otherwise a slow client loses it only over max_queued_bytes. Returns how
 * many got it queued. */
guint ds_server_publish_result (DsServer *server, JsonNode *body, const DsPayloadInfo *infos,
                                GBytes *const *payloads, guint n_payloads, gboolean newest_only);

/* Sends an event to every subscribed connection; slow ones lose it (counted). Returns how
 * many received it. */
guint ds_server_publish (DsServer *server, const char *event, JsonNode *body,
                         const DsPayloadInfo *infos, GBytes *const *payloads, guint n_payloads);

/* Sends a preview frame as a `frame` event (one payload) to the connections subscribed with
 * frames; a slow one loses it. Frames have their own seq. Returns how many received it. */
guint ds_server_publish_frame (DsServer *server, JsonNode *body, const DsPayloadInfo *info, GBytes *payload);
/* Connections subscribed with frames. Any thread (atomic): the acquisition thread copies a
 * frame only when someone wants it. */
guint ds_server_frame_subscribers (DsServer *server);

typedef struct {
  guint clients;
  guint subscribers;
  guint64 accepted;
  guint tcp_clients;
  guint64 refused;          /* over max_clients with nobody to make room */
  guint64 evicted;          /* closed to make room for a newcomer */
  guint64 timed_out;        /* closed for idle_timeout_ms or auth_timeout_ms */
  guint64 requests;
  /* Requests refused for what the client sent: malformed lines, unknown commands, bad
   * arguments, a missing token. A device that failed or a busy queue is not the client's
   * fault and is counted only in error_replies. */
  guint64 bad_requests;
  guint64 error_replies[DS_PROTOCOL_ERROR_BAD_REPLY + 1]; /* every error reply, by wire code */
  guint64 published;        /* events produced */
  guint64 dropped;          /* event deliveries lost to slow clients, all clients ever */
  gsize queued_bytes;       /* now, all clients */
  gsize max_client_queued_bytes; /* now, the fullest client's queue (bounded by the cap) */
} DsServerStats;

void ds_server_get_stats (const DsServer *server, DsServerStats *stats);
/* Daemon stop, first step: every request from now on is answered `cancelled`. */
void ds_server_begin_stop (DsServer *server);
/* Second step, for at most timeout_ms of running the server's main context: what clients sent
 * before the stop (connections still in the listen backlog included) is read and answered,
 * the replies already queued (a capture's `cancelled`, a result) are written out, then each
 * connection and the listeners are closed. */
void ds_server_drain (DsServer *server, guint timeout_ms);
/* Closes every connection and listener now, discarding what is queued. */
void ds_server_shutdown (DsServer *server);

G_END_DECLS
