/* The server's state, shared by its files (server.c: connections and events; server_reply.c:
 * replies and their accounting). Not for other modules: they use server.h. */
#pragma once
#include "daemon/service/server.h"
#include "daemon/service/accept_loop.h"

typedef struct {
  DsServer *server;
  gboolean subscribed;
  gboolean frames;      /* subscribed with "frames": preview frames as `frame` events */
  gboolean authenticated;
  gboolean is_tcp;
  gboolean bridge;      /* the live view's, for a browser's controls: no socket place (the live
                           view has its own limit, so that pages never lock socket clients out) */
  gboolean leaving;     /* being closed by the server (timeout, eviction): its place is free */
  gint64 accepted_us;
  gint64 active_us;     /* last complete request, or last moment it was busy being answered */
  gint64 leaving_us;
  /* Result accounting (docs/protocol.md, "Events"): results published and not sent to this
   * client since the last result queued for it, which the next result queued reports; and the
   * count the waiting per-frame result (ds_connection_has_newest_waiting) reports, which a newer
   * one that replaces it takes over, plus one for it. */
  guint64 skipped;
  guint64 waiting_skipped;
} ClientState;

/* How long a connection the server is closing may take to read its last error line. */
#define LEAVING_GRACE_US (2 * G_USEC_PER_SEC)
/* How long, at stop, output may wait without a byte going out before its peer is given up. */
#define DRAIN_STALL_US (500 * 1000)

struct DsServer {
  DsServerLimits limits;
  DsServerRequestFunc on_request;
  gpointer user_data;
  GSocketListener *listener;
  DsAcceptLoop *accepting; /* not GSocketService: it spins when out of descriptors */
  GMainContext *context; /* where the server was created: connections, sweep, drain */
  GSource *sweep;
  GHashTable *clients; /* DsConnection* -> NULL (set); holds a reference */
  guint16 tcp_port;
  char *unix_path;     /* removed on free when we created it */
  guint64 seq;
  guint64 frame_seq;   /* `frame` events: their own count, so that `result` seq gaps still mean
                        * results lost */
  gint frame_subscribers; /* atomic: connections with frames on (read by any thread) */
  gboolean draining;
  DsServerStats stats;
};
