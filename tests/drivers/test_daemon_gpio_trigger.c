/* descatterd's GPIO trigger end to end: [trigger] backend=gpio pulses line 0 of
 * descatter-labsim's simulated GPIO chip (--gpio-chip, over its UNIX socket), which is wired to
 * labsim's camera input Line0; the camera ([camera] trigger=line0, real GigE Vision) exposes on
 * that edge, not on a software command, and the illuminator is labsim's Modbus controller (its
 * sync output unwired). Every set equals the scene's truth (the renderer's, computed here); a
 * missed trigger is a grab timeout, counted, failing its set cleanly, and the next set is
 * correct; a double trigger's surplus frame is dropped with its reason and never folded; a chip
 * that is not there and a line another consumer holds are refused naming them.
 * Usage: test_daemon_gpio_trigger LABSIM SCENE. Binds UDP 3956. */
#include <glib/gstdio.h>
#include <stdio.h>
#include <string.h>

#include "tests/common/daemon_harness.h"
#include "tests/common/truth_check.h"
#include "drivers/gpio/gpio_backends.h"

static const char *labsim_path, *scene_path;
static DsScene *the_scene;
static DsImage *truth_t, *truth_g;

typedef struct {
  char *dir, *chip_path;
  TestLabsim *labsim;
} Rig;

static Rig *
rig_start (const char *const *faults)
{
  Rig *r = g_new0 (Rig, 1);
  r->dir = g_dir_make_tmp ("gpio-trigger-XXXXXX", NULL);
  r->chip_path = g_build_filename (r->dir, "gpio.sock", NULL);
  g_autoptr (GPtrArray) args = g_ptr_array_new ();
  const char *wiring[] = { "--gpio-chip", r->chip_path, "--sync-line", "-1" };
  for (guint i = 0; i < G_N_ELEMENTS (wiring); i++)
    g_ptr_array_add (args, (gpointer) wiring[i]);
  for (guint i = 0; faults && faults[i]; i++)
    g_ptr_array_add (args, (gpointer) faults[i]);
  g_ptr_array_add (args, NULL);
  r->labsim = test_labsim_start (labsim_path, scene_path, (const char *const *) args->pdata);
  return r;
}

static void
rig_stop (Rig *r)
{
  test_labsim_stop (r->labsim);
  g_rmdir (r->dir);
  g_free (r->chip_path);
  g_free (r->dir);
  g_free (r);
}

static char *
daemon_config (const Rig *r, const char *chip, guint grab_timeout_ms, guint retries)
{
  return g_strdup_printf ("[camera]\nbackend=aravis\naddress=127.0.0.1\npixel-format=Mono12p\n"
                          "exposure-us=%g\ngrab-timeout-ms=%u\ntrigger=line0\n"
                          "[illuminator]\nbackend=modbus\nmodbus-uri=tcp://127.0.0.1:%u\nmodbus-timeout-ms=300\n"
                          "period-px=%g\nduty=%g\ngpio-chip=%s\n"
                          "[trigger]\nbackend=gpio\ngpio-line=0\npulse-us=100\n"
                          "[acquisition]\nphases=4\naverages=2\ndark-frame=true\nphase-retries=%u\n",
                          ds_scene_default_exposure_us (the_scene), grab_timeout_ms, r->labsim->modbus_port,
                          ds_scene_period_px (the_scene), ds_scene_duty (the_scene), chip, retries);
}

static char *
labsim_chip (const Rig *r)
{
  return g_strdup_printf ("labsim:%s", r->chip_path);
}

/* A daemon on conf takes `sets` sets, each equal to the truth; returns its frame counters. */
static TestFrames
correct_sets (const char *conf, guint sets)
{
  TestDaemon *d = test_daemon_start (conf, NULL);
  g_autoptr (DsClient) c = test_daemon_connect (d);
  for (guint i = 0; i < sets; i++)
    g_assert_true (truth_capture (c, NULL, the_scene, truth_t, truth_g, NULL, NULL));
  TestFrames f = test_daemon_frames (c);
  test_daemon_stop_clean (d);
  return f;
}

/* descatterd --check --probe: opens the configured devices, the GPIO trigger's line included.
 * Returns its exit status; *err (the caller's) what it printed on stderr. */
static int
probe (const Rig *r, const char *chip, char **err)
{
  g_autofree char *text = daemon_config (r, chip, 1000, 0);
  return test_daemon_check (text, TRUE, NULL, err);
}

/* No faults: every set correct, each exposure one pulse: no timeout, no surplus frame. */
static void
test_sets (void)
{
  Rig *r = rig_start (NULL);
  g_autofree char *chip = labsim_chip (r);
  /* However slowly a loaded (or sanitized) labsim serves, no grab may time out. */
  g_autofree char *conf = daemon_config (r, chip, 10000, 4);
  TestFrames f = correct_sets (conf, 3);
  g_assert_cmpint (f.timeouts, ==, 0);
  /* Unlike the projector's sync (which pulses on every apply), the GPIO line is pulsed once per
   * frame the sequencer takes, after the phase is applied: no frame is surplus or stale. */
  g_assert_cmpint (f.stale + f.wrong_phase + f.aborted, ==, 0);
  g_assert_cmpint (f.folded, ==, 3 * (4 + 1) * 2);
  rig_stop (r);
}

