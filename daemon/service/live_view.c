#include "daemon/service/live_view.h"

#include <malloc.h>
#include <poll.h>
#include <string.h>
#include <sys/ioctl.h>
#include <linux/sockios.h>

#include "daemon/service/live_bridge.h"
#include "daemon/service/json_build.h"
#include "daemon/service/live_encode.h"

/* Pictures no larger than this a side: enough to focus by, small for a network. */
#define LIVE_MAX_SIDE 640
#define STATUS_INTERVAL_MS 500
/* Commands a page may send (the daemon checks their arguments as for any client). */
static const char *const page_commands[] = { "capture", "start", "stop", "cancel", "status", "dark", "release",
                                             "acquire", "preview", "set", NULL };

typedef enum { KIND_STATUS, KIND_RESULT, KIND_FRAME, N_KINDS } Kind;

typedef struct {
  DsLiveView *live;
  SoupWebsocketConnection *ws;
  gboolean busy;            /* an update sent and not acknowledged yet */
  gboolean dirty[N_KINDS];  /* a newer update of this kind waits */
  DsLiveBridge *bridge;     /* made at the first command */
  GSocket *socket;          /* under the WebSocket: how much it has not sent yet (NULL: unknown) */
  guint next_kind;          /* the kind tried first at the next send: kinds take turns */
  guint64 results_skipped;  /* results published since the last one sent to it that it was not
                               sent (a newer one came first); told with the next one */
} Client;

struct DsLiveView {
  GMainContext *context;
  DsServer *server;
  DsLiveStatusFunc status_func;
  gpointer status_data;
  gint64 frame_interval_us;
  guint max_clients;
  gsize send_budget;
  gint wanting;             /* atomic: clients able to take an update now (not waiting for an
                               ack): the frame hook copies, and the encoder works, only for them */

  /* Handed from the fold worker (frame) and the main thread (result) to the encoder. */
  GMutex lock;
  GCond cond;
  DsImage *frame;           /* the newest frame not yet encoded, or NULL */
  DsImage *spare;           /* a frame buffer the encoder gave back */
  DsLiveFrameInfo frame_info;
  gint64 last_copy_us;
  DsResult *result;         /* the newest result not yet encoded */
  char *result_meta;
  gboolean quit;
  GThread *encoder;

  /* Main thread. */
  GBytes *latest[N_KINDS];
  GPtrArray *clients;       /* Client * */
  guint status_source;
  DsLiveStats stats;
};

/* ---- main thread: clients ---- */

static void
set_busy (Client *c, gboolean busy)
{
  if (c->busy != busy)
    g_atomic_int_add (&c->live->wanting, busy ? -1 : 1);
  c->busy = busy;
}

/* Whether the client's socket has taken what was sent before: an ack says the page drew an
 * update, not that it read the next, so a client acknowledging without reading would otherwise
 * pile updates up in libsoup's queue. libsoup writes what the kernel takes at once, so its own
 * queue is empty while the socket is writable and has less than the budget unsent. */
static gboolean
within_budget (Client *c)
{
  if (!c->socket)
    return TRUE;
  int fd = g_socket_get_fd (c->socket);
  struct pollfd p = { .fd = fd, .events = POLLOUT };
  if (poll (&p, 1, 0) != 1 || !(p.revents & POLLOUT))
    return FALSE;
  int unsent = 0;
  if (ioctl (fd, SIOCOUTQ, &unsent) != 0)
    return TRUE;
  return (gsize) unsent < c->live->send_budget;
}

