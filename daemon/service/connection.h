/* One client connection of descatterd: bounded line framing in, a bounded queue of
 * reference-counted byte chunks out. Lives on the main thread (GMainContext of the daemon);
 * nothing here blocks: reads and writes are asynchronous GIO operations. */
#pragma once
#include <gio/gio.h>

G_BEGIN_DECLS

typedef struct DsConnection DsConnection;

/* A complete line (newline removed), or, when too_long is TRUE, the notice that a line exceeded
 * the limit and was discarded up to its newline (line is NULL then): the stream stays in sync. */
typedef void (*DsConnectionLineFunc) (DsConnection *conn, const char *line, gsize len,
                                      gboolean too_long, gpointer user_data);
/* The peer went away or the connection was closed; called once. The owner drops its reference. */
typedef void (*DsConnectionClosedFunc) (DsConnection *conn, gpointer user_data);

typedef struct {
  gsize max_line;         /* bytes before the newline */
  gsize max_queued_bytes; /* bytes waiting to be written to this client */
} DsConnectionLimits;

DsConnection *ds_connection_new (GIOStream *stream, const DsConnectionLimits *limits,
                                 DsConnectionLineFunc on_line, DsConnectionClosedFunc on_closed,
                                 gpointer user_data);
DsConnection *ds_connection_ref (DsConnection *conn);
void ds_connection_unref (DsConnection *conn);
G_DEFINE_AUTOPTR_CLEANUP_FUNC (DsConnection, ds_connection_unref)

/* Starts reading. */
void ds_connection_start (DsConnection *conn);

/* Queues a message: a line and the payload chunks after it, all written in order. The chunks are
 * referenced, never copied, so one result fans out to many clients at the cost of a pointer.
 * A droppable message (a stream event) is refused (returns FALSE, counted in dropped) when it
 * would push the queue past max_queued_bytes; a reply is always queued, but if that overfills
 * the queue twice over, the client is not reading at all and is disconnected. */
gboolean ds_connection_send (DsConnection *conn, GBytes *line, GBytes *const *payloads,
                             guint n_payloads, gboolean droppable);

/* Queues a message of which only the newest need reach the peer (a per-frame result): the one
 * queued before it this way is removed if its writing has not begun, so that at most two wait,
 * the one being written and the newest. Messages are removed whole and only before their first
 * byte goes out, so the peer never gets a torn one; messages queued with ds_connection_send keep
 * their place and order. Refused (FALSE, the waiting one kept) when it would push the queue past
 * max_queued_bytes even in the waiting one's place. A removed or refused message counts in
 * dropped. */
gboolean ds_connection_send_newest (DsConnection *conn, GBytes *line, GBytes *const *payloads,
                                    guint n_payloads);
/* TRUE while a message queued with ds_connection_send_newest waits, its writing not begun: the
 * next such message replaces it. */
gboolean ds_connection_has_newest_waiting (const DsConnection *conn);

/* Closes now; queued data is discarded. on_closed runs (once) from an idle callback of the
 * connection's context (at default priority, so a freed place is seen before the next accept
 * is processed). */
void ds_connection_close (DsConnection *conn);

/* Closes once everything queued so far has been written (e.g. after a fatal error reply). */
void ds_connection_close_after_flush (DsConnection *conn);

/* A request whose reply comes later (a capture) holds the connection: after the peer's EOF
 * (a half-close, as `nc -N` does) the connection stays open until every hold is released
 * and the queue is written. */
void ds_connection_hold (DsConnection *conn);
void ds_connection_release (DsConnection *conn);

gsize ds_connection_queued_bytes (const DsConnection *conn);
/* TRUE while a request is being answered (a hold) or output waits to be written: such a
 * connection is not idle, whatever time passed since its last request. */
gboolean ds_connection_is_busy (const DsConnection *conn);
/* How long queued output has waited without a byte written (µs); 0 when nothing waits. */
gint64 ds_connection_stalled_us (const DsConnection *conn);
/* TRUE when the peer has closed (or shut down its sending side) and nothing it sent waits to
 * be read or answered: the connection can be closed now, before its EOF is processed. */
gboolean ds_connection_peer_gone (const DsConnection *conn);
/* TRUE when the peer has sent bytes not read yet (a request the server has not seen). */
gboolean ds_connection_has_unread_input (const DsConnection *conn);
/* Messages refused or removed (ds_connection_send_newest) for a slow peer. */
guint64 ds_connection_dropped (const DsConnection *conn);
gboolean ds_connection_is_closed (const DsConnection *conn);

/* Free-form per-connection data of the owner (e.g. subscription state). */
void ds_connection_set_data (DsConnection *conn, gpointer data, GDestroyNotify destroy);
gpointer ds_connection_get_data (DsConnection *conn);

G_END_DECLS
