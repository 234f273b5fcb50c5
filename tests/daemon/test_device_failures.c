/* Every kind of device failure reaches the client with the wire code docs/protocol.md gives
 * (issue 10: device failures came as `failed`, rejected frames as `device_error`). A real
 * daemon on the simulated lab with one fault injected for every frame; the capture's reply and
 * the subscribers' `failed` event both carry the code, and the message says what failed. */
#include <string.h>

#include "tests/common/daemon_harness.h"

typedef struct {
  const char *faults;     /* [sim] faults */
  const char *wire;       /* expected code */
  const char *mentions;   /* the message names the failure */
} Case;

static void
test_wire_code_of_each_failure (void)
{
  const Case cases[] = {
    /* device failures: the camera or the illuminator said no */
    { "timeout=1", "device_error", "no frame" },
    { "incomplete=1", "device_error", "camera" },
    { "not-ready=1", "device_error", "illuminator" },
    { "disconnect-after=3", "device_error", "camera" },
    /* the devices answered, but the frames failed verification */
    /* (wrong-phase=1 shifts every frame alike: the offset learned from the first frame absorbs
     * it and the set is right; tests/daemon/test_sequencer.c covers a wrong phase.) */
    /* (stale=1: every frame shows the phase lit before the last move. With the next phase
     * applied during each frame's transfer (docs/design.md, "The pipeline"), the retried
     * frames repeat phases the set already holds and the repeat check refuses them until the
     * retries run out; before that, the first set failed as a whole.) */
    { "stale=1", "failed", "frame dropped (wrong_phase)" },
    /* (drop=1 loses every frame: that is a camera timeout, a device failure.) */
    { "drop=1", "device_error", "no frame" },
  };
  for (guint i = 0; i < G_N_ELEMENTS (cases); i++) {
    g_autofree char *conf = g_strdup_printf (
        "[camera]\nbackend=sim\ngrab-timeout-ms=20\n[illuminator]\nbackend=sim\nsettle-timeout-ms=20\n"
        "[acquisition]\nphases=4\ndark-frame=false\nphase-retries=1\n[sim]\nscene=%s\nfaults=%s\n",
        SCENE_FILE, cases[i].faults);
    TestDaemon *d = test_daemon_start (conf, NULL);
    g_autoptr (DsClient) sub = test_daemon_connect (d);
    g_autoptr (DsMessage) s = test_daemon_call_ok (sub, "subscribe", NULL);
    g_autoptr (DsClient) c = test_daemon_connect (d);
    g_autoptr (GError) error = NULL;
    g_autoptr (DsMessage) m = ds_client_call (c, "capture", NULL, NULL, NULL, &error);
    g_assert_no_error (error);
    g_test_message ("%s: %s: %s", cases[i].faults, m->reply->ok ? "ok" : ds_protocol_error_name (m->reply->error_code),
                    m->reply->ok ? "" : m->reply->error_message);
    g_assert_false (m->reply->ok);
    g_assert_cmpstr (ds_protocol_error_name (m->reply->error_code), ==, cases[i].wire);
    /* Each prefix once ("phase 0: phase 0: retries exhausted" was the old text). */
    g_assert_false (g_regex_match_simple ("phase \\d+: phase \\d+:", m->reply->error_message, 0, 0));
    if (!strstr (m->reply->error_message, cases[i].mentions))
      g_error ("%s: \"%s\" does not mention \"%s\"", cases[i].faults, m->reply->error_message, cases[i].mentions);
    /* The subscriber's event says the same. */
    for (;;) {
      g_autoptr (DsMessage) ev = ds_client_read (sub, 20000, &error);
      g_assert_no_error (error);
      if (g_strcmp0 (ev->reply->event, "failed") != 0)
        continue;
      JsonObject *body = json_node_get_object (ev->reply->body);
      g_assert_cmpstr (json_object_get_string_member (body, "code"), ==, cases[i].wire);
      g_assert_cmpstr (json_object_get_string_member (body, "reason"), ==, m->reply->error_message);
      break;
    }
    g_assert_cmpint (test_daemon_stop (d), ==, 0);
    test_daemon_free (d);
  }
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  g_test_add_func ("/device-failures/wire-code", test_wire_code_of_each_failure);
  return g_test_run ();
}