static void
try_send (Client *c)
{
  if (c->busy || soup_websocket_connection_get_state (c->ws) != SOUP_WEBSOCKET_STATE_OPEN)
    return;
  /* Over its budget the client keeps its dirty flags: newer updates replace these meanwhile,
   * and the next status tick or ack tries again. */
  if (!within_budget (c))
    return;
  /* Kinds take turns: a page acknowledging slower than the status ticks (twice a second) would
   * otherwise be sent status alone, never a result or a frame. */
  for (guint i = 0; i < N_KINDS; i++) {
    guint k = (c->next_kind + i) % N_KINDS;
    if (!c->dirty[k] || !c->live->latest[k])
      continue;
    c->next_kind = k + 1;
    c->dirty[k] = FALSE;
    set_busy (c, TRUE);
    c->live->stats.sent++;
    GBytes *msg = c->live->latest[k];
    if (k == KIND_RESULT && c->results_skipped > 0) {
      /* Before the result it precedes: the page counts what it never drew. */
      g_autofree char *note = g_strdup_printf ("{\"type\":\"skipped\",\"results\":%" G_GUINT64_FORMAT "}",
                                               c->results_skipped);
      soup_websocket_connection_send_text (c->ws, note);
      c->results_skipped = 0;
    }
    if (k == KIND_STATUS)
      soup_websocket_connection_send_text (c->ws, g_bytes_get_data (msg, NULL));
    else
      soup_websocket_connection_send_message (c->ws, SOUP_WEBSOCKET_DATA_BINARY, msg);
    return;
  }
}

static void
publish (DsLiveView *lv, Kind kind, GBytes *msg)
{
  if (lv->latest[kind])
    g_bytes_unref (lv->latest[kind]);
  lv->latest[kind] = msg;
  for (guint i = 0; i < lv->clients->len; i++) {
    Client *c = lv->clients->pdata[i];
    if (c->dirty[kind]) {
      lv->stats.superseded++;
      if (kind == KIND_RESULT)
        c->results_skipped++;
    }
    c->dirty[kind] = TRUE;
    try_send (c);
  }
}

static void
send_text (Client *c, const char *text)
{
  if (soup_websocket_connection_get_state (c->ws) == SOUP_WEBSOCKET_STATE_OPEN)
    soup_websocket_connection_send_text (c->ws, text);
}

static void
on_bridge_line (const char *line, gpointer data)
{
  Client *c = data;
  /* Replies carry "id"/"ok", events "event": the page tells them from its own updates. */
  send_text (c, line);
}

static void
reply_error (Client *c, JsonNode *id, const char *message)
{
  g_autoptr (JsonBuilder) b = ds_json_object_begin ();
  ds_json_add_node (b, "id", id ? json_node_copy (id) : NULL);
  ds_json_add_bool (b, "ok", FALSE);
  ds_json_begin_member_object (b, "error");
  ds_json_add_string (b, "code", "bad_request");
  ds_json_add_string (b, "message", message);
  json_builder_end_object (b);
  g_autoptr (JsonNode) root = ds_json_object_end (b);
  g_autofree char *text = json_to_string (root, FALSE);
  send_text (c, text);
}

