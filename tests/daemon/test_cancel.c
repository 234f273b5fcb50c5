/* `cancel` end to end on the in-process simulated lab (docs/protocol.md, `cancel`): a real
 * daemon process, one connection capturing and another cancelling. The expectations are counts
 * the protocol defines, not times: a cancelled set acquired fewer frames than it asked for,
 * every one of them aborted; nothing was folded, published or spooled; nothing is acquired
 * after the reply. The ctest timeout is the only clock. */
#include <glib/gstdio.h>
#include <string.h>

#include "tests/common/daemon_harness.h"

#define LONG_PHASES 64
#define LONG_AVERAGES 8

static char *
config_text (const char *extra)
{
  return g_strdup_printf ("[camera]\nbackend=sim\n[illuminator]\nbackend=sim\n"
                          "[sim]\nscene=%s\nseed=7\n%s",
                          SCENE_FILE, extra ? extra : "");
}

static JsonNode *
status_body (DsClient *c, DsMessage **keep)
{
  *keep = test_daemon_call_ok (c, "status", NULL);
  return (*keep)->reply->body;
}

static guint
count_files (const char *dir_path)
{
  g_autoptr (GDir) dir = g_dir_open (dir_path, 0, NULL);
  guint n = 0;
  while (dir && g_dir_read_name (dir))
    n++;
  return n;
}

typedef struct {
  DsClient *canceller;
  DsMessage *cancel_reply; /* the cancel's, sent at the first progress event */
  guint progress;
} CancelAtProgress;

/* The capture's first progress event (a phase done, so the set is under way): cancel from the
 * other connection. Its reply comes once the daemon took the cancel. */
static void
on_capture_event (const DsMessage *ev, gpointer data)
{
  CancelAtProgress *cp = data;
  if (g_strcmp0 (ev->reply->event, "progress") != 0 || cp->progress++ > 0)
    return;
  g_autoptr (GError) error = NULL;
  cp->cancel_reply = ds_client_call (cp->canceller, "cancel", NULL, NULL, NULL, &error);
  g_assert_no_error (error);
}

/* A capture of 64 x 8 frames cancelled once its first phase is done: answered `cancelled`,
 * its frames aborted (fewer than the set's), no result spooled, status idle and still after the
 * reply; a capture after it works and is spooled. */
static void
test_cancel_capture (void)
{
  g_autofree char *tmp = g_dir_make_tmp ("descatter-cancel-XXXXXX", NULL);
  g_autofree char *spool = g_build_filename (tmp, "spool", NULL);
  g_autofree char *extra = g_strdup_printf ("[daemon]\nspool-dir=%s\n", spool);
  g_autofree char *conf = config_text (extra);
  TestDaemon *d = test_daemon_start (conf, NULL);
  g_autoptr (DsClient) a = test_daemon_connect (d);
  g_autoptr (DsClient) b = test_daemon_connect (d);
  TestFrames before = test_daemon_frames (b);

  g_autoptr (JsonObject) args = json_object_new ();
  json_object_set_int_member (args, "phases", LONG_PHASES);
  json_object_set_int_member (args, "averages", LONG_AVERAGES);
  json_object_set_boolean_member (args, "progress", TRUE);
  CancelAtProgress cp = { .canceller = b };
  g_autoptr (GError) error = NULL;
  g_autoptr (DsMessage) m = ds_client_call (a, "capture", args, on_capture_event, &cp, &error);
  g_assert_no_error (error);
  g_autoptr (DsMessage) cancel_reply = cp.cancel_reply;
  g_assert_nonnull (cancel_reply);
  g_assert_false (m->reply->ok);
  g_assert_cmpint (m->reply->error_code, ==, DS_PROTOCOL_ERROR_CANCELLED);
  /* The set stopped part way: fewer phases reported than it has. */
  g_assert_cmpuint (cp.progress, <, LONG_PHASES);

  g_assert_true (cancel_reply->reply->ok);
  g_assert_cmpint (test_json_int (cancel_reply->reply->body, "cancelled"), ==, 1);
  JsonObject *cr = json_node_get_object (cancel_reply->reply->body);
  g_assert_false (json_object_get_boolean_member (cr, "stream_stopped"));
  g_assert_cmpstr (json_object_get_string_member (cr, "state"), ==, "idle");

  TestFrames after = test_daemon_frames (b);
  gint64 acquired = after.acquired - before.acquired;
  g_assert_cmpint (acquired, >, 0);
  g_assert_cmpint (acquired, <, LONG_PHASES * LONG_AVERAGES);
  g_assert_cmpint (after.folded, ==, before.folded);
  /* Every frame of the set dropped (folded ones went down with it as aborted). */
  g_assert_cmpint (after.dropped - before.dropped, ==, acquired);
  g_assert_cmpint (after.aborted - before.aborted, >, 0);
  g_autoptr (DsMessage) keep = NULL;
  JsonNode *st = status_body (b, &keep);
  g_assert_cmpstr (json_object_get_string_member (json_node_get_object (st), "state"), ==, "idle");
  g_assert_cmpint (test_json_int (st, "sets_cancelled"), ==, 1);
  g_assert_cmpint (test_json_int (st, "sets_done"), ==, 0);
  g_assert_cmpint (test_json_int (st, "sets_failed"), ==, 0);
  g_assert_cmpint (test_json_int (st, "pending"), ==, 0);
  /* Nothing acquired after the reply: the same count a while later. */
  g_usleep (300 * 1000);
  TestFrames later = test_daemon_frames (b);
  g_assert_cmpint (later.acquired, ==, after.acquired);
  g_assert_cmpuint (count_files (spool), ==, 0);

  /* The daemon works on: a capture after the cancel is answered and spooled. */
  g_autoptr (JsonObject) small = json_object_new ();
  json_object_set_int_member (small, "phases", 8);
  g_autoptr (DsMessage) ok = test_daemon_call_ok (a, "capture", small);
  test_daemon_stop_clean (d);
  g_assert_cmpuint (count_files (spool), >, 0);
  g_autofree char *cmd = g_strdup_printf ("rm -rf '%s'", tmp);
  g_assert_cmpint (system (cmd), ==, 0);
}

