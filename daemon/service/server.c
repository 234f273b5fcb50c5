#include "daemon/service/server_private.h"
#include "daemon/service/accept_loop.h"
#include "daemon/service/json_build.h"
#include "daemon/service/token.h"

#include "build_info.h"

#include <errno.h>
#include <gio/gunixsocketaddress.h>
#include <glib/gstdio.h>
#include <string.h>
#include <sys/stat.h>
#include <systemd/sd-daemon.h>


static gboolean sweep_connections (gpointer data);
static void on_accepted (GSocketConnection *sc, gpointer user_data);

/* Subscribed or not, frames or not, with the count of frame subscribers kept. */
static void
set_subscription (DsServer *s, ClientState *st, gboolean subscribed, gboolean frames)
{
  frames = subscribed && frames;
  if (subscribed && !st->subscribed)
    st->skipped = 0; /* results before the subscription are none of its skipped */
  if (frames != st->frames)
    g_atomic_int_add (&s->frame_subscribers, frames ? 1 : -1);
  st->subscribed = subscribed;
  st->frames = frames;
}

DsServer *
ds_server_new (const DsServerLimits *limits, DsServerRequestFunc on_request, gpointer user_data)
{
  DsServer *s = g_new0 (DsServer, 1);
  s->limits = *limits;
  s->limits.token = g_strdup (limits->token);
  if (s->limits.max_line == 0 || s->limits.max_line > DS_PROTOCOL_MAX_LINE)
    s->limits.max_line = DS_PROTOCOL_MAX_LINE;
  s->on_request = on_request;
  s->user_data = user_data;
  s->listener = g_socket_listener_new ();
  s->accepting = ds_accept_loop_new (s->listener, on_accepted, s);
  /* GLib's default backlog (10) refuses bursts of clients connecting at once; the client
   * limit is enforced after accept, with a clear `limit` error instead. */
  g_socket_listener_set_backlog (s->listener, 256);
  s->clients = g_hash_table_new_full (g_direct_hash, g_direct_equal,
                                      (GDestroyNotify) ds_connection_unref, NULL);
  if (s->limits.max_tcp_clients == 0 || s->limits.max_tcp_clients > s->limits.max_clients)
    s->limits.max_tcp_clients = MAX (1, s->limits.max_clients / 2);
  if (s->limits.evict_quiet_ms == 0)
    s->limits.evict_quiet_ms = 1000;
  s->context = g_main_context_ref_thread_default ();
  /* One timer for all connections; its period bounds how late a timeout is noticed. */
  guint shortest = 1000;
  if (s->limits.idle_timeout_ms)
    shortest = MIN (shortest, s->limits.idle_timeout_ms);
  if (s->limits.auth_timeout_ms)
    shortest = MIN (shortest, s->limits.auth_timeout_ms);
  s->sweep = g_timeout_source_new (CLAMP (shortest / 4, 20, 250));
  g_source_set_callback (s->sweep, sweep_connections, s, NULL);
  g_source_attach (s->sweep, s->context);
  return s;
}

static void
stop_listening (DsServer *server)
{
  ds_accept_loop_stop (server->accepting);
  g_socket_listener_close (server->listener);
}

void
ds_server_shutdown (DsServer *server)
{
  stop_listening (server);
  GList *conns = g_hash_table_get_keys (server->clients);
  for (GList *l = conns; l; l = l->next)
    ds_connection_close (l->data);
  g_list_free (conns);
}

void
ds_server_free (DsServer *server)
{
  if (!server)
    return;
  ds_server_shutdown (server);
  /* Connections may still have closing callbacks queued; they hold their own references. */
  GList *conns = g_hash_table_get_keys (server->clients);
  for (GList *l = conns; l; l = l->next) {
    ClientState *st = ds_connection_get_data (l->data);
    if (st)
      st->server = NULL;
  }
  g_list_free (conns);
  g_hash_table_destroy (server->clients);
  ds_accept_loop_free (server->accepting);
  g_clear_object (&server->listener);
  g_source_destroy (server->sweep);
  g_source_unref (server->sweep);
  g_main_context_unref (server->context);
  if (server->unix_path)
    g_unlink (server->unix_path);
  g_free (server->unix_path);
  g_free (server->limits.token);
  g_free (server);
}

/* What for_each_subscriber does for one connection; returns whether it received the event. */
typedef gboolean (*SubscriberFunc) (DsServer *server, DsConnection *c, ClientState *st, gpointer data);

