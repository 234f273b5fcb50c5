/* descatterd over Modbus RTU, end to end, against two controllers on a serial line:
 *  - descatter-labsim's own RTU side (on a pty it creates), with its serial fault knobs;
 *  - tests/drivers/pymodbus_controller.py, docs/registers.md implemented with Debian's pymodbus
 *    serial server on one end of a socat pty pair, descatterd on the other; labsim's camera
 *    sees the phase that controller lights (--light-from).
 * Every set either equals the scene's truth within the noise model or fails with a message that
 * names what went wrong; after each fault the daemon recovers on its own.
 * Usage: test_daemon_rtu LABSIM SCENE PYMODBUS_CONTROLLER. Binds UDP 3956. */
#include <glib/gstdio.h>
#include <signal.h>
#include <stdio.h>
#include <string.h>

#include "tests/common/daemon_harness.h"
#include "tests/common/truth_check.h"
#include "drivers/aravis/aravis_camera.h"
#include "drivers/modbus/modbus_illuminator.h"
#include "period_check.h"

static const char *labsim_path, *scene_path, *controller_path;
static DsScene *the_scene;
static DsImage *truth_t, *truth_g;

/* A helper process that dies with the test; waits for a line containing `ready` (NULL: do not
 * wait) and returns it. keep_out (may be NULL): the helper's stdout, for lines it prints later. */
static GSubprocess *
spawn (const char *const *argv, const char *ready, char **ready_line, GDataInputStream **keep_out)
{
  GSubprocess *p = test_spawn (argv, ready ? G_SUBPROCESS_FLAGS_STDOUT_PIPE : G_SUBPROCESS_FLAGS_STDOUT_SILENCE);
  if (!ready)
    return p;
  g_autoptr (GDataInputStream) out = g_data_input_stream_new (g_subprocess_get_stdout_pipe (p));
  char *line = test_wait_line (out, argv[0], ready);
  if (ready_line)
    *ready_line = line;
  else
    g_free (line);
  if (keep_out)
    *keep_out = g_steal_pointer (&out);
  return p;
}

static void
stop (GSubprocess *p)
{
  g_subprocess_send_signal (p, SIGTERM);
  g_subprocess_wait (p, NULL, NULL);
  g_object_unref (p);
}

/* The response timeout is the peers' answer time on this shared 2-core machine, not a real
 * controller's: at load average 9, 400 reads took up to 40 ms from labsim's RTU side and 48 ms
 * from the pymodbus controller (p99 26 and 43 ms), and the daemon itself waits for a core too;
 * at load 20 250 ms was missed. The faults below are armed by count or by toggle, so the timeout
 * only sets how long a failing access takes: 1 s, and as long for a phase to settle; a frame
 * within 10 s (labsim renders it). The client's connection never idles out while the line is
 * taken down and up again. */
#define ANSWER_MS 1000

static char *
daemon_config (const char *uri)
{
  return g_strdup_printf ("[daemon]\nidle-timeout-ms=0\n"
                          "[camera]\nbackend=aravis\naddress=127.0.0.1\npixel-format=Mono16\n"
                          "exposure-us=%g\ngrab-timeout-ms=10000\n"
                          "[illuminator]\nbackend=modbus\nmodbus-uri=%s\nmodbus-timeout-ms=%u\n"
                          "settle-timeout-ms=5000\nperiod-px=%g\nduty=%g\n"
                          "[acquisition]\nphases=4\ndark-frame=true\nphase-retries=2\n",
                          ds_scene_default_exposure_us (the_scene), uri, ANSWER_MS, ds_scene_period_px (the_scene),
                          ds_scene_duty (the_scene));
}

typedef struct {
  guint ok, failed;
  gboolean failed_before_last_ok; /* a failure was followed by a correct set: recovery */
} Tally;

/* One capture: correct against the truth, or failed with a message naming the illuminator and
 * `must_name` (NULL: any reason). Returns the error message of a failure (owned by the caller),
 * NULL when correct. */