/* {"ack": true}: the last update is drawn. {"id", "cmd", "args"}: a command for the daemon. */
static void
on_message (SoupWebsocketConnection *ws, gint type, GBytes *message, gpointer data)
{
  (void) ws;
  Client *c = data;
  if (type != SOUP_WEBSOCKET_DATA_TEXT)
    return;
  gsize len;
  const char *text = g_bytes_get_data (message, &len);
  g_autoptr (JsonParser) parser = json_parser_new ();
  if (!json_parser_load_from_data (parser, text, (gssize) len, NULL) ||
      !JSON_NODE_HOLDS_OBJECT (json_parser_get_root (parser))) {
    reply_error (c, NULL, "not a JSON object");
    return;
  }
  JsonObject *o = json_node_get_object (json_parser_get_root (parser));
  if (json_object_has_member (o, "ack")) {
    set_busy (c, FALSE);
    try_send (c);
    return;
  }
  JsonNode *id = json_object_get_member (o, "id");
  if (id && !JSON_NODE_HOLDS_NULL (id) &&
      !(JSON_NODE_HOLDS_VALUE (id) && (json_node_get_value_type (id) == G_TYPE_INT64 ||
                                       json_node_get_value_type (id) == G_TYPE_DOUBLE ||
                                       json_node_get_value_type (id) == G_TYPE_STRING))) {
    reply_error (c, NULL, "\"id\" must be a number or a string");
    return;
  }
  /* Any JSON may come: "cmd" is read only once it is known to be a string. */
  JsonNode *cmd_node = json_object_get_member (o, "cmd");
  const char *cmd = cmd_node && JSON_NODE_HOLDS_VALUE (cmd_node) && json_node_get_value_type (cmd_node) == G_TYPE_STRING
                        ? json_node_get_string (cmd_node)
                        : NULL;
  if (!cmd_node || !cmd) {
    reply_error (c, id, "missing string member \"cmd\" (or {\"ack\": true})");
    return;
  }
  if (!g_strv_contains (page_commands, cmd)) {
    g_autofree char *msg = g_strdup_printf ("\"%s\" is not a command of the live view (capture, start, stop, "
                                            "cancel, status, dark, release, acquire, preview, set)", cmd);
    reply_error (c, id, msg);
    return;
  }
  if (c->bridge && !ds_live_bridge_is_open (c->bridge))
    g_clear_pointer (&c->bridge, ds_live_bridge_free);
  if (!c->bridge) {
    g_autoptr (GError) error = NULL;
    c->bridge = ds_live_bridge_new (c->live->server, on_bridge_line, c, &error);
    if (!c->bridge) {
      reply_error (c, id, error->message);
      return;
    }
  }
  /* The line as the page wrote it: the daemon checks it like any other. */
  g_autofree char *line = g_strndup (text, len);
  g_strdelimit (line, "\r\n", ' ');
  ds_live_bridge_send (c->bridge, line);
}

static void
client_free (Client *c)
{
  g_signal_handlers_disconnect_by_data (c->ws, c);
  ds_live_bridge_free (c->bridge);
  g_object_unref (c->ws);
  g_clear_object (&c->socket);
  g_free (c);
}

static void
on_closed (SoupWebsocketConnection *ws, gpointer data)
{
  (void) ws;
  Client *c = data;
  DsLiveView *lv = c->live;
  set_busy (c, TRUE); /* it takes nothing any more */
  g_ptr_array_remove_fast (lv->clients, c);
  client_free (c);
  /* What libsoup and the encoder buffered for it is freed; give the heap's unused top back so
   * that the daemon's size returns after a page leaves. */
  malloc_trim (0);
}

gboolean
ds_live_view_is_full (const DsLiveView *lv)
{
  return lv->clients->len >= lv->max_clients;
}

void
ds_live_view_add_client (DsLiveView *lv, SoupWebsocketConnection *ws, GSocket *socket)
{
  if (ds_live_view_is_full (lv)) {
    /* The HTTP server refused the upgrade already; a race of two at once ends here. */
    soup_websocket_connection_close (ws, SOUP_WEBSOCKET_CLOSE_POLICY_VIOLATION, "max-live-clients");
    return;
  }
  Client *c = g_new0 (Client, 1);
  c->live = lv;
  c->ws = g_object_ref (ws);
  c->socket = socket ? g_object_ref (socket) : NULL;
  /* Pages send acks and short commands only. */
  soup_websocket_connection_set_max_incoming_payload_size (ws, 64 * 1024);
  soup_websocket_connection_set_keepalive_interval (ws, 15);
  g_signal_connect (ws, "message", G_CALLBACK (on_message), c);
  g_signal_connect (ws, "closed", G_CALLBACK (on_closed), c);
  g_ptr_array_add (lv->clients, c);
  c->busy = TRUE;
  set_busy (c, FALSE);
  for (guint k = 0; k < N_KINDS; k++)
    c->dirty[k] = lv->latest[k] != NULL;
  try_send (c);
}