/* Calls `func` for every open connection subscribed to this kind of event: results and events,
 * or preview frames (`frames`). Returns how many received it. */
static guint
for_each_subscriber (DsServer *server, gboolean frames, SubscriberFunc func, gpointer data)
{
  guint delivered = 0;
  GHashTableIter it;
  gpointer key;
  g_hash_table_iter_init (&it, server->clients);
  while (g_hash_table_iter_next (&it, &key, NULL)) {
    DsConnection *c = key;
    ClientState *st = ds_connection_get_data (c);
    if (!st || !(frames ? st->frames : st->subscribed) || ds_connection_is_closed (c))
      continue;
    if (func (server, c, st, data))
      delivered++;
  }
  return delivered;
}

typedef struct {
  GBytes *line; /* shared by every receiver, like the payloads */
  GBytes *const *payloads;
  guint n_payloads;
  guint64 *dropped;
} Broadcast;

/* Droppable: a client reading slower than the daemon produces loses events (a gap in their
 * seq), never the daemon's time. */
static gboolean
send_droppable (DsServer *server, DsConnection *c, ClientState *st, gpointer data)
{
  (void) server;
  (void) st;
  Broadcast *b = data;
  if (ds_connection_send (c, b->line, b->payloads, b->n_payloads, TRUE))
    return TRUE;
  (*b->dropped)++;
  return FALSE;
}

/* Sends one line to the subscribed connections that asked for this kind of event; returns how
 * many received it, *dropped counts the others. */
static guint
broadcast (DsServer *server, GBytes *line, GBytes *const *payloads, guint n_payloads, gboolean frames,
           guint64 *dropped)
{
  Broadcast b = { line, payloads, n_payloads, dropped };
  return for_each_subscriber (server, frames, send_droppable, &b);
}

typedef struct {
  guint64 seq;
  JsonNode *body;
  const DsPayloadInfo *infos;
  GBytes *const *payloads;
  guint n_payloads;
  gboolean newest_only;
  GBytes *shared; /* the line of a client that skipped nothing */
} ResultEvent;

/* One result to one subscriber, with the results it was not sent counted in `skipped`: those
 * dropped since its last result, and with newest_only the one this result replaces. */
static gboolean
send_result (DsServer *server, DsConnection *c, ClientState *st, gpointer data)
{
  ResultEvent *r = data;
  gboolean replaces = r->newest_only && ds_connection_has_newest_waiting (c);
  guint64 skipped = st->skipped + (replaces ? st->waiting_skipped + 1 : 0);
  g_autoptr (GBytes) own = NULL;
  if (skipped > 0) {
    /* Only a client that fell behind gets a line of its own. */
    gsize own_len = 0;
    char *own_text = ds_result_event_build (r->seq, skipped, r->body, r->infos, r->n_payloads, &own_len);
    own = g_bytes_new_take (own_text, own_len);
  }
  GBytes *line = own ? own : r->shared;
  gboolean sent = r->newest_only ? ds_connection_send_newest (c, line, r->payloads, r->n_payloads)
                                 : ds_connection_send (c, line, r->payloads, r->n_payloads, TRUE);
  if (!sent) {
    st->skipped++;
    server->stats.dropped++;
    return FALSE;
  }
  if (replaces)
    server->stats.dropped++; /* the one it replaced, never sent */
  st->skipped = 0;
  if (r->newest_only)
    st->waiting_skipped = skipped;
  return TRUE;
}

guint
ds_server_publish_result (DsServer *server, JsonNode *body, const DsPayloadInfo *infos, GBytes *const *payloads,
                          guint n_payloads, gboolean newest_only)
{
  guint64 seq = ++server->seq;
  server->stats.published++;
  gsize len = 0;
  g_autofree char *text = ds_result_event_build (seq, 0, body, infos, n_payloads, &len);
  g_autoptr (GBytes) shared = g_bytes_new (text, len);
  ResultEvent r = { seq, body, infos, payloads, n_payloads, newest_only, shared };
  return for_each_subscriber (server, FALSE, send_result, &r);
}

guint
ds_server_publish (DsServer *server, const char *event, JsonNode *body, const DsPayloadInfo *infos,
                   GBytes *const *payloads, guint n_payloads)
{
  gsize len = 0;
  g_autofree char *text = ds_event_build (event, ++server->seq, body, infos, n_payloads, &len);
  g_autoptr (GBytes) line = g_bytes_new (text, len);
  server->stats.published++;
  return broadcast (server, line, payloads, n_payloads, FALSE, &server->stats.dropped);
}