static char *
capture (DsClient *c, Tally *t, const char *must_name)
{
  char *message = NULL;
  if (truth_capture (c, NULL, the_scene, truth_t, truth_g, &message, NULL)) {
    if (t->failed)
      t->failed_before_last_ok = TRUE;
    t->ok++;
    return NULL;
  }
  if (must_name && !strstr (message, must_name))
    g_error ("the failure \"%s\" does not name \"%s\"", message, must_name);
  g_assert_nonnull (strstr (message, "illuminator"));
  t->failed++;
  return message;
}

/* The daemon's configuration for a serial line at `device` (this test's line settings). */
static char *
line_config (const char *device)
{
  g_autofree char *uri = g_strdup_printf ("rtu:%s?baud=115200&parity=N", device);
  return daemon_config (uri);
}

/* descatterd on the serial line at `device` and a client, after two sets that must be correct. */
static TestDaemon *
daemon_on_line (const char *device, DsClient **client, Tally *t)
{
  g_autofree char *conf = line_config (device);
  TestDaemon *d = test_daemon_start (conf, NULL);
  *client = test_daemon_connect (d);
  memset (t, 0, sizeof *t);
  g_free (capture (*client, t, NULL));
  g_free (capture (*client, t, NULL));
  g_assert_cmpuint (t->ok, ==, 2);
  return d;
}

/* labsim's controller on its own pty: a clean set, then answers with bad CRCs, silences and the
 * line going away for a second. */
static void
test_labsim_rtu (void)
{
  g_autoptr (GError) error = NULL;
  g_autofree char *dir = g_dir_make_tmp ("ds-rtu-XXXXXX", &error);
  g_assert_no_error (error);
  g_autofree char *link = g_build_filename (dir, "ttyLAB", NULL);
  const char *args[] = { "--modbus-rtu", "pty", "--modbus-rtu-link", link, NULL };
  TestLabsim *l = test_labsim_start (labsim_path, scene_path, args);
  g_autoptr (DsClient) c = NULL;
  Tally t;
  TestDaemon *d = daemon_on_line (link, &c, &t);
  test_daemon_frames (c);
  /* What the controller says of its period reaches the daemon's status (labsim's projector:
   * PERIOD_ADJUSTABLE, 2.00 .. 655.35 px). */
  g_autoptr (DsMessage) dev = test_daemon_call_ok (c, "status", NULL);
  JsonObject *ill = json_node_get_object (json_object_get_member (
      json_node_get_object (json_object_get_member (json_node_get_object (dev->reply->body), "devices")),
      "illuminator"));
  g_assert_true (json_object_get_boolean_member (ill, "period_adjustable"));
  g_assert_cmpfloat (json_object_get_double_member (ill, "period_min_px"), ==, 2.0);
  g_assert_cmpfloat (json_object_get_double_member (ill, "period_max_px"), ==, 655.35);
  test_daemon_stop_clean (d);
  test_labsim_stop (l);

  /* Faults on the line: every 13th answer has a bad CRC, every 17th never comes; after 150
   * requests the line is away for a second. */
  const char *faults[] = { "--modbus-rtu", "pty", "--modbus-rtu-link", link, "--modbus-bad-crc-every", "13",
                           "--modbus-silent-every", "17", "--modbus-rtu-vanish-after", "150",
                           "--modbus-rtu-vanish-for", "1", NULL };
  g_clear_pointer (&c, ds_client_free);
  l = test_labsim_start (labsim_path, scene_path, faults);
  g_autofree char *conf = line_config (link);
  d = test_daemon_start (conf, NULL);
  c = test_daemon_connect (d);
  memset (&t, 0, sizeof t);
  for (guint i = 0; i < 7; i++)
    g_free (capture (c, &t, "Modbus"));
  /* Where the faults fall depends on timing: after the last failure, a correct set must come. */
  for (guint i = 0; i < 4 && t.failed && !t.failed_before_last_ok; i++)
    g_free (capture (c, &t, "Modbus"));
  g_test_message ("labsim RTU with faults: %u sets correct, %u failed", t.ok, t.failed);
  /* The line goes away in the middle of a set (its 150th request): that set fails. Bad CRCs and
   * silences are retried within the access and need not fail any. */
  g_assert_cmpuint (t.failed, >=, 1);
  g_assert_cmpuint (t.ok, >=, 3);
  g_assert_true (t.failed == 0 || t.failed_before_last_ok);
  test_daemon_frames (c);
  test_daemon_stop_clean (d);
  test_labsim_stop (l);
  g_rmdir (dir);
}