/* Continuous mode cancelled after its first result: the stream stops, status says so, and no
 * frame is acquired after the reply. */
static void
test_cancel_stream (void)
{
  g_autofree char *conf = config_text ("[acquisition]\nphases=8\n");
  TestDaemon *d = test_daemon_start (conf, NULL);
  g_autoptr (DsClient) c = test_daemon_connect (d);
  g_autoptr (DsMessage) sub = test_daemon_call_ok (c, "subscribe", NULL);
  g_autoptr (DsMessage) start = test_daemon_call_ok (c, "start", NULL);
  for (guint got = 0; got < 1;) {
    g_autoptr (DsMessage) ev = ds_client_read (c, 60000, NULL);
    g_assert_nonnull (ev);
    got += g_strcmp0 (ev->reply->event, "result") == 0;
  }
  g_autoptr (DsMessage) cancel = test_daemon_call_ok (c, "cancel", NULL);
  JsonObject *cr = json_node_get_object (cancel->reply->body);
  g_assert_true (json_object_get_boolean_member (cr, "stream_stopped"));
  g_assert_cmpint (json_object_get_int_member (cr, "cancelled"), ==, 0);
  g_assert_cmpstr (json_object_get_string_member (cr, "state"), ==, "idle");
  g_autoptr (DsMessage) keep = NULL;
  JsonNode *st = status_body (c, &keep);
  g_assert_false (json_object_get_boolean_member (json_node_get_object (st), "continuous"));
  g_assert_cmpstr (json_object_get_string_member (json_node_get_object (st), "state"), ==, "idle");
  TestFrames after = test_daemon_frames (c);
  g_usleep (300 * 1000);
  TestFrames later = test_daemon_frames (c);
  g_assert_cmpint (later.acquired, ==, after.acquired);
  test_daemon_stop_clean (d);
}

/* Nothing running: answered at once with nothing cancelled. */
static void
test_cancel_idle (void)
{
  g_autofree char *conf = config_text (NULL);
  TestDaemon *d = test_daemon_start (conf, NULL);
  g_autoptr (DsClient) c = test_daemon_connect (d);
  g_autoptr (DsMessage) cancel = test_daemon_call_ok (c, "cancel", NULL);
  JsonObject *cr = json_node_get_object (cancel->reply->body);
  g_assert_cmpint (json_object_get_int_member (cr, "cancelled"), ==, 0);
  g_assert_false (json_object_get_boolean_member (cr, "stream_stopped"));
  g_assert_cmpstr (json_object_get_string_member (cr, "state"), ==, "idle");
  /* Arguments are refused, as for every command without any. */
  g_autoptr (JsonObject) args = json_object_new ();
  json_object_set_int_member (args, "tag", 3);
  g_autoptr (GError) error = NULL;
  g_autoptr (DsMessage) bad = ds_client_call (c, "cancel", args, NULL, NULL, &error);
  g_assert_no_error (error);
  g_assert_false (bad->reply->ok);
  g_assert_cmpint (bad->reply->error_code, ==, DS_PROTOCOL_ERROR_BAD_ARGUMENT);
  test_daemon_stop_clean (d);
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  g_test_add_func ("/cancel/capture", test_cancel_capture);
  g_test_add_func ("/cancel/stream", test_cancel_stream);
  g_test_add_func ("/cancel/idle", test_cancel_idle);
  return g_test_run ();
}
