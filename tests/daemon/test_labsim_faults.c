/* What a lab hits in its first hour with a real camera (issue 10), over real GigE Vision and
 * Modbus TCP: descatter-labsim (a GigE Vision camera on Aravis's fake camera, a Modbus
 * illuminator) with its fault knobs. None of it may crash the daemon,
 * leave it unanswering, or answer with a code that misleads: each set is correct (against the
 * simulator's truth) or fails with device_error/failed naming the device and the setting.
 *   test_labsim_faults LABSIM SCENE      (ctest: in a private network namespace, UDP 3956) */
#include <glib/gstdio.h>
#include <signal.h>
#include <stdio.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include "tests/common/daemon_harness.h"
#include "tests/common/truth_check.h"

static const char *labsim_path, *scene_path;
static DsScene *the_scene;
static DsImage *truth_t, *truth_g;

/* Timeouts no device of a loaded machine misses (labsim renders its frames, and answers Modbus,
 * in a process that waits for a core like every other): a frame within GRAB_MS, an answer
 * within 1 s. Only the lost camera's test sets a short grab timeout: how soon a loss is seen is
 * what it asserts. Connections never idle out: a client waits through labsim's restart or a
 * whole continuous run, which a loaded machine stretched past the default 60 s. */
#define GRAB_MS 10000

static char *
config_for (const TestLabsim *l, guint grab_timeout_ms, const char *camera_extra, const char *extra)
{
  return g_strdup_printf ("[daemon]\nidle-timeout-ms=0\n"
                          "[camera]\nbackend=aravis\naddress=127.0.0.1\nexposure-us=%g\ngrab-timeout-ms=%u\n%s\n"
                          "[illuminator]\nbackend=modbus\nmodbus-uri=tcp://127.0.0.1:%u\nmodbus-timeout-ms=1000\n"
                          "period-px=%g\nduty=%g\n"
                          "[acquisition]\nphases=4\ndark-frame=true\nphase-retries=3\n%s",
                          ds_scene_default_exposure_us (the_scene), grab_timeout_ms,
                          camera_extra ? camera_extra : "", l->modbus_port, ds_scene_period_px (the_scene),
                          ds_scene_duty (the_scene), extra ? extra : "");
}

static JsonObject *
status_of (DsClient *c, DsMessage **keep)
{
  *keep = test_daemon_call_ok (c, "status", NULL);
  return json_node_get_object ((*keep)->reply->body);
}

/* A capture: correct against the truth, or a failure with a code and a message. Returns the
 * wire code name ("ok" for a correct set). */
static const char *
capture (DsClient *c, JsonObject *args, char **message)
{
  const char *code = NULL;
  return truth_capture (c, args, the_scene, truth_t, truth_g, message, &code) ? "ok" : code;
}

static void
assert_mentions (const char *text, const char *const *words)
{
  for (guint i = 0; words[i]; i++)
    if (!text || !strstr (text, words[i]))
      g_error ("\"%s\" does not mention \"%s\"", text, words[i]);
}

/* The camera refuses a configured setting: the daemon runs, status says not ready and why
 * (the setting and what the camera allows), captures fail with device_error saying the same.
 * A capture asking for a gain beyond the camera's range fails the same way, and the next one
 * with valid settings is correct. (Before: a crash in run_set, at the first capture.) */