typedef struct {
  char *dir, *a, *b;
  GSubprocess *socat, *controller;
  GDataInputStream *controller_out;
  guint light_port;
  const char *const *controller_args; /* more arguments for the controller, NULL-terminated; may be NULL */
} Line;

/* The serial line (socat pty pair, links a and b) and the controller on end a. */
static void
line_up (Line *ln)
{
  g_autofree char *pa = g_strdup_printf ("pty,raw,echo=0,link=%s", ln->a);
  g_autofree char *pb = g_strdup_printf ("pty,raw,echo=0,link=%s", ln->b);
  const char *socat[] = { "socat", pa, pb, NULL };
  ln->socat = spawn (socat, NULL, NULL, NULL);
  /* socat makes its links once it runs: however long a loaded machine takes to start it
   * (bounded for a socat that never does). */
  for (guint i = 0; i < 6000 && !(g_file_test (ln->a, G_FILE_TEST_EXISTS) && g_file_test (ln->b, G_FILE_TEST_EXISTS)); i++)
    g_usleep (10000);
  g_assert_true (g_file_test (ln->a, G_FILE_TEST_EXISTS));
  g_assert_true (g_file_test (ln->b, G_FILE_TEST_EXISTS));
  g_autofree char *port = g_strdup_printf ("%u", ln->light_port);
  const char *ctl[] = { "/usr/bin/python3", controller_path, ln->a, "--baud", "115200", "--parity", "N",
                        "--light-port", port, "--busy-count", "4" };
  g_autoptr (GPtrArray) argv = g_ptr_array_new ();
  for (guint i = 0; i < G_N_ELEMENTS (ctl); i++)
    g_ptr_array_add (argv, (gpointer) ctl[i]);
  for (guint i = 0; ln->controller_args && ln->controller_args[i]; i++)
    g_ptr_array_add (argv, (gpointer) ln->controller_args[i]);
  g_ptr_array_add (argv, NULL);
  g_autofree char *ready = NULL;
  ln->controller = spawn ((const char *const *) argv->pdata, "ready", &ready, &ln->controller_out);
  const char *lp = strstr (ready, "light=127.0.0.1:");
  g_assert_nonnull (lp);
  ln->light_port = (guint) g_ascii_strtoull (lp + strlen ("light=127.0.0.1:"), NULL, 10);
}

static void
line_down (Line *ln)
{
  stop (ln->controller);
  g_clear_object (&ln->controller_out);
  stop (ln->socat);
  ln->controller = ln->socat = NULL;
  for (guint i = 0; i < 6000 && g_file_test (ln->b, G_FILE_TEST_EXISTS); i++)
    g_usleep (10000);
  g_assert_false (g_file_test (ln->b, G_FILE_TEST_EXISTS));
}

/* Arms a fault knob of the controller and waits until it says it is armed: every request it
 * reads from then on gets the fault (a signal alone is handled some requests later). */
static void
controller_signal (Line *ln, int sig, const char *armed)
{
  g_subprocess_send_signal (ln->controller, sig);
  g_free (test_wait_line (ln->controller_out, "pymodbus_controller.py", armed));
}