static gboolean
status_tick (gpointer data)
{
  DsLiveView *lv = data;
  if (lv->clients->len == 0)
    return G_SOURCE_CONTINUE;
  g_autoptr (JsonNode) status = lv->status_func (lv->status_data);
  g_autoptr (JsonBuilder) b = ds_json_object_begin ();
  ds_json_add_string (b, "type", "status");
  ds_json_add_node (b, "status", json_node_ref (status));
  g_autoptr (JsonNode) root = ds_json_object_end (b);
  char *text = json_to_string (root, FALSE);
  publish (lv, KIND_STATUS, g_bytes_new_take (text, strlen (text) + 1)); /* with its NUL, for send_text */
  return G_SOURCE_CONTINUE;
}

/* ---- the encoder thread ---- */

typedef struct {
  DsLiveView *live;
  Kind kind;
  GBytes *msg;
} Encoded;

static gboolean
deliver (gpointer data)
{
  Encoded *e = data;
  publish (e->live, e->kind, g_steal_pointer (&e->msg));
  return G_SOURCE_REMOVE;
}

static void
encoded_free (gpointer data)
{
  Encoded *e = data;
  if (e->msg)
    g_bytes_unref (e->msg);
  g_free (e);
}

static void
post (DsLiveView *lv, Kind kind, GBytes *msg)
{
  Encoded *e = g_new0 (Encoded, 1);
  e->live = lv;
  e->kind = kind;
  e->msg = msg;
  g_main_context_invoke_full (lv->context, G_PRIORITY_DEFAULT, deliver, e, encoded_free);
}

static gpointer
encoder_main (gpointer data)
{
  DsLiveView *lv = data;
  g_mutex_lock (&lv->lock);
  for (;;) {
    while (!lv->quit && !lv->frame && !lv->result)
      g_cond_wait (&lv->cond, &lv->lock);
    if (lv->quit)
      break;
    DsImage *frame = g_steal_pointer (&lv->frame);
    DsLiveFrameInfo info = lv->frame_info;
    DsResult *result = g_steal_pointer (&lv->result);
    g_autofree char *meta = g_steal_pointer (&lv->result_meta);
    g_mutex_unlock (&lv->lock);
    if (result) {
      post (lv, KIND_RESULT, ds_live_encode_result (ds_result_separation (result), meta, LIVE_MAX_SIDE));
      ds_result_unref (result);
    }
    if (frame)
      post (lv, KIND_FRAME, ds_live_encode_frame (frame, &info, LIVE_MAX_SIDE));
    g_mutex_lock (&lv->lock);
    if (frame) {
      /* Back as the next copy's buffer. */
      if (!lv->spare)
        lv->spare = frame;
      else
        ds_image_free (frame);
    }
  }
  g_mutex_unlock (&lv->lock);
  return NULL;
}

/* ---- inputs ---- */

void
ds_live_view_on_frame (const DsFrame *frame, guint phase, const DsCaptureSettings *settings, gpointer data)
{
  DsLiveView *lv = data;
  if (g_atomic_int_get (&lv->wanting) <= 0)
    return;
  gint64 now = g_get_monotonic_time ();
  g_mutex_lock (&lv->lock);
  if (now - lv->last_copy_us < lv->frame_interval_us) {
    g_mutex_unlock (&lv->lock);
    return;
  }
  lv->last_copy_us = now;
  const DsImage *src = frame->image;
  DsImage *dst = lv->frame ? lv->frame : g_steal_pointer (&lv->spare);
  if (dst && !(ds_image_same_shape (dst, src) && dst->stride >= src->width * ds_sample_size (src->type)))
    g_clear_pointer (&dst, ds_image_free);
  if (!dst)
    dst = ds_image_new (src->type, src->width, src->height, NULL);
  if (dst) {
    gsize row = src->width * ds_sample_size (src->type);
    for (guint y = 0; y < src->height; y++)
      memcpy (ds_image_row (dst, y), ds_image_row (src, y), row);
    dst->bit_depth = src->bit_depth;
    lv->frame = dst;
    lv->frame_info = (DsLiveFrameInfo) { .phase = phase, .n_phases = settings->phases, .frame_id = frame->frame_id,
                                         .period_px = settings->period_px, .saturation_dn = settings->saturation_dn,
                                         .exposure_us = frame->exposure_us, .gain_db = frame->gain_db,
                                         .time_unix_ms = g_get_real_time () / 1000 };
    g_cond_signal (&lv->cond);
  }
  g_mutex_unlock (&lv->lock);
}