static void
test_camera_rejects_setting (void)
{
  /* A camera offering Mono8 and Mono16 only, with 0..10 dB of gain. */
  const char *camera[] = { "--pixel-formats", "Mono8,Mono16", "--gain-max", "10", NULL };
  TestLabsim *l = test_labsim_start (labsim_path, scene_path, camera);
  const struct { const char *camera; const char *must[4]; } refused[] = {
    { "pixel-format=Mono12p", { "PixelFormat Mono12p", "Mono16", "Mono8" } },
    { "pixel-format=Mono12", { "PixelFormat Mono12", "Mono16", NULL } },
    { "gain-db=12", { "gain 12 dB", "[0, 10]", NULL } },
  };
  for (guint i = 0; i < G_N_ELEMENTS (refused); i++) {
    g_autofree char *conf = config_for (l, GRAB_MS, refused[i].camera, NULL);
    TestDaemon *d = test_daemon_start_full (conf, NULL, NULL, FALSE);
    g_autoptr (DsClient) c = test_daemon_connect (d);
    g_autoptr (DsMessage) keep = NULL;
    JsonObject *st = status_of (c, &keep);
    const char *why = json_object_get_string_member_with_default (st, "not_ready_reason", NULL);
    g_test_message ("%s: ready %d: %s", refused[i].camera, json_object_get_boolean_member (st, "ready"), why);
    g_assert_false (json_object_get_boolean_member (st, "ready"));
    assert_mentions (why, refused[i].must);
    for (guint k = 0; k < 2; k++) {
      g_autofree char *msg = NULL;
      g_assert_cmpstr (capture (c, NULL, &msg), ==, "device_error");
      assert_mentions (msg, refused[i].must);
    }
    test_daemon_stop_clean (d);
  }
  /* Valid configuration, a capture asking for too much gain, then a normal one. */
  g_autofree char *conf = config_for (l, GRAB_MS, "pixel-format=Mono16", NULL);
  TestDaemon *d = test_daemon_start (conf, NULL);
  g_autoptr (DsClient) c = test_daemon_connect (d);
  g_autoptr (JsonObject) args = json_object_new ();
  json_object_set_double_member (args, "gain_db", 12);
  g_autofree char *msg = NULL;
  g_assert_cmpstr (capture (c, args, &msg), ==, "device_error");
  assert_mentions (msg, (const char *const[]) { "gain 12 dB", "[0, 10]", NULL });
  g_assert_cmpstr (capture (c, NULL, NULL), ==, "ok");
  test_daemon_stop_clean (d);
  test_labsim_stop (l);
}

/* The lab's devices stopped between two captures (labsim killed), then back: the capture in
 * between fails with device_error, the daemon answers throughout, and once the devices are
 * back a capture is correct again. (Before: a crash, 5 of 5 runs.) */
static void
test_devices_stopped_between_captures (void)
{
  TestLabsim *l = test_labsim_start (labsim_path, scene_path, NULL);
  g_autofree char *conf = config_for (l, GRAB_MS, NULL, NULL);
  TestDaemon *d = test_daemon_start (conf, NULL);
  g_autoptr (DsClient) c = test_daemon_connect (d);
  g_assert_cmpstr (capture (c, NULL, NULL), ==, "ok");
  guint port = l->modbus_port; /* where the daemon's configuration points */
  for (guint round = 0; round < 2; round++) {
    test_labsim_stop (l);
    g_autofree char *msg = NULL;
    const char *code = capture (c, NULL, &msg);
    g_test_message ("devices gone: %s: %s", code, msg);
    g_assert_cmpstr (code, ==, "device_error");
    g_autoptr (DsMessage) keep = NULL;
    JsonObject *st = status_of (c, &keep);
    g_assert_false (json_object_get_boolean_member (st, "ready"));
    l = test_labsim_start_on_port (labsim_path, scene_path, NULL, port);
    /* Reconnection takes its backoff (at most 2 s a try): captures fail with device_error until
     * the daemon has the devices back, however long a loaded machine takes (bounded for a hang). */
    const char *after = NULL;
    gint64 give_up = g_get_monotonic_time () + 120 * G_USEC_PER_SEC;
    while (g_strcmp0 (after, "ok") != 0 && g_get_monotonic_time () < give_up) {
      g_autofree char *m2 = NULL;
      after = capture (c, NULL, &m2);
      if (g_strcmp0 (after, "ok") != 0) {
        g_assert_cmpstr (after, ==, "device_error");
        g_usleep (500 * 1000);
      }
    }
    g_assert_cmpstr (after, ==, "ok");
  }
  g_autoptr (DsMessage) keep = NULL;
  JsonObject *st = status_of (c, &keep);
  g_assert_true (json_object_get_boolean_member (st, "ready"));
  test_daemon_stop_clean (d);
  test_labsim_stop (l);
}

/* Runs continuous acquisition until `sets` results or failures arrived; every result correct,
 * every failure with a reason and a code; returns the failures. */
static char *first_failure;

typedef struct {
  int fd;
  GThread *thread;
  gint stop;
  guint pings;
} NotifyListener;

