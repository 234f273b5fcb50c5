/* Requests sent while the devices open (docs/protocol.md, "Commands"): they wait in the
 * acquisition queue and run once the devices are open, or are answered `device_error` with the
 * reason when the devices fail to open. A real daemon process on the in-process simulated lab,
 * whose opening is stretched by the `open-delay-ms` fault so that the requests surely arrive
 * while it opens; the expectations are the protocol's, not times. */
#include <glib/gstdio.h>
#include <string.h>

#include "tests/common/daemon_harness.h"

/* Long enough that the first requests surely arrive while the devices open: the socket exists
 * well before the acquisition thread finished a delay of this size. */
#define OPEN_DELAY_MS 3000

static char *
config_text (void)
{
  return g_strdup_printf ("[camera]\nbackend=sim\n[illuminator]\nbackend=sim\n"
                          "[sim]\nscene=%s\nseed=7\nfaults=open-delay-ms=%d\n",
                          SCENE_FILE, OPEN_DELAY_MS);
}

static const char *
status_state (DsClient *c)
{
  static char state[32];
  g_autoptr (DsMessage) st = test_daemon_call_ok (c, "status", NULL);
  g_strlcpy (state, json_object_get_string_member (json_node_get_object (st->reply->body), "state"),
             sizeof state);
  return state;
}

/* A capture sent as soon as the socket exists, while status says `opening`: it waits and
 * succeeds with the phases it asked for; a dark frame queued behind it too. */
static void
test_capture_waits_for_devices (void)
{
  g_autofree char *conf = config_text ();
  TestDaemon *d = test_daemon_start_unready (conf);
  g_autoptr (DsClient) a = test_daemon_connect (d);
  g_assert_cmpstr (status_state (a), ==, "opening");

  g_autoptr (JsonObject) args = json_object_new ();
  json_object_set_int_member (args, "phases", 4);
  g_autoptr (GError) error = NULL;
  g_autoptr (DsMessage) m = ds_client_call (a, "capture", args, NULL, NULL, &error);
  g_assert_no_error (error);
  if (!m->reply->ok)
    g_error ("capture while opening: %s: %s", ds_protocol_error_name (m->reply->error_code),
             m->reply->error_message);
  g_assert_cmpint (test_json_int (m->reply->body, "settings.phases"), ==, 4);
  g_assert_cmpuint (m->reply->n_payloads, >, 0);
  TestFrames f = test_daemon_frames (a);
  g_assert_cmpint (f.folded, >=, 4);
  test_daemon_stop_clean (d);
}

/* Preview asked for while the devices open waits like a capture: answered `preview` once they
 * are open, and status then says so. */
static void
test_preview_waits_for_devices (void)
{
  g_autofree char *conf = config_text ();
  TestDaemon *d = test_daemon_start_unready (conf);
  g_autoptr (DsClient) a = test_daemon_connect (d);
  g_assert_cmpstr (status_state (a), ==, "opening");

  g_autoptr (JsonObject) on = json_object_new ();
  json_object_set_string_member (on, "state", "on");
  json_object_set_string_member (on, "light", "all");
  g_autoptr (GError) error = NULL;
  g_autoptr (DsMessage) m = ds_client_call (a, "preview", on, NULL, NULL, &error);
  g_assert_no_error (error);
  if (!m->reply->ok)
    g_error ("preview while opening: %s: %s", ds_protocol_error_name (m->reply->error_code),
             m->reply->error_message);
  g_assert_cmpstr (json_object_get_string_member (json_node_get_object (m->reply->body), "state"), ==, "preview");
  g_assert_cmpstr (status_state (a), ==, "preview");
  g_autoptr (JsonObject) off = json_object_new ();
  json_object_set_string_member (off, "state", "off");
  g_autoptr (DsMessage) o = ds_client_call (a, "preview", off, NULL, NULL, &error);
  g_assert_no_error (error);
  g_assert_true (o->reply->ok);
  test_daemon_stop_clean (d);
}

/* Devices that cannot open: the simulated lab's scene file, there when the daemon checked its
 * configuration, is gone by the time the devices open. A capture sent while they open is
 * answered `device_error` naming the lab and why, and the daemon exits failed; a start sent
 * meanwhile says it waits for the devices. */
static void
test_capture_answered_when_devices_fail (void)
{
  g_autofree char *tmp = g_dir_make_tmp ("descatter-opening-XXXXXX", NULL);
  g_autofree char *scene = g_build_filename (tmp, "vanishing.scene", NULL);
  g_autofree char *text = NULL;
  g_assert_true (g_file_get_contents (SCENE_FILE, &text, NULL, NULL));
  g_assert_true (g_file_set_contents (scene, text, -1, NULL));
  g_autofree char *conf = g_strdup_printf ("[camera]\nbackend=sim\n[illuminator]\nbackend=sim\n"
                                           "[sim]\nscene=%s\nfaults=open-delay-ms=%d\n",
                                           scene, OPEN_DELAY_MS);
  TestDaemon *d = test_daemon_start_unready (conf);
  g_autoptr (DsClient) a = test_daemon_connect (d);
  g_assert_cmpstr (status_state (a), ==, "opening");
  g_assert_cmpint (g_remove (scene), ==, 0);
  /* A start while they open is taken, and its reply says it waits for them. */
  g_autoptr (DsMessage) st = test_daemon_call_ok (a, "start", NULL);
  JsonObject *sto = json_node_get_object (st->reply->body);
  g_assert_cmpstr (json_object_get_string_member (sto, "message"), ==,
                   "continuous acquisition starts once the devices are open");
  g_assert_cmpstr (json_object_get_string_member (sto, "not_ready_reason"), ==, "devices are opening");
  g_autoptr (GError) error = NULL;
  g_autoptr (DsMessage) m = ds_client_call (a, "capture", NULL, NULL, NULL, &error);
  g_assert_no_error (error);
  g_assert_false (m->reply->ok);
  g_test_message ("capture: %s: %s", ds_protocol_error_name (m->reply->error_code), m->reply->error_message);
  g_assert_cmpint (m->reply->error_code, ==, DS_PROTOCOL_ERROR_DEVICE);
  g_assert_nonnull (strstr (m->reply->error_message, "the devices failed to open"));
  g_assert_nonnull (strstr (m->reply->error_message, "simulated lab"));
  g_assert_nonnull (strstr (m->reply->error_message, "vanishing.scene"));
  g_subprocess_wait (d->proc, NULL, &error);
  g_assert_no_error (error);
  g_assert_true (g_subprocess_get_if_exited (d->proc));
  g_assert_cmpint (g_subprocess_get_exit_status (d->proc), !=, 0);
  g_clear_object (&d->proc);
  test_daemon_free (d);
  g_rmdir (tmp);
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  g_test_add_func ("/devices-opening/capture-waits", test_capture_waits_for_devices);
  g_test_add_func ("/devices-opening/devices-fail", test_capture_answered_when_devices_fail);
  g_test_add_func ("/devices-opening/preview-waits", test_preview_waits_for_devices);
  return g_test_run ();
}
