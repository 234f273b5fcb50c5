/* The live view's server side (docs/operations.md, "Live view"): what browsers connected over
 * WebSocket see, and how a slow one is kept from slowing anything.
 *
 *   - raw frames: the sequencer's frame hook (fold worker thread) copies at most max_fps frames
 *     a second into a slot, and only while someone watches; the encoder thread turns the newest
 *     into a small picture with the measured stripe period and phase, the histogram and levels
 *     over the sensor's significant bits, and the samples at full resolution (live_encode.h);
 *   - results: every published result (main thread) is encoded the same way (transmissive,
 *     scattered, plain average, mask);
 *   - status: the daemon's status document twice a second (frame counters, drop reasons,
 *     camera and illuminator state).
 * Each client gets one update at a time and acknowledges it (the page sends {"ack": true} when
 * it has drawn it); meanwhile newer updates replace older ones of the same kind (counted as
 * superseded). A browser that stops reading therefore holds at most one update in its socket
 * and costs nothing else; nothing waits for it. A result update follows a text message
 * {"type": "skipped", "results": N} when N results published since the last one sent to that
 * page were not sent to it, so that shown plus skipped is what was published. The page's controls go through a protocol
 * connection of its own (live_bridge.h).
 *
 * Threads: ds_live_view_on_frame on the fold worker; ds_live_view_new/free and everything else
 * on the main thread (the GMainContext given). */
#pragma once
#include <glib.h>
#include <json-glib/json-glib.h>
#include <libsoup/soup.h>

#include "daemon/service/metrics.h"
#include "daemon/acquire/result.h"
#include "daemon/service/server.h"

G_BEGIN_DECLS

typedef struct DsLiveView DsLiveView;

/* The status document (main thread): a new reference. */
typedef JsonNode *(*DsLiveStatusFunc) (gpointer user_data);

typedef struct {
  double max_fps;           /* raw frames copied a second at most */
  guint max_clients;        /* browsers at once ([http] max-live-clients); their controls' bridges
                               are not counted in the socket's max-clients */
  gsize send_budget_bytes;  /* per client: unsent bytes in its socket beyond which it gets no
                               update (newer ones replace the waiting ones) */
} DsLiveViewLimits;

DsLiveView *ds_live_view_new (GMainContext *context, DsServer *server, const DsLiveViewLimits *limits,
                              DsLiveStatusFunc status, gpointer status_data);
/* Closes every client, stops the encoder thread. Remove the frame hook first. */
void ds_live_view_free (DsLiveView *live);
G_DEFINE_AUTOPTR_CLEANUP_FUNC (DsLiveView, ds_live_view_free)

/* The sequencer's frame hook (DsSequencerFrameFunc; user_data is the live view). */
void ds_live_view_on_frame (const DsFrame *frame, guint phase, const DsCaptureSettings *settings,
                            gpointer user_data);
/* A published result. */
void ds_live_view_on_result (DsLiveView *live, DsResult *result);
/* TRUE when max_clients browsers are connected: the HTTP server refuses the next upgrade. */
gboolean ds_live_view_is_full (const DsLiveView *live);
/* A browser's WebSocket and the socket under it (NULL: no send budget); the live view takes
 * references. */
void ds_live_view_add_client (DsLiveView *live, SoupWebsocketConnection *ws, GSocket *socket);

/* Clients, updates sent and superseded (the http_* fields are the HTTP server's). */
void ds_live_view_get_stats (DsLiveView *live, DsLiveStats *stats);

G_END_DECLS