guint
ds_server_publish_frame (DsServer *server, JsonNode *body, const DsPayloadInfo *info, GBytes *payload)
{
  gsize len = 0;
  g_autofree char *text = ds_event_build ("frame", ++server->frame_seq, body, info, 1, &len);
  g_autoptr (GBytes) line = g_bytes_new (text, len);
  /* Frames lost to slow readers are not results lost: they count apart from stats.dropped. */
  guint64 frames_dropped = 0;
  return broadcast (server, line, &payload, 1, TRUE, &frames_dropped);
}

guint
ds_server_frame_subscribers (DsServer *server)
{
  return (guint) g_atomic_int_get (&server->frame_subscribers);
}

static void
handle_hello (DsServer *s, DsConnection *conn, ClientState *st, DsRequest *req)
{
  g_autoptr (GError) error = NULL;
  const char *const allowed[] = { "token", "client", NULL };
  if (!ds_request_check_keys (req, allowed, &error)) {
    ds_server_reply_error (s, conn, req->id, error);
    return;
  }
  for (guint i = 0; allowed[i]; i++) {
    JsonNode *v = json_object_get_member (req->args, allowed[i]);
    if (v && (!JSON_NODE_HOLDS_VALUE (v) || json_node_get_value_type (v) != G_TYPE_STRING)) {
      g_set_error (&error, DS_PROTOCOL_ERROR, DS_PROTOCOL_ERROR_BAD_ARGUMENT, "hello: \"%s\" must be a string",
                   allowed[i]);
      ds_server_reply_error (s, conn, req->id, error);
      return;
    }
  }
  if (st->is_tcp && s->limits.token) {
    JsonNode *t = json_object_get_member (req->args, "token");
    const char *given = t ? json_node_get_string (t) : NULL;
    if (!ds_token_equal (s->limits.token, given)) {
      g_set_error (&error, DS_PROTOCOL_ERROR, DS_PROTOCOL_ERROR_UNAUTHORIZED, "hello: wrong or missing token");
      ds_server_reply_error (s, conn, req->id, error);
      ds_connection_close_after_flush (conn);
      return;
    }
  }
  st->authenticated = TRUE;
  g_autoptr (JsonBuilder) b = ds_json_object_begin ();
  ds_json_add_string (b, "server", "descatterd");
  ds_json_add_string (b, "version", DS_VERSION);
  ds_json_add_string (b, "git", DS_GIT_DESCRIBE);
  ds_json_add_int (b, "protocol", DS_PROTOCOL_VERSION);
  ds_json_add_uint (b, "max_line", s->limits.max_line);
  g_autoptr (JsonNode) result = ds_json_object_end (b);
  ds_server_reply_ok (s, conn, req->id, result, NULL, NULL, 0);
}

static void
handle_subscription (DsServer *s, DsConnection *conn, ClientState *st, DsRequest *req, gboolean on)
{
  g_autoptr (GError) error = NULL;
  const char *const allowed_on[] = { "frames", NULL };
  const char *const allowed_off[] = { NULL };
  gboolean frames = FALSE;
  if (!ds_request_check_keys (req, on ? allowed_on : allowed_off, &error) ||
      !ds_request_get_bool (req, "frames", FALSE, &frames, &error)) {
    ds_server_reply_error (s, conn, req->id, error);
    return;
  }
  set_subscription (s, st, on, frames);
  g_autoptr (JsonBuilder) b = ds_json_object_begin ();
  ds_json_add_bool (b, "subscribed", on);
  ds_json_add_bool (b, "frames", st->frames);
  ds_json_add_uint (b, "next_seq", s->seq + 1);
  g_autoptr (JsonNode) result = ds_json_object_end (b);
  ds_server_reply_ok (s, conn, req->id, result, NULL, NULL, 0);
}

static void
handle_subscribe (DsServer *s, DsConnection *conn, ClientState *st, DsRequest *req)
{
  handle_subscription (s, conn, st, req, TRUE);
}

static void
handle_unsubscribe (DsServer *s, DsConnection *conn, ClientState *st, DsRequest *req)
{
  handle_subscription (s, conn, st, req, FALSE);
}

/* The commands the server answers itself; every other one goes to the service's handler. Only
 * hello may come before the token (a TCP client's first request). */
