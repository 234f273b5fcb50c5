/* `descatterd --check --probe` against real GigE Vision and Modbus TCP (descatter-labsim) with a
 * camera that lacks formats and gain: a configured setting the camera refuses fails (exit 1)
 * naming the setting and what the camera allows, a matching configuration passes (exit 0) and
 * the camera's identity printed is the one Aravis itself reads from it; an illuminator faulted,
 * too hot or stuck busy, and an absent camera, fail too. (issue 10)
 *   test_check_probe LABSIM SCENE      (ctest: in a private network namespace, UDP 3956) */
#include <arv.h>
#include <glib/gstdio.h>
#include <string.h>

#include "tests/common/daemon_harness.h"

static const char *labsim_path, *scene_path;

typedef struct {
  int status;
  char *out, *err;
} Probe;

static void
probe_clear (Probe *p)
{
  g_free (p->out);
  g_free (p->err);
}
G_DEFINE_AUTO_CLEANUP_CLEAR_FUNC (Probe, probe_clear)

/* descatterd --check [--probe] on a configuration with camera_keys under [camera]. */
static Probe
probe (const TestLabsim *l, const char *camera_keys, gboolean with_probe)
{
  g_autofree char *text = g_strdup_printf (
      "[camera]\nbackend=aravis\naddress=127.0.0.1\n%s\n"
      "[illuminator]\nbackend=modbus\nmodbus-uri=tcp://127.0.0.1:%u\nmodbus-timeout-ms=200\n",
      camera_keys, l ? l->modbus_port : 1);
  g_test_message ("[camera] %s", camera_keys);
  Probe r = { 0 };
  r.status = test_daemon_check (text, with_probe, &r.out, &r.err);
  return r;
}

static void
assert_mentions (const char *text, const char *const *words)
{
  for (guint i = 0; words[i]; i++)
    if (!strstr (text, words[i]))
      g_error ("\"%s\" does not mention \"%s\"", text, words[i]);
}

static void
test_probe_refused_and_matching (void)
{
  /* A camera offering Mono8 and Mono16 only, with 0..10 dB of gain. */
  const char *camera[] = { "--pixel-formats", "Mono8,Mono16", "--gain-max", "10", NULL };
  TestLabsim *l = test_labsim_start (labsim_path, scene_path, camera);
  const struct { const char *keys; const char *err[4]; } refused[] = {
    { "pixel-format=Mono12p", { "PixelFormat Mono12p", "Mono8, Mono16", NULL } },
    { "pixel-format=Mono12", { "PixelFormat Mono12 ", "Mono8, Mono16", NULL } },
    { "pixel-format=Mono16\ngain-db=12", { "gain 12 dB", "[0, 10]", NULL } },
    { "pixel-format=Mono16\nexposure-us=5", { "exposure 5 µs", NULL } },
  };
  for (guint i = 0; i < G_N_ELEMENTS (refused); i++) {
    g_auto (Probe) r = probe (l, refused[i].keys, TRUE);
    g_assert_cmpint (r.status, ==, 1);
    assert_mentions (r.err, (const char *const[]) { "refuse the configured settings", NULL });
    assert_mentions (r.err, refused[i].err);
    /* What the camera allows is printed even when it refuses. */
    assert_mentions (r.out, (const char *const[]) { "pixel formats offered: Mono8, Mono16", "gain range: 0 .. 10 dB", NULL });
  }
  /* Without --probe the devices are not asked: the same configuration passes. */
  {
    g_auto (Probe) r = probe (l, "pixel-format=Mono12p", FALSE);
    g_assert_cmpint (r.status, ==, 0);
    g_assert_null (strstr (r.out, "pixel formats offered"));
  }
  /* The limits themselves are allowed. */
  g_auto (Probe) ok = probe (l, "pixel-format=Mono16\ngain-db=10", TRUE);
  g_assert_cmpint (ok.status, ==, 0);
  assert_mentions (ok.out, (const char *const[]) { "the devices took the configured settings", "firmware ", NULL });
  /* The identity printed is the camera's, as Aravis reads it independently. */
  g_autoptr (GError) error = NULL;
  g_autoptr (ArvCamera) cam = arv_camera_new ("127.0.0.1", &error);
  g_assert_no_error (error);
  const char *vendor = arv_camera_get_vendor_name (cam, NULL), *model = arv_camera_get_model_name (cam, NULL),
             *serial = arv_camera_get_device_serial_number (cam, NULL);
  g_assert_nonnull (vendor);
  g_autofree char *identity = g_strdup_printf ("vendor %s, model %s, serial %s", vendor, model, serial);
  assert_mentions (ok.out, (const char *const[]) { identity, NULL });
  g_clear_object (&cam);
  TestLabsim gone_lab = *l;
  test_labsim_stop (l);
  /* No camera at the address: fails naming it. */
  g_auto (Probe) gone = probe (&gone_lab, "pixel-format=Mono16", TRUE);
  g_assert_cmpint (gone.status, ==, 1);
  assert_mentions (gone.err, (const char *const[]) { "127.0.0.1", NULL });
}

/* An illuminator that is not idle and well when it opens is not a rig ready to capture: the
 * first phase of every set would fail. */
static void
test_probe_illuminator_state (void)
{
  const struct { const char *knob; const char *err; } states[] = {
    { "--illuminator-fault", "driver fault" },
    { "--over-temperature", "over-temperature" },
    { "--stuck-not-ready", "not ready" },
  };
  for (guint i = 0; i < G_N_ELEMENTS (states); i++) {
    const char *knob[] = { states[i].knob, NULL };
    TestLabsim *l = test_labsim_start (labsim_path, scene_path, knob);
    g_auto (Probe) r = probe (l, "pixel-format=Mono16", TRUE);
    g_assert_cmpint (r.status, ==, 1);
    assert_mentions (r.err, (const char *const[]) { "the illuminator reports", states[i].err, NULL });
    test_labsim_stop (l);
  }
}

/* --probe is part of --check, never a way to start the daemon. */
static void
test_probe_needs_check (void)
{
  g_autoptr (GError) error = NULL;
  g_autoptr (GSubprocess) p = g_subprocess_new (G_SUBPROCESS_FLAGS_STDOUT_SILENCE | G_SUBPROCESS_FLAGS_STDERR_PIPE,
                                                &error, DESCATTERD_PATH, "--probe", "--sim", NULL);
  g_assert_no_error (error);
  g_autofree char *err = NULL;
  g_subprocess_communicate_utf8 (p, NULL, NULL, NULL, &err, &error);
  g_assert_no_error (error);
  g_assert_cmpint (g_subprocess_get_exit_status (p), ==, 2);
  g_assert_nonnull (strstr (err, "--check --probe"));
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  if (argc != 3) {
    g_printerr ("usage: test_check_probe LABSIM SCENE\n");
    return 2;
  }
  labsim_path = argv[1];
  scene_path = argv[2];
  g_test_add_func ("/check-probe/needs-check", test_probe_needs_check);
  g_test_add_func ("/check-probe/refused-and-matching", test_probe_refused_and_matching);
  g_test_add_func ("/check-probe/illuminator-state", test_probe_illuminator_state);
  int rc = g_test_run ();
  arv_shutdown ();
  return rc;
}