/* A stand-in for systemd's notify socket: counts WATCHDOG=1 pings. */
static gpointer
notify_listen (gpointer data)
{
  NotifyListener *n = data;
  char buf[4096];
  while (!g_atomic_int_get (&n->stop)) {
    struct timeval tv = { 0, 100000 };
    setsockopt (n->fd, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
    gssize r = recv (n->fd, buf, sizeof buf - 1, 0);
    if (r <= 0)
      continue;
    buf[r] = 0;
    if (!strstr (buf, "WATCHDOG=1"))
      continue;
    g_atomic_int_inc ((gint *) &n->pings);
  }
  return NULL;
}

/* Continuous acquisition until `sets` sets came, each correct or failed with a reason. With a
 * watchdog listener, *pings_while_failing: the pings between the first failed set and the first
 * correct one after it (the daemon fed the watchdog while its camera was away). */
static guint
continuous_watched (TestDaemon *d, guint sets, guint *device_events, NotifyListener *watchdog,
                    guint *pings_while_failing)
{
  guint pings_at_failure = 0;
  gboolean recovered = FALSE;
  g_autoptr (DsClient) sub = test_daemon_connect (d);
  g_autoptr (DsClient) ctl = test_daemon_connect (d);
  g_autoptr (DsMessage) s = test_daemon_call_ok (sub, "subscribe", NULL);
  g_autoptr (DsMessage) st = test_daemon_call_ok (ctl, "start", NULL);
  guint ok = 0, failed = 0;
  while (ok + failed < sets) {
    g_autoptr (GError) error = NULL;
    g_autoptr (DsMessage) ev = ds_client_read (sub, 60000, &error);
    g_assert_no_error (error);
    if (g_strcmp0 (ev->reply->event, "result") == 0) {
      TruthCheck tc;
      truth_check (ev, the_scene, truth_t, truth_g, &tc);
      g_assert_true (truth_check_passed (&tc));
      ok++;
      if (watchdog && failed > 0 && !recovered) {
        *pings_while_failing = (guint) g_atomic_int_get ((gint *) &watchdog->pings) - pings_at_failure;
        recovered = TRUE;
      }
    } else if (g_strcmp0 (ev->reply->event, "failed") == 0) {
      JsonObject *b = json_node_get_object (ev->reply->body);
      const char *code = json_object_get_string_member (b, "code");
      g_assert_true (g_strcmp0 (code, "device_error") == 0 || g_strcmp0 (code, "failed") == 0);
      g_assert_cmpuint (strlen (json_object_get_string_member (b, "reason")), >, 0);
      if (!first_failure)
        first_failure = g_strdup (json_object_get_string_member (b, "reason"));
      if (watchdog && failed == 0)
        pings_at_failure = (guint) g_atomic_int_get ((gint *) &watchdog->pings);
      failed++;
    } else if (g_strcmp0 (ev->reply->event, "device") == 0)
      (*device_events)++;
  }
  g_autoptr (DsMessage) stop = test_daemon_call_ok (ctl, "stop", NULL);
  test_daemon_frames (ctl);
  g_test_message ("continuous: %u correct, %u failed with a reason, %u device events", ok, failed, *device_events);
  g_assert_cmpuint (ok, >, 0);
  return failed;
}

static guint
continuous (TestDaemon *d, guint sets, guint *device_events)
{
  return continuous_watched (d, sets, device_events, NULL, NULL);
}

/* Modbus exception responses for 30 % of the requests during continuous acquisition. (Before:
 * the daemon died within 1-7 s.) */
static void
test_modbus_exceptions_continuous (void)
{
  const char *faults[] = { "--modbus-exception-rate", "0.3", NULL };
  TestLabsim *l = test_labsim_start (labsim_path, scene_path, faults);
  g_autofree char *conf = config_for (l, GRAB_MS, NULL, NULL);
  TestDaemon *d = test_daemon_start (conf, NULL);
  guint events = 0;
  continuous (d, 10, &events);
  test_daemon_stop_clean (d);
  test_labsim_stop (l);
}

/* A wrong [illuminator] period-px: the set fails (nothing verifiable), and the reason says
 * what to check: the configured period and the one the frames show, each prefix once. (Before:
 * "phase 0: phase 0: retries exhausted ... snr 0.1 < 5.0".) */
static void
test_wrong_period (void)
{
  /* A controller of the first register map stores PERIOD_CENTIPX but draws its optics' period:
   * a wrong period-px reaches the frames unrefused (labsim's default projector would draw it, one
   * of a fixed period would refuse it before writing). */
  const char *rev1[] = { "--map-revision", "1", NULL };
  TestLabsim *l = test_labsim_start (labsim_path, scene_path, rev1);
  double wrong = ds_scene_period_px (the_scene) * 2.7;
  g_autofree char *conf = config_for (l, GRAB_MS, NULL, NULL);
  g_autofree char *period = g_strdup_printf ("period-px=%g", ds_scene_period_px (the_scene));
  g_autofree char *bad_period = g_strdup_printf ("period-px=%g", wrong);
  g_autoptr (GString) c = g_string_new (conf);
  g_string_replace (c, period, bad_period, 1);
  TestDaemon *d = test_daemon_start (c->str, NULL);
  g_autoptr (DsClient) cl = test_daemon_connect (d);
  g_autofree char *msg = NULL;
  g_assert_cmpstr (capture (cl, NULL, &msg), ==, "failed");
  g_test_message ("period-px %g on a %g px scene: %s", wrong, ds_scene_period_px (the_scene), msg);
  g_autofree char *configured = g_strdup_printf ("configured period of %.1f px", wrong);
  g_autofree char *shows = g_strdup_printf ("period of about %.1f px", ds_scene_period_px (the_scene));
  assert_mentions (msg, (const char *const[]) { configured, shows, "period-px", NULL });
  g_assert_false (g_regex_match_simple ("phase \\d+: phase \\d+:", msg, 0, 0));
  test_daemon_stop_clean (d);
  test_labsim_stop (l);
}

/* The camera vanishes for 8 s during continuous acquisition, under a watchdog of 4 s (systemd's
 * protocol: WATCHDOG_USEC, a notify socket). The loss is detected as a loss ("lost", not retries
 * running out) while the camera is still away, and reported; the watchdog keeps being fed while
 * the camera is away: pings arrive between the first failed set and the first correct one after
 * it (before: detection took 10-13 s and the watchdog starved, so systemd would have restarted
 * the service); acquisition resumes correct once it is back. Asserted by the order of events,
 * not by the gaps between pings, which a loaded machine stretches. */
static void
test_camera_lost_continuous (void)
{
  const char *faults[] = { "--camera-vanish-after", "30", "--camera-vanish-for", "8", NULL };
  TestLabsim *l = test_labsim_start (labsim_path, scene_path, faults);
  g_autoptr (GError) error = NULL;
  g_autofree char *dir = g_dir_make_tmp ("ds-notify-XXXXXX", &error);
  g_assert_no_error (error);
  g_autofree char *sock_path = g_build_filename (dir, "notify", NULL);
  NotifyListener n = { 0 };
  n.fd = socket (AF_UNIX, SOCK_DGRAM | SOCK_CLOEXEC, 0);
  struct sockaddr_un sa = { .sun_family = AF_UNIX };
  g_strlcpy (sa.sun_path, sock_path, sizeof sa.sun_path);
  g_assert_cmpint (bind (n.fd, (struct sockaddr *) &sa, sizeof sa), ==, 0);
  n.thread = g_thread_new ("notify", notify_listen, &n);
  const char *env[] = { "NOTIFY_SOCKET", sock_path, "WATCHDOG_USEC", "4000000", NULL };
  g_autofree char *conf = config_for (l, 1000, NULL, NULL);
  TestDaemon *d = test_daemon_start_full (conf, NULL, env, TRUE);
  g_clear_pointer (&first_failure, g_free);
  guint events = 0;
  guint pings_while_failing = 0;
  guint failed = continuous_watched (d, 12, &events, &n, &pings_while_failing);
  g_atomic_int_set (&n.stop, 1);
  g_thread_join (n.thread);
  close (n.fd);
  g_test_message ("camera lost for 8 s: first failure \"%s\"; %u sets failed, %u device events; %u watchdog pings, "
                  "%u of them between the first failed set and the first correct one after it",
                  first_failure, failed, events, n.pings, pings_while_failing);
  g_assert_cmpuint (failed, >, 0);     /* the loss was noticed ... */
  g_assert_nonnull (strstr (first_failure, "lost"));
  g_assert_cmpuint (events, >, 0);     /* ... and reported */
  g_assert_cmpuint (pings_while_failing, >, 0); /* the watchdog was fed while the camera was away */
  test_daemon_stop_clean (d);
  test_labsim_stop (l);
  g_unlink (sock_path);
  g_rmdir (dir);
  g_clear_pointer (&first_failure, g_free);
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  if (argc < 3) {
    fprintf (stderr, "usage: test_labsim_faults LABSIM SCENE\n");
    return 2;
  }
  labsim_path = argv[1];
  scene_path = argv[2];
  truth_scene_load (scene_path, &the_scene, &truth_t, &truth_g);
  g_test_add_func ("/labsim-faults/camera-rejects-setting", test_camera_rejects_setting);
  g_test_add_func ("/labsim-faults/devices-stopped-between-captures", test_devices_stopped_between_captures);
  g_test_add_func ("/labsim-faults/modbus-exceptions-continuous", test_modbus_exceptions_continuous);
  g_test_add_func ("/labsim-faults/camera-lost-continuous", test_camera_lost_continuous);
  g_test_add_func ("/labsim-faults/wrong-period", test_wrong_period);
  int status = g_test_run ();
  truth_scene_free (the_scene, truth_t, truth_g);
  return status;
}