static const struct {
  const char *cmd;
  gboolean before_token;
  void (*handle) (DsServer *s, DsConnection *conn, ClientState *st, DsRequest *req);
} server_commands[] = {
  { "hello", TRUE, handle_hello },
  { "subscribe", FALSE, handle_subscribe },
  { "unsubscribe", FALSE, handle_unsubscribe },
};

void
ds_server_add_own_commands (GPtrArray *names)
{
  for (guint i = 0; i < G_N_ELEMENTS (server_commands); i++)
    g_ptr_array_add (names, (gpointer) server_commands[i].cmd);
}

/* ---- the connection policy (docs/protocol.md, "Connections") ---- */

static gboolean
holds_place (DsConnection *conn, const ClientState *st)
{
  return st && !st->bridge && !st->leaving && !ds_connection_is_closed (conn);
}

static void
count_places (DsServer *s, guint *all, guint *tcp)
{
  *all = *tcp = 0;
  GHashTableIter it;
  gpointer key;
  g_hash_table_iter_init (&it, s->clients);
  while (g_hash_table_iter_next (&it, &key, NULL)) {
    ClientState *st = ds_connection_get_data (key);
    if (!holds_place (key, st))
      continue;
    (*all)++;
    *tcp += st->is_tcp;
  }
}

/* Says why on the connection (an error line with a null id), then closes it once that is
 * written; its place is free at once. */
static void
dismiss (DsConnection *conn, ClientState *st, DsProtocolError code, const char *why)
{
  g_autoptr (GError) error = g_error_new_literal (DS_PROTOCOL_ERROR, code, why);
  gsize len = 0;
  char *line = ds_reply_build_error (NULL, error, &len);
  g_autoptr (GBytes) b = g_bytes_new_take (line, len);
  ds_connection_send (conn, b, NULL, 0, FALSE);
  st->leaving = TRUE;
  st->leaving_us = g_get_monotonic_time ();
  set_subscription (st->server, st, FALSE, FALSE);
  ds_connection_close_after_flush (conn);
}

static gboolean
sweep_connections (gpointer data)
{
  DsServer *s = data;
  gint64 now = g_get_monotonic_time ();
  GHashTableIter it;
  gpointer key;
  g_hash_table_iter_init (&it, s->clients);
  while (g_hash_table_iter_next (&it, &key, NULL)) {
    DsConnection *conn = key;
    ClientState *st = ds_connection_get_data (conn);
    if (!st || ds_connection_is_closed (conn))
      continue;
    if (st->leaving) {
      /* It does not read its last line: it gets no longer than this. */
      if (now - st->leaving_us > LEAVING_GRACE_US)
        ds_connection_close (conn);
      continue;
    }
    if (ds_connection_is_busy (conn)) {
      st->active_us = now;
      continue;
    }
    if (st->is_tcp && !st->authenticated && s->limits.auth_timeout_ms &&
        now - st->accepted_us > (gint64) s->limits.auth_timeout_ms * 1000) {
      g_autofree char *why = g_strdup_printf ("no hello with the token within %u ms: closed",
                                              s->limits.auth_timeout_ms);
      s->stats.timed_out++;
      dismiss (conn, st, DS_PROTOCOL_ERROR_UNAUTHORIZED, why);
      continue;
    }
    if (!st->subscribed && s->limits.idle_timeout_ms &&
        now - st->active_us > (gint64) s->limits.idle_timeout_ms * 1000) {
      g_autofree char *why = g_strdup_printf ("no complete request for %u ms (idle-timeout-ms): closed",
                                              s->limits.idle_timeout_ms);
      s->stats.timed_out++;
      dismiss (conn, st, DS_PROTOCOL_ERROR_LIMIT, why);
    }
  }
  return G_SOURCE_CONTINUE;
}

/* The connection to close so that a newcomer fits, or NULL: one that owes the token, else the
 * one quiet longest; never a subscriber, one being answered, or one quiet for less than
 * evict_quiet_ms (a newcomer gets that long to send its first request). A TCP newcomer only
 * ever displaces TCP connections. */
