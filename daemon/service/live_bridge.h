/* The browser's controls reach descatterd as an ordinary protocol client: each live-view client
 * gets a connection of its own to the daemon's DsServer (a socketpair, added already
 * authenticated: the browser presented the HTTP token), writes the request lines the page sends
 * and reads the replies, passing each reply's JSON line back and skipping its payloads (the
 * browser sees results through the live view instead). Every command is the socket's, with its
 * checks and error codes (docs/protocol.md). Main thread; nothing blocks. */
#pragma once
#include <glib.h>

#include "daemon/service/server.h"

G_BEGIN_DECLS

typedef struct DsLiveBridge DsLiveBridge;

/* A reply or event line for the browser. */
typedef void (*DsLiveBridgeLineFunc) (const char *line, gpointer user_data);

DsLiveBridge *ds_live_bridge_new (DsServer *server, DsLiveBridgeLineFunc on_line, gpointer user_data,
                                  GError **error);
/* Stops reading (no callback after this) and closes the connection. */
void ds_live_bridge_free (DsLiveBridge *bridge);

/* Queues one request line (no newline; it is added). */
void ds_live_bridge_send (DsLiveBridge *bridge, const char *line);
/* FALSE once the daemon closed the connection (its idle timeout, or a full server making room):
 * the owner makes a new bridge for the next command. */
gboolean ds_live_bridge_is_open (const DsLiveBridge *bridge);

G_END_DECLS