/* Every 12th edge is missed; no retries, so that set fails on the timeout, and the next is whole. */
static void
test_missed_trigger (void)
{
  const char *faults[] = { "--line-miss-every", "12", NULL };
  Rig *r = rig_start (faults);
  g_autofree char *chip = labsim_chip (r);
  /* Long enough that only a missed edge times out, even on a loaded machine. */
  g_autofree char *conf = daemon_config (r, chip, 2000, 0);
  TestDaemon *d = test_daemon_start (conf, NULL);
  g_autoptr (DsClient) c = test_daemon_connect (d);
  guint failed = 0, recovered = 0;
  gboolean last_failed = FALSE;
  for (guint i = 0; i < 4; i++) {
    g_autofree char *why = NULL;
    gboolean ok = truth_capture (c, NULL, the_scene, truth_t, truth_g, &why, NULL);
    if (!ok) {
      g_assert_nonnull (strstr (why, "no frame within 2000 ms"));
      failed++;
    } else if (last_failed)
      recovered++;
    last_failed = !ok;
  }
  TestFrames f = test_daemon_frames (c);
  /* 10 frames a set ((4 phases + dark) x 2 averages), every 12th edge missed: set 1 takes edges
   * 1-10, set 2 fails at edge 12, set 3 takes 13-22, set 4 fails at edge 24. */
  g_assert_cmpuint (failed, ==, 2);
  g_assert_cmpuint (recovered, ==, 1);
  g_assert_cmpint (f.timeouts, ==, failed); /* each missed edge counted once */
  g_assert_cmpint (f.stale + f.wrong_phase, ==, 0);
  test_daemon_stop_clean (d);
  rig_stop (r);
}

/* Every 5th edge makes two frames: the surplus one is dropped with its reason, every set is
 * still the truth (no frame folded into the next phase). */
static void
test_double_trigger (void)
{
  const char *faults[] = { "--line-double-every", "5", NULL };
  Rig *r = rig_start (faults);
  g_autofree char *chip = labsim_chip (r);
  g_autofree char *conf = daemon_config (r, chip, 10000, 4);
  TestFrames f = correct_sets (conf, 3);
  g_assert_cmpint (f.timeouts, ==, 0);
  g_assert_cmpint (f.stale + f.wrong_phase, >=, 1); /* the surplus frames, dropped with their reason */
  g_assert_cmpint (f.folded, ==, 3 * (4 + 1) * 2);

  /* The devices' own checks: a chip that is not there, then a line another consumer holds
   * (refused BUSY naming it, as the kernel does), then the same line free again. */
  g_autofree char *absent = g_strdup_printf ("labsim:%s/absent.sock", r->dir);
  g_autofree char *err1 = NULL, *err2 = NULL;
  g_assert_cmpint (probe (r, absent, &err1), ==, 1);
  g_assert_nonnull (strstr (err1, "[trigger] backend=gpio"));
  g_assert_nonnull (strstr (err1, "cannot open the chip"));
  guint zero = 0;
  g_autoptr (GError) error = NULL;
  DsGpioLines *held = ds_gpio_lines_open (chip, &zero, 1, NULL, "test-holder", &error);
  g_assert_no_error (error);
  g_assert_cmpint (probe (r, chip, &err2), ==, 1);
  g_assert_nonnull (strstr (err2, "line 0 is busy: held by \"test-holder\""));
  ds_gpio_lines_free (held);
  g_assert_cmpint (probe (r, chip, NULL), ==, 0);
  rig_stop (r);
}

/* A rig of GPIO only: the illuminator's stripe lines are the chip's lines 1..8 (enable 9),
 * which labsim's camera sees as its projector (--gpio-stripe-lines), and the trigger line 0. */
static void
test_gpio_illuminator (void)
{
  const char *lines[] = { "--gpio-stripe-lines", "8", "--gpio-enable-line", "9", NULL };
  Rig *r = rig_start (lines);
  g_autofree char *chip = labsim_chip (r);
  g_autofree char *conf = g_strdup_printf (
      "[camera]\nbackend=aravis\naddress=127.0.0.1\npixel-format=Mono12p\nexposure-us=%g\ngrab-timeout-ms=10000\n"
      "trigger=line0\n"
      "[illuminator]\nbackend=gpio\ngpio-chip=%s\ngpio-lines=1,2,3,4,5,6,7,8\ngpio-enable-line=9\n"
      "pattern=square\nperiod-px=%g\nduty=%g\n"
      "[trigger]\nbackend=gpio\ngpio-line=0\n"
      "[acquisition]\nphases=4\naverages=2\ndark-frame=true\nphase-retries=4\n",
      ds_scene_default_exposure_us (the_scene), chip, ds_scene_period_px (the_scene), ds_scene_duty (the_scene));
  TestFrames f = correct_sets (conf, 2);
  g_assert_cmpint (f.timeouts + f.stale + f.wrong_phase + f.aborted, ==, 0);
  rig_stop (r);
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  if (argc < 3) {
    fprintf (stderr, "usage: test_daemon_gpio_trigger LABSIM SCENE\n");
    return 2;
  }
  labsim_path = argv[1];
  scene_path = argv[2];
  truth_scene_load (scene_path, &the_scene, &truth_t, &truth_g);
  g_test_add_func ("/daemon-gpio-trigger/sets", test_sets);
  g_test_add_func ("/daemon-gpio-trigger/missed-trigger", test_missed_trigger);
  g_test_add_func ("/daemon-gpio-trigger/double-trigger-and-chip-errors", test_double_trigger);
  g_test_add_func ("/daemon-gpio-trigger/gpio-illuminator", test_gpio_illuminator);
  int status = g_test_run ();
  truth_scene_free (the_scene, truth_t, truth_g);
  return status;
}