static DsConnection *
find_room (DsServer *s, gboolean newcomer_tcp)
{
  gint64 now = g_get_monotonic_time ();
  gint64 quiet_us = (gint64) s->limits.evict_quiet_ms * 1000;
  DsConnection *unauthenticated = NULL, *quiet = NULL;
  gint64 oldest_accept = G_MAXINT64, oldest_active = G_MAXINT64;
  GHashTableIter it;
  gpointer key;
  g_hash_table_iter_init (&it, s->clients);
  while (g_hash_table_iter_next (&it, &key, NULL)) {
    ClientState *st = ds_connection_get_data (key);
    if (!holds_place (key, st) || (newcomer_tcp && !st->is_tcp) || ds_connection_is_busy (key))
      continue;
    if (st->is_tcp && !st->authenticated && now - st->accepted_us >= quiet_us &&
        st->accepted_us < oldest_accept) {
      oldest_accept = st->accepted_us;
      unauthenticated = key;
    }
    if (!st->subscribed && now - st->active_us >= quiet_us && st->active_us < oldest_active) {
      oldest_active = st->active_us;
      quiet = key;
    }
  }
  return unauthenticated ? unauthenticated : quiet;
}

static guint
close_departed (DsServer *s)
{
  guint n = 0;
  GHashTableIter it;
  gpointer key;
  g_hash_table_iter_init (&it, s->clients);
  while (g_hash_table_iter_next (&it, &key, NULL))
    if (holds_place (key, ds_connection_get_data (key)) && ds_connection_peer_gone (key)) {
      ds_connection_close (key);
      n++;
    }
  return n;
}

static void
on_line (DsConnection *conn, const char *line, gsize len, gboolean too_long, gpointer user_data)
{
  ClientState *st = user_data;
  DsServer *s = st->server;
  if (!s || st->leaving)
    return;
  if (!too_long && len == 0)
    return; /* blank lines are ignored: not answered, and not a sign of life either */
  st->active_us = g_get_monotonic_time ();
  s->stats.requests++;
  g_autoptr (GError) error = NULL;
  if (too_long) {
    g_set_error (&error, DS_PROTOCOL_ERROR, DS_PROTOCOL_ERROR_LINE_TOO_LONG,
                 "request line longer than %zu bytes; discarded up to its newline", s->limits.max_line);
    ds_server_reply_error (s, conn, NULL, error);
    return;
  }
  JsonNode *id = NULL;
  g_autoptr (DsRequest) req = ds_request_parse (line, len, &id, &error);
  if (!req) {
    ds_server_reply_error (s, conn, id, error);
    if (id)
      json_node_unref (id);
    return;
  }
  if (s->draining) {
    g_set_error (&error, DS_PROTOCOL_ERROR, DS_PROTOCOL_ERROR_CANCELLED, "%s: the daemon is stopping",
                 req->cmd);
    ds_server_reply_error (s, conn, req->id, error);
    return;
  }
  guint own = 0;
  while (own < G_N_ELEMENTS (server_commands) && strcmp (req->cmd, server_commands[own].cmd) != 0)
    own++;
  gboolean is_own = own < G_N_ELEMENTS (server_commands);
  if (!st->authenticated && !(is_own && server_commands[own].before_token)) {
    g_set_error (&error, DS_PROTOCOL_ERROR, DS_PROTOCOL_ERROR_UNAUTHORIZED,
                 "%s: send hello with the token first", req->cmd);
    ds_server_reply_error (s, conn, req->id, error);
    return;
  }
  if (is_own)
    server_commands[own].handle (s, conn, st, req);
  else
    s->on_request (s, conn, req, s->user_data);
}

static void
on_closed (DsConnection *conn, gpointer user_data)
{
  ClientState *st = user_data;
  DsServer *s = st->server;
  if (!s)
    return;
  set_subscription (s, st, FALSE, FALSE);
  g_hash_table_remove (s->clients, conn);
}

/* A new client on `stream`; already authenticated when `trusted` (the live view's bridge),
 * else as its transport says. */
