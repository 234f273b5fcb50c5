/* Continuous acquisition on a rig whose sets all fail stops by itself after [acquisition]
 * max-failed-sets failures in a row (docs/protocol.md, `stream_stopped`). The rig: the
 * in-process simulated lab whose illuminator controller answers busy to every phase it is
 * asked to light (the `not-ready` fault), so that every set fails at its first phase. (A
 * controller that lights every phase one step off is no such rig: the first set learns the
 * offset, and the sets succeed.) The expectations are
 * the configured count and the protocol's promises: exactly that many sets failed, then a
 * `stream_stopped` event, status no longer continuous, last_error saying when and why. */
#include <string.h>

#include "tests/common/daemon_harness.h"

#define MAX_FAILED 3

static void
test_failing_stream_stops (void)
{
  g_autofree char *conf = g_strdup_printf ("[camera]\nbackend=sim\n[illuminator]\nbackend=sim\n"
                                           "[acquisition]\nphases=4\ndark-frame=false\nphase-retries=1\n"
                                           "max-failed-sets=%d\n[sim]\nscene=%s\nseed=7\nfaults=not-ready=1\n",
                                           MAX_FAILED, SCENE_FILE);
  TestDaemon *d = test_daemon_start (conf, NULL);
  g_autoptr (DsClient) sub = test_daemon_connect (d);
  g_autoptr (DsClient) c = test_daemon_connect (d);
  g_autoptr (DsMessage) s = test_daemon_call_ok (sub, "subscribe", NULL);
  g_autoptr (DsMessage) started = test_daemon_call_ok (c, "start", NULL);

  guint failed_events = 0, results = 0;
  g_autofree char *reason = NULL;
  while (!reason) {
    g_autoptr (GError) error = NULL;
    /* The ctest timeout is the clock: events come as the sets fail. */
    g_autoptr (DsMessage) ev = ds_client_read (sub, 0, &error);
    g_assert_no_error (error);
    const char *kind = ev->reply->event;
    if (g_strcmp0 (kind, "failed") == 0) {
      failed_events++;
      g_test_message ("failed: %s", json_object_get_string_member (json_node_get_object (ev->reply->body), "reason"));
    } else if (g_strcmp0 (kind, "result") == 0)
      results++;
    else if (g_strcmp0 (kind, "stream_stopped") == 0)
      reason = g_strdup (json_object_get_string_member (json_node_get_object (ev->reply->body), "reason"));
  }
  g_test_message ("stream_stopped: %s", reason);
  g_assert_cmpuint (results, ==, 0);
  g_assert_cmpuint (failed_events, ==, MAX_FAILED);
  g_autofree char *count = g_strdup_printf ("%d sets in a row failed", MAX_FAILED);
  g_assert_nonnull (strstr (reason, count));
  g_assert_nonnull (strstr (reason, "continuous acquisition stopped at "));
  g_assert_nonnull (strstr (reason, "max-failed-sets"));

  g_autoptr (DsMessage) st = test_daemon_call_ok (c, "status", NULL);
  JsonObject *o = json_node_get_object (st->reply->body);
  g_assert_false (json_object_get_boolean_member (o, "continuous"));
  g_assert_cmpstr (json_object_get_string_member (o, "state"), ==, "idle");
  g_assert_cmpint (json_object_get_int_member (o, "sets_failed"), ==, MAX_FAILED);
  g_assert_cmpint (json_object_get_int_member (o, "sets_done"), ==, 0);
  g_assert_cmpstr (json_object_get_string_member (o, "last_error"), ==, reason);
  /* The timestamp: an ISO 8601 UTC time right after "at ". */
  const char *at = strstr (reason, "stopped at ") + strlen ("stopped at ");
  g_autofree char *stamp = g_strndup (at, 20);
  g_autoptr (GDateTime) when = g_date_time_new_from_iso8601 (stamp, NULL);
  g_assert_nonnull (when);
  /* Nothing runs after it: the counters stay. */
  g_usleep (300 * 1000);
  g_autoptr (DsMessage) st2 = test_daemon_call_ok (c, "status", NULL);
  g_assert_cmpint (json_object_get_int_member (json_node_get_object (st2->reply->body), "sets_failed"), ==,
                   MAX_FAILED);
  test_daemon_stop_clean (d);
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  g_test_add_func ("/stream-failures/failing-stream-stops", test_failing_stream_stops);
  return g_test_run ();
}