static void
line_new (Line *ln, const char *const *controller_args)
{
  g_autoptr (GError) error = NULL;
  memset (ln, 0, sizeof *ln);
  ln->dir = g_dir_make_tmp ("ds-pymodbus-XXXXXX", &error);
  g_assert_no_error (error);
  ln->a = g_build_filename (ln->dir, "ttyA", NULL);
  ln->b = g_build_filename (ln->dir, "ttyB", NULL);
  ln->controller_args = controller_args;
  line_up (ln);
}

static void
line_free (Line *ln)
{
  line_down (ln);
  g_rmdir (ln->dir);
  g_free (ln->dir);
  g_free (ln->a);
  g_free (ln->b);
}

/* A controller written elsewhere: sets are correct; exception 06 beyond the retries, silence
 * and the whole line going away each fail one set with a clear reason, and the next set is
 * correct again. */
static void
test_pymodbus_controller (void)
{
  Line ln;
  line_new (&ln, NULL);
  g_autofree char *light = g_strdup_printf ("tcp://127.0.0.1:%u", ln.light_port);
  const char *args[] = { "--light-from", light, NULL };
  TestLabsim *l = test_labsim_start (labsim_path, scene_path, args);
  g_autoptr (DsClient) c = NULL;
  Tally t;
  TestDaemon *d = daemon_on_line (ln.b, &c, &t);

  /* Busy for 4 requests: more than one access's 3 attempts (the set's first access, loading the
   * pattern, fails: the sequencer does not retry that), fewer than two accesses' (the next set
   * gets through on a retry). */
  controller_signal (&ln, SIGUSR1, "armed busy");
  g_autofree char *busy = capture (c, &t, "exception 06");
  g_assert_nonnull (busy);
  g_free (capture (c, &t, NULL));
  g_assert_cmpuint (t.ok, ==, 3);

  /* Silent until told otherwise: every attempt of the set's first access times out. */
  controller_signal (&ln, SIGUSR2, "silent on");
  g_autofree char *silent = capture (c, &t, "timed out");
  g_assert_nonnull (silent);
  controller_signal (&ln, SIGUSR2, "silent off");
  g_free (capture (c, &t, NULL));
  g_assert_cmpuint (t.ok, ==, 4);

  /* The peer goes away (controller and line) and comes back under the same names. */
  line_down (&ln);
  g_autofree char *away = capture (c, &t, ln.b);
  g_assert_nonnull (away);
  line_up (&ln);
  g_free (capture (c, &t, NULL));
  g_free (capture (c, &t, NULL));
  g_assert_cmpuint (t.ok, ==, 6);
  g_assert_cmpuint (t.failed, ==, 3);
  test_daemon_frames (c);
  test_daemon_stop_clean (d);
  test_labsim_stop (l);
  line_free (&ln);
}

/* The period register on a controller written elsewhere (issue 12), driven by the daemon's
 * Modbus backend over RTU and seen by labsim's camera through that controller's registers: an
 * adjustable projector shows the period asked for in the frames; a fixed one and one of the
 * first map (no CAPABILITIES) say so, and the backend refuses another period before writing. */