static void
add_client (DsServer *s, GIOStream *stream, gboolean is_tcp, gboolean trusted)
{
  ClientState *st = g_new0 (ClientState, 1);
  st->server = s;
  st->is_tcp = is_tcp;
  st->accepted_us = st->active_us = g_get_monotonic_time ();
  /* UNIX clients were let in by the socket's file permissions; TCP ones need the token when
   * one is configured. */
  st->authenticated = trusted || !(is_tcp && s->limits.token);
  st->bridge = trusted;
  DsConnectionLimits cl = { .max_line = s->limits.max_line, .max_queued_bytes = s->limits.max_queued_bytes };
  DsConnection *conn = ds_connection_new (stream, &cl, on_line, on_closed, st);
  ds_connection_set_data (conn, st, g_free);
  s->stats.accepted++;
  guint all, tcp;
  count_places (s, &all, &tcp);
  if (!trusted && (all >= s->limits.max_clients || (is_tcp && tcp >= s->limits.max_tcp_clients))) {
    /* A peer that already went away holds its place only until its EOF is read; under load
     * the accept may come first: close those now. */
    if (close_departed (s))
      count_places (s, &all, &tcp);
  }
  if (!trusted && (all >= s->limits.max_clients || (is_tcp && tcp >= s->limits.max_tcp_clients))) {
    DsConnection *victim = find_room (s, is_tcp);
    if (!victim) {
      s->stats.refused++;
      g_autoptr (GError) error = g_error_new (
          DS_PROTOCOL_ERROR, DS_PROTOCOL_ERROR_LIMIT,
          "too many clients (%u of max-clients %u, %u of max-tcp-clients %u), none quiet for %u ms to make room",
          all, s->limits.max_clients, tcp, s->limits.max_tcp_clients, s->limits.evict_quiet_ms);
      ds_server_reply_error (NULL, conn, NULL, error);
      st->server = NULL;
      ds_connection_close_after_flush (conn);
      ds_connection_unref (conn);
      return;
    }
    ClientState *vst = ds_connection_get_data (victim);
    g_autofree char *why = g_strdup_printf (
        "closed to make room for a new connection (quiet for %.1f s while the server was full)",
        (double) (g_get_monotonic_time () - vst->active_us) / 1e6);
    s->stats.evicted++;
    dismiss (victim, vst, DS_PROTOCOL_ERROR_LIMIT, why);
  }
  g_hash_table_add (s->clients, conn);
  ds_connection_start (conn);
}

static void
on_accepted (GSocketConnection *sc, gpointer user_data)
{
  DsServer *s = user_data;
  GSocketAddress *remote = g_socket_connection_get_remote_address (sc, NULL);
  gboolean is_tcp = remote && G_IS_INET_SOCKET_ADDRESS (remote);
  g_clear_object (&remote);
  add_client (s, G_IO_STREAM (sc), is_tcp, FALSE);
}

void
ds_server_add_stream (DsServer *server, GIOStream *stream)
{
  add_client (server, stream, FALSE, TRUE);
}

static gboolean
keep_waking (gpointer data)
{
  (void) data;
  return G_SOURCE_CONTINUE;
}

void
ds_server_begin_stop (DsServer *server)
{
  server->draining = TRUE;
}

void
ds_server_drain (DsServer *server, guint timeout_ms)
{
  server->draining = TRUE;
  gint64 started = g_get_monotonic_time ();
  gint64 deadline = started + (gint64) timeout_ms * 1000;
  /* Wakes the blocking iteration below even when no connection makes progress. */
  g_autoptr (GSource) wake = g_timeout_source_new (20);
  g_source_set_callback (wake, keep_waking, NULL, NULL);
  g_source_attach (wake, server->context);
  for (;;) {
    /* Everything ready now: accepts from the backlog, requests already sent, writes. */
    while (g_main_context_iteration (server->context, FALSE))
      ;
    gboolean open = FALSE;
    GHashTableIter it;
    gpointer key;
    g_hash_table_iter_init (&it, server->clients);
    while (g_hash_table_iter_next (&it, &key, NULL)) {
      DsConnection *conn = key;
      if (!ds_connection_is_busy (conn) && !ds_connection_has_unread_input (conn))
        ds_connection_close_after_flush (conn);
      /* A peer that reads nothing (a stuck subscriber) does not hold the stop up; counted from
       * the stop, not from when it stopped reading. */
      if (MIN (ds_connection_stalled_us (conn), g_get_monotonic_time () - started) > DRAIN_STALL_US)
        ds_connection_close (conn);
      open |= !ds_connection_is_closed (conn);
    }
    if (!open || g_get_monotonic_time () >= deadline)
      break;
    g_main_context_iteration (server->context, TRUE);
  }
  g_source_destroy (wake);
  stop_listening (server);
}

static gboolean
ensure_started (DsServer *s)
{
  ds_accept_loop_start (s->accepting);
  return TRUE;
}

