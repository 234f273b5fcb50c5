/* descatterd's hardware-trigger path end to end: labsim's camera on TriggerSource Line0, driven
 * by the illuminator controller's sync output ([trigger] backend=projector-sync), over real
 * GigE Vision and Modbus TCP. Every set equals the scene's truth; a missed sync pulse is a grab
 * timeout, counted and retried; a double pulse is a surplus frame, dropped with its reason.
 * Usage: test_daemon_trigger LABSIM SCENE. Binds UDP 3956. */
#include <stdio.h>
#include <string.h>

#include "tests/common/daemon_harness.h"
#include "tests/common/truth_check.h"

static const char *labsim_path, *scene_path;
static DsScene *the_scene;
static DsImage *truth_t, *truth_g;

static char *
daemon_config (const TestLabsim *l, guint grab_timeout_ms)
{
  return g_strdup_printf ("[camera]\nbackend=aravis\naddress=127.0.0.1\npixel-format=Mono12p\n"
                          "exposure-us=%g\ngrab-timeout-ms=%u\ntrigger=line0\n"
                          "[illuminator]\nbackend=modbus\nmodbus-uri=tcp://127.0.0.1:%u\nmodbus-timeout-ms=300\n"
                          "period-px=%g\nduty=%g\n"
                          "[trigger]\nbackend=projector-sync\n"
                          "[acquisition]\nphases=4\naverages=2\ndark-frame=true\nphase-retries=4\n",
                          ds_scene_default_exposure_us (the_scene), grab_timeout_ms, l->modbus_port,
                          ds_scene_period_px (the_scene), ds_scene_duty (the_scene));
}

/* n captures: each correct or failed with a reason; returns the correct ones. */
static guint
captures (DsClient *c, guint n)
{
  guint ok = 0;
  for (guint i = 0; i < n; i++)
    ok += truth_capture (c, NULL, the_scene, truth_t, truth_g, NULL, NULL);
  return ok;
}

static void
run (const char *const *labsim_args, gboolean faults)
{
  TestLabsim *l = test_labsim_start (labsim_path, scene_path, labsim_args);
  /* Without faults no grab may time out, however slowly a loaded (or sanitized) labsim
   * serves its frames; with them a missed pulse should cost little time. */
  g_autofree char *conf = daemon_config (l, faults ? 1000 : 10000);
  TestDaemon *d = test_daemon_start (conf, NULL);
  g_autoptr (DsClient) c = test_daemon_connect (d);
  guint ok = captures (c, 3);
  g_test_message ("%u of 3 sets correct", ok);
  TestFrames f = test_daemon_frames (c);
  if (!faults) {
    g_assert_cmpuint (ok, ==, 3);
    g_assert_cmpint (f.timeouts, ==, 0);
    /* Every apply pulses the sync line, loading the pattern and switching off for the dark
     * frame too: so a loaded rig shows surplus frames, stale, of another phase or without
     * stripes, and loopback may lose packets of one. The daemon must drop each with its reason
     * and keep every set correct; none may be folded into a set that then failed. */
    g_assert_cmpint (f.aborted, ==, 0);
  } else {
    g_assert_cmpuint (ok, >=, 2);
    g_assert_cmpint (f.timeouts, >, 0);              /* the missed pulses, counted */
    g_assert_cmpint (f.stale + f.wrong_phase, >, 0); /* the surplus frames, dropped with their reason */
  }
  test_daemon_stop_clean (d);
  test_labsim_stop (l);
}

static void
test_projector_sync (void)
{
  run (NULL, FALSE);
}

/* Every 5th sync pulse makes no frame, every 7th two. */
static void
test_missed_and_double (void)
{
  const char *args[] = { "--line-miss-every", "5", "--line-double-every", "7", NULL };
  run (args, TRUE);
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  if (argc < 3) {
    fprintf (stderr, "usage: test_daemon_trigger LABSIM SCENE\n");
    return 2;
  }
  labsim_path = argv[1];
  scene_path = argv[2];
  truth_scene_load (scene_path, &the_scene, &truth_t, &truth_g);
  g_test_add_func ("/daemon-trigger/projector-sync", test_projector_sync);
  g_test_add_func ("/daemon-trigger/missed-and-double", test_missed_and_double);
  int status = g_test_run ();
  truth_scene_free (the_scene, truth_t, truth_g);
  return status;
}