void
ds_live_view_on_result (DsLiveView *lv, DsResult *result)
{
  if (lv->clients->len == 0)
    return;
  g_autoptr (JsonNode) meta = ds_result_to_json (result);
  char *text = json_to_string (meta, FALSE);
  g_mutex_lock (&lv->lock);
  if (lv->result) {
    lv->stats.superseded++; /* the encoder had not taken the previous one yet */
    ds_result_unref (lv->result);
    for (guint i = 0; i < lv->clients->len; i++)
      ((Client *) lv->clients->pdata[i])->results_skipped++;
  }
  lv->result = ds_result_ref (result);
  g_free (lv->result_meta);
  lv->result_meta = text;
  g_cond_signal (&lv->cond);
  g_mutex_unlock (&lv->lock);
}

DsLiveView *
ds_live_view_new (GMainContext *context, DsServer *server, const DsLiveViewLimits *limits, DsLiveStatusFunc status,
                  gpointer status_data)
{
  DsLiveView *lv = g_new0 (DsLiveView, 1);
  double max_fps = limits->max_fps;
  lv->max_clients = MAX (1, limits->max_clients);
  lv->send_budget = MAX (65536, limits->send_budget_bytes);
  lv->context = g_main_context_ref (context);
  lv->server = server;
  lv->status_func = status;
  lv->status_data = status_data;
  lv->frame_interval_us = (gint64) (1e6 / MAX (max_fps, 0.01));
  g_mutex_init (&lv->lock);
  g_cond_init (&lv->cond);
  lv->clients = g_ptr_array_new ();
  lv->encoder = g_thread_new ("live-encoder", encoder_main, lv);
  GSource *src = g_timeout_source_new (STATUS_INTERVAL_MS);
  g_source_set_callback (src, status_tick, lv, NULL);
  lv->status_source = g_source_attach (src, context);
  g_source_unref (src);
  return lv;
}

void
ds_live_view_free (DsLiveView *lv)
{
  if (!lv)
    return;
  GSource *src = g_main_context_find_source_by_id (lv->context, lv->status_source);
  if (src)
    g_source_destroy (src);
  g_mutex_lock (&lv->lock);
  lv->quit = TRUE;
  g_cond_signal (&lv->cond);
  g_mutex_unlock (&lv->lock);
  g_thread_join (lv->encoder);
  /* Updates the encoder posted and the loop has not delivered point at lv: deliver them now. */
  while (g_main_context_iteration (lv->context, FALSE))
    ;
  while (lv->clients->len) {
    Client *c = g_ptr_array_steal_index_fast (lv->clients, lv->clients->len - 1);
    soup_websocket_connection_close (c->ws, SOUP_WEBSOCKET_CLOSE_GOING_AWAY, "descatterd is stopping");
    client_free (c);
  }
  g_ptr_array_unref (lv->clients);
  for (guint k = 0; k < N_KINDS; k++)
    if (lv->latest[k])
      g_bytes_unref (lv->latest[k]);
  ds_image_free (lv->frame);
  ds_image_free (lv->spare);
  if (lv->result)
    ds_result_unref (lv->result);
  g_free (lv->result_meta);
  g_mutex_clear (&lv->lock);
  g_cond_clear (&lv->cond);
  g_main_context_unref (lv->context);
  g_free (lv);
}

void
ds_live_view_get_stats (DsLiveView *lv, DsLiveStats *stats)
{
  memset (stats, 0, sizeof *stats);
  stats->clients = lv->clients->len;
  stats->sent = lv->stats.sent;
  stats->superseded = lv->stats.superseded;
}