gboolean
ds_server_listen_unix (DsServer *server, const char *path, guint mode, GError **error)
{
  struct stat stbuf;
  if (lstat (path, &stbuf) == 0) {
    if (!S_ISSOCK (stbuf.st_mode)) {
      g_set_error (error, G_IO_ERROR, G_IO_ERROR_EXISTS, "%s exists and is not a socket; not replacing it",
                   path);
      return FALSE;
    }
    /* A socket file may be left over from a crash; replace it only if nobody answers. */
    g_autoptr (GSocketClient) probe = g_socket_client_new ();
    g_autoptr (GSocketAddress) addr = g_unix_socket_address_new (path);
    g_autoptr (GSocketConnection) live =
      g_socket_client_connect (probe, G_SOCKET_CONNECTABLE (addr), NULL, NULL);
    if (live) {
      g_set_error (error, G_IO_ERROR, G_IO_ERROR_ADDRESS_IN_USE,
                   "%s: another daemon is listening there", path);
      return FALSE;
    }
    g_unlink (path);
  }
  g_autoptr (GSocketAddress) addr = g_unix_socket_address_new (path);
  if (!g_socket_listener_add_address (server->listener, addr, G_SOCKET_TYPE_STREAM,
                                      G_SOCKET_PROTOCOL_DEFAULT, NULL, NULL, error)) {
    g_prefix_error (error, "%s: ", path);
    return FALSE;
  }
  if (chmod (path, mode) != 0) {
    g_set_error (error, G_IO_ERROR, g_io_error_from_errno (errno), "%s: chmod %o: %s", path, mode,
                 g_strerror (errno));
    return FALSE;
  }
  g_free (server->unix_path);
  server->unix_path = g_strdup (path);
  return ensure_started (server);
}

gboolean
ds_server_listen_tcp (DsServer *server, const char *address, guint16 port, GError **error)
{
  g_autoptr (GInetAddress) ia = g_inet_address_new_from_string (address);
  if (!ia) {
    g_set_error (error, G_IO_ERROR, G_IO_ERROR_INVALID_ARGUMENT, "TCP address \"%s\" is not an IP address",
                 address);
    return FALSE;
  }
  if (!g_inet_address_get_is_loopback (ia) && !server->limits.token) {
    g_set_error (error, G_IO_ERROR, G_IO_ERROR_PERMISSION_DENIED,
                 "TCP on %s (not loopback) requires a token file", address);
    return FALSE;
  }
  g_autoptr (GSocketAddress) sa = g_inet_socket_address_new (ia, port);
  g_autoptr (GSocketAddress) effective = NULL;
  if (!g_socket_listener_add_address (server->listener, sa, G_SOCKET_TYPE_STREAM,
                                      G_SOCKET_PROTOCOL_TCP, NULL, &effective, error)) {
    g_prefix_error (error, "%s:%u: ", address, port);
    return FALSE;
  }
  server->tcp_port = g_inet_socket_address_get_port (G_INET_SOCKET_ADDRESS (effective));
  return ensure_started (server);
}

guint16
ds_server_tcp_port (const DsServer *server)
{
  return server->tcp_port;
}

guint
ds_server_adopt_systemd_sockets (DsServer *server, GError **error)
{
  int n = sd_listen_fds (TRUE);
  if (n < 0) {
    g_set_error (error, G_IO_ERROR, g_io_error_from_errno (-n), "sd_listen_fds: %s", g_strerror (-n));
    return 0;
  }
  for (int i = 0; i < n; i++) {
    g_autoptr (GSocket) sock = g_socket_new_from_fd (SD_LISTEN_FDS_START + i, error);
    if (!sock || !g_socket_listener_add_socket (server->listener, sock, NULL, error))
      return 0;
  }
  if (n > 0)
    ensure_started (server);
  return (guint) n;
}

void
ds_server_get_stats (const DsServer *server, DsServerStats *stats)
{
  *stats = server->stats;
  stats->queued_bytes = 0;
  stats->max_client_queued_bytes = 0;
  count_places ((DsServer *) server, &stats->clients, &stats->tcp_clients);
  stats->subscribers = 0;
  GHashTableIter it;
  gpointer key;
  g_hash_table_iter_init (&it, server->clients);
  while (g_hash_table_iter_next (&it, &key, NULL)) {
    ClientState *st = ds_connection_get_data (key);
    if (holds_place (key, st) && st->subscribed)
      stats->subscribers++;
    gsize q = ds_connection_queued_bytes (key);
    stats->queued_bytes += q;
    stats->max_client_queued_bytes = MAX (stats->max_client_queued_bytes, q);
  }
}