static void
test_pymodbus_period (void)
{
  g_autoptr (GError) error = NULL;
  double period = ds_scene_period_px (the_scene);
  Line ln;
  line_new (&ln, NULL);
  g_autofree char *light = g_strdup_printf ("tcp://127.0.0.1:%u", ln.light_port);
  const char *args[] = { "--light-from", light, NULL };
  TestLabsim *l = test_labsim_start (labsim_path, scene_path, args);
  g_autofree char *uri = g_strdup_printf ("rtu:%s?baud=115200&parity=N", ln.b);
  DsIlluminator *ill = ds_modbus_illuminator_open (uri, 1, ANSWER_MS, &error);
  g_assert_no_error (error);
  DsIlluminatorStatus st;
  g_assert_true (ill->ops->get_status (ill->backend, &st, &error));
  g_assert_true (st.period_adjustable);
  g_assert_cmpfloat (st.period_min_px, ==, 2.0);
  g_assert_cmpfloat (st.period_max_px, ==, 655.35);
  DsCamera *cam = ds_aravis_camera_open ("127.0.0.1", 4, &error);
  g_assert_no_error (error);
  DsCameraSettings cs = { .exposure_us = ds_scene_default_exposure_us (the_scene), .pixel_format = "Mono16",
                          .trigger_source = DS_CAMERA_TRIGGER_SOFTWARE };
  g_assert_true (cam->ops->configure (cam->backend, &cs, &error));
  g_assert_true (cam->ops->start (cam->backend, &error));
  g_assert_no_error (error);
  /* Rows above the scene's objects: stripes over the medium only. */
  DsRegion region = { 0, 0, ds_scene_width (the_scene), MIN (ds_scene_height (the_scene), 40u) };
  DsStripePattern p = { .kind = ds_scene_pattern_is_sine (the_scene) ? DS_STRIPES_SINE : DS_STRIPES_SQUARE,
                        .period_px = 1.75 * period, .duty = ds_scene_duty (the_scene),
                        .black_level = ds_scene_black_level (the_scene), .intensity = 1, .n_phases = 4 };
  period_check_frames (ill, cam, &p, &region, 0.005);
  ds_camera_close (cam);
  ds_illuminator_close (ill);
  test_labsim_stop (l);
  line_free (&ln);

  /* A fixed projector, and a controller of the first map. */
  const char *fixed[] = { "--fixed-period-centipx", "825", NULL };
  const char *rev1[] = { "--map-revision", "1", NULL };
  const char *const *variants[] = { fixed, rev1 };
  for (guint v = 0; v < G_N_ELEMENTS (variants); v++) {
    line_new (&ln, variants[v]);
    g_autofree char *u = g_strdup_printf ("rtu:%s?baud=115200&parity=N", ln.b);
    ill = ds_modbus_illuminator_open (u, 1, ANSWER_MS, &error);
    g_assert_no_error (error);
    g_assert_true (ill->ops->get_status (ill->backend, &st, &error));
    g_assert_false (st.period_adjustable);
    g_assert_cmpfloat (st.period_min_px, ==, v == 0 ? 8.25 : 0);
    g_assert_cmpfloat (st.period_max_px, ==, st.period_min_px);
    p.period_px = 8.25;
    g_assert_true (ill->ops->set_pattern (ill->backend, &p, &error));
    g_assert_true (ill->ops->set_phase (ill->backend, 1, 5000, &error));
    g_assert_no_error (error);
    p.period_px = 12;
    g_assert_false (ill->ops->set_pattern (ill->backend, &p, &error));
    g_assert_error (error, DS_ILLUMINATOR_ERROR, DS_DEVICE_ERROR_UNSUPPORTED);
    g_test_message ("%s", error->message);
    g_assert_nonnull (strstr (error->message, "PERIOD_CENTIPX"));
    g_assert_nonnull (strstr (error->message, "8.25 px"));
    g_assert_nonnull (strstr (error->message, "asked for 12.00 px"));
    g_clear_error (&error);
    ds_illuminator_close (ill);
    line_free (&ln);
  }
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  if (argc < 4) {
    fprintf (stderr, "usage: test_daemon_rtu LABSIM SCENE PYMODBUS_CONTROLLER\n");
    return 2;
  }
  labsim_path = argv[1];
  scene_path = argv[2];
  controller_path = argv[3];
  truth_scene_load (scene_path, &the_scene, &truth_t, &truth_g);
  g_test_add_func ("/daemon-rtu/labsim", test_labsim_rtu);
  g_test_add_func ("/daemon-rtu/pymodbus-controller", test_pymodbus_controller);
  g_test_add_func ("/daemon-rtu/pymodbus-period", test_pymodbus_period);
  int status = g_test_run ();
  truth_scene_free (the_scene, truth_t, truth_g);
  return status;
}
