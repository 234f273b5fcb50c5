/* Frame accounting around lost frames (docs/protocol.md, "Frame accounting"): a real daemon on
 * the simulated lab with scripted faults on the triggers after the first two ([sim]
 * faults=faults-after=2,<fault>-next=N: the frame-id tracker has seen ids before the loss).
 * Expected counters are derived by hand from the fault-free run of the same capture: a frame
 * lost in transit ("drop": its id never seen) or a lost trigger ("timeout": no id) adds one
 * timeout and one retry and nothing else; an incomplete frame adds one acquired frame dropped as
 * `incomplete` and one retry. A counted loss is never dropped a second time as `frame_gap` for
 * the next frame (before: one loss cost two retries, and the next good frame was dropped as
 * frame_gap). The simulated frames are rendered in the same order either way (a lost frame
 * renders nothing), so the results equal the fault-free run's payload for payload: nothing
 * folded into a wrong phase. */
#include <string.h>

#include "tests/common/daemon_harness.h"

typedef struct {
  gint64 acquired, folded, dropped, retries, timeouts, frame_gap, incomplete;
} Counts;

static Counts
counts_of (const DsMessage *m)
{
  Counts c = { test_json_int (m->reply->body, "frames.acquired"), test_json_int (m->reply->body, "frames.folded"),
               test_json_int (m->reply->body, "frames.dropped"), test_json_int (m->reply->body, "frames.retries"),
               test_json_int (m->reply->body, "frames.timeouts"),
               test_json_int (m->reply->body, "frames.dropped_by_reason.frame_gap"),
               test_json_int (m->reply->body, "frames.dropped_by_reason.incomplete") };
  return c;
}

/* `before` captures, then one more (automatic when target_error > 0) on a fresh daemon; returns
 * the last one's reply (its counters are its set's). */
static DsMessage *
capture_with (const char *faults, gboolean dark, double target_error, guint before)
{
  g_autofree char *conf = g_strdup_printf (
      "[camera]\nbackend=sim\ngrab-timeout-ms=20\n[illuminator]\nbackend=sim\nsettle-timeout-ms=20\n"
      "[acquisition]\nphases=4\ndark-frame=%s\nphase-retries=3\n[sim]\nscene=%s\nseed=7\n%s%s\n",
      dark ? "true" : "false", SCENE_FILE, faults ? "faults=" : "", faults ? faults : "");
  TestDaemon *d = test_daemon_start (conf, NULL);
  g_autoptr (DsClient) c = test_daemon_connect (d);
  g_autoptr (JsonObject) args = json_object_new ();
  if (target_error > 0)
    json_object_set_double_member (args, "target_error", target_error);
  g_autoptr (GError) error = NULL;
  for (guint i = 0; i < before; i++) {
    g_autoptr (DsMessage) first = ds_client_call (c, "capture", NULL, NULL, NULL, &error);
    g_assert_no_error (error);
    g_assert_true (first->reply->ok);
  }
  DsMessage *m = ds_client_call (c, "capture", args, NULL, NULL, &error);
  g_assert_no_error (error);
  g_assert_cmpint (test_daemon_stop (d), ==, 0);
  test_daemon_free (d);
  return m;
}

typedef struct {
  const char *faults;
  gboolean dark;
  double target_error;
  guint before;            /* captures before the one counted */
  gint64 d_acquired, d_retries, d_timeouts, d_incomplete; /* added to the fault-free run's */
} Case;

static void
test_counters (gconstpointer data)
{
  const Case *k = data;
  g_autoptr (DsMessage) clean = capture_with (NULL, k->dark, k->target_error, k->before);
  if (!clean->reply->ok)
    g_error ("fault-free: the capture failed: %s", clean->reply->error_message);
  Counts c0 = counts_of (clean);
  g_assert_cmpint (c0.retries, ==, 0);
  g_autoptr (DsMessage) m = capture_with (k->faults, k->dark, k->target_error, k->before);
  if (!m->reply->ok)
    g_error ("%s: the capture failed: %s", k->faults, m->reply->error_message);
  Counts c = counts_of (m);
  g_test_message ("%s: acquired %" G_GINT64_FORMAT " folded %" G_GINT64_FORMAT " dropped %" G_GINT64_FORMAT
                  " (frame_gap %" G_GINT64_FORMAT ", incomplete %" G_GINT64_FORMAT ") retries %" G_GINT64_FORMAT
                  " timeouts %" G_GINT64_FORMAT "; fault-free: acquired %" G_GINT64_FORMAT " folded %" G_GINT64_FORMAT,
                  k->faults, c.acquired, c.folded, c.dropped, c.frame_gap, c.incomplete, c.retries, c.timeouts,
                  c0.acquired, c0.folded);
  g_assert_cmpint (c.frame_gap, ==, 0);
  g_assert_cmpint (c.acquired, ==, c0.acquired + k->d_acquired);
  g_assert_cmpint (c.folded, ==, c0.folded);
  g_assert_cmpint (c.dropped, ==, c0.dropped + k->d_incomplete);
  g_assert_cmpint (c.incomplete, ==, c0.incomplete + k->d_incomplete);
  g_assert_cmpint (c.retries, ==, k->d_retries);
  g_assert_cmpint (c.timeouts, ==, k->d_timeouts);
  /* The same frames folded into the same phases: the same result, payload for payload. */
  g_assert_cmpuint (m->reply->n_payloads, ==, clean->reply->n_payloads);
  g_assert_cmpuint (m->reply->n_payloads, >, 0);
  for (guint i = 0; i < m->reply->n_payloads; i++)
    g_assert_true (g_bytes_equal (m->payloads[i], clean->payloads[i]));
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  /* Phase 2's frame (the third trigger) lost in transit, retried once; before: its retry's frame was dropped as
   * frame_gap and retried again (acquired +1, retries 2). */
  static const Case drop1 = { "faults-after=2,drop-next=1", FALSE, 0, 0, 0, 1, 1, 0 };
  /* Two in a row: two timeouts, then a frame with two ids missing, both counted; before: a
   * third retry for the frame gap. */
  static const Case drop2 = { "faults-after=2,drop-next=2", FALSE, 0, 0, 0, 2, 2, 0 };
  /* A lost trigger and then a frame lost in transit: two counted losses, one id missing. */
  static const Case mixed = { "faults-after=2,timeout-next=1,drop-next=2", FALSE, 0, 0, 0, 2, 2, 0 };
  /* A pilot frame of the automatic operating point lost (the pilot's own retry path): its third
   * trigger, phase 1/2 at P. */
  static const Case pilot = { "faults-after=2,drop-next=1", TRUE, 0.1, 0, 0, 1, 1, 0 };
  g_test_add_data_func ("/lost-frames/drop", &drop1, test_counters);
  g_test_add_data_func ("/lost-frames/drop-two", &drop2, test_counters);
  g_test_add_data_func ("/lost-frames/lost-trigger-then-drop", &mixed, test_counters);
  g_test_add_data_func ("/lost-frames/pilot-drop", &pilot, test_counters);
  return g_test_run ();
}
