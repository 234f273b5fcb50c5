/* Soak: many phase sets in continuous mode with randomly injected faults. Pass criteria
 * (issue 7): every set is either correct (within the noise-model bound against the
 * simulator's truth) or failed with a reason; the counters add up (acquired = folded +
 * dropped); the daemon's RSS stops growing.
 * Usage: test_soak SCENE SETS FAULTS [LABSIM]   (ctest: reduced runs; the full 1000-set runs
 * are in docs/reliability.md). With LABSIM, the daemon drives descatter-labsim over GigE Vision
 * and Modbus TCP and FAULTS are labsim's fault options (space-separated); otherwise FAULTS is
 * the in-process simulated devices' [sim] faults string. */
#include <stdio.h>
#include <string.h>

#include "tests/common/daemon_harness.h"
#include "tests/common/truth_check.h"

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  if (argc < 4) {
    fprintf (stderr, "usage: test_soak SCENE SETS FAULTS\n");
    return 2;
  }
  const char *scene_path = argv[1];
  guint sets = (guint) g_ascii_strtoull (argv[2], NULL, 10);
  g_autoptr (GError) error = NULL;
  g_autoptr (DsScene) scene = ds_scene_load (scene_path, &error);
  g_assert_no_error (error);
  g_autoptr (DsRenderer) renderer = ds_renderer_new (scene, NULL, &error);
  g_assert_no_error (error);
  double exposure = ds_scene_default_exposure_us (scene);
  DsImage *tt = NULL, *tg = NULL;
  g_assert_true (ds_renderer_truth (renderer, exposure, 0.0, &tt, &tg, &error));
  g_autoptr (DsImage) truth_t = tt;
  g_autoptr (DsImage) truth_g = tg;

  TestLabsim *lab = NULL;
  g_autofree char *conf = NULL;
  if (argc > 4) {
    g_auto (GStrv) fault_args = g_strsplit (argv[3], " ", -1);
    lab = test_labsim_start (argv[4], scene_path, (const char *const *) fault_args);
    conf = g_strdup_printf (
        "[camera]\nbackend=aravis\naddress=127.0.0.1\npixel-format=Mono16\nexposure-us=%g\n"
        "grab-timeout-ms=1000\n[illuminator]\nbackend=modbus\nmodbus-uri=tcp://127.0.0.1:%u\n"
        "modbus-timeout-ms=200\nperiod-px=%g\nduty=%g\n"
        "[acquisition]\nphases=8\ndark-frame=true\nphase-retries=4\n",
        exposure, lab->modbus_port, ds_scene_period_px (scene), ds_scene_duty (scene));
  } else
    conf = g_strdup_printf (
        "[camera]\nbackend=sim\nexposure-us=%g\ngrab-timeout-ms=300\n[illuminator]\nbackend=sim\n"
        "[acquisition]\nphases=8\ndark-frame=true\nphase-retries=4\n"
        "[sim]\nscene=%s\nseed=11\nfaults=%s\n", exposure, scene_path, argv[3]);
  TestDaemon *d = test_daemon_start (conf, NULL);
  g_autoptr (DsClient) sub = test_daemon_connect (d);
  g_autoptr (DsClient) ctl = test_daemon_connect (d);
  g_autoptr (DsMessage) s = test_daemon_call_ok (sub, "subscribe", NULL);
  g_autoptr (DsMessage) st = test_daemon_call_ok (ctl, "start", NULL);

  guint correct = 0, failed = 0, wrong = 0, devices = 0;
  guint64 rss_early = 0, rss_late = 0;
  double worst_ratio = 0;
  while (correct + failed < sets) {
    g_autoptr (DsMessage) ev = ds_client_read (sub, 120000, &error);
    g_assert_no_error (error);
    const char *kind = ev->reply->event;
    if (g_strcmp0 (kind, "result") == 0) {
      TruthCheck tc;
      truth_check (ev, scene, truth_t, truth_g, &tc);
      if (truth_check_passed (&tc))
        correct++;
      else {
        wrong++;
        g_printerr ("set %" G_GINT64_FORMAT " WRONG: rms %.2f/%.2f (allowed %.2f/%.2f)\n",
                    test_json_int (ev->reply->body, "set_id"), tc.rms_transmissive,
                    tc.rms_scattered, tc.allowed_transmissive, tc.allowed_scattered);
      }
      worst_ratio = MAX (worst_ratio, tc.rms_transmissive / tc.allowed_transmissive);
    } else if (g_strcmp0 (kind, "failed") == 0) {
      JsonObject *b = json_node_get_object (ev->reply->body);
      const char *reason = json_object_get_string_member_with_default (b, "reason", "");
      g_assert_cmpuint (strlen (reason), >, 0); /* a failure always says why */
      failed++;
    } else if (g_strcmp0 (kind, "device") == 0)
      devices++;
    guint done = correct + failed;
    /* The baseline once the result and frame pools are warm: after a fifth of the sets and at
     * least two results (failed sets allocate no result). */
    if (!rss_early && done >= MAX (sets / 5, 2) && correct >= 2)
      rss_early = test_daemon_rss_kib (d);
  }
  rss_late = test_daemon_rss_kib (d);
  if (!rss_early) /* fewer than two results: no warm baseline, the growth is not measured */
    rss_early = rss_late;
  /* The control connection has been idle since `start`: the daemon closes such a one after
   * idle-timeout-ms (60 s), which a soak on a busy machine outlasts. A fresh one stops it. */
  g_clear_pointer (&ctl, ds_client_free);
  ctl = test_daemon_connect (d);
  g_autoptr (DsMessage) stop = test_daemon_call_ok (ctl, "stop", NULL);
  TestFrames f = test_daemon_frames (ctl); /* asserts acquired = folded + dropped */
  printf ("soak: %u sets: %u correct, %u failed with a reason, %u wrong; %u device events; "
          "frames acquired %" G_GINT64_FORMAT " = folded %" G_GINT64_FORMAT " + dropped %" G_GINT64_FORMAT
          "; worst rms/allowed %.2f; RSS %" G_GUINT64_FORMAT " -> %" G_GUINT64_FORMAT " KiB\n",
          sets, correct, failed, wrong, devices, f.acquired, f.folded, f.dropped, worst_ratio, rss_early, rss_late);
  g_assert_cmpuint (wrong, ==, 0);
  g_assert_cmpuint (correct, >, 0);
  /* The faults happened (in-process: dropped frames; labsim: dropped frames, device errors or
   * failed sets). */
  g_assert_cmpint (f.dropped + failed + f.device_errors, >, 0);
  /* Bounded growth: after the first fifth, the heap may not grow by more than a few results'
   * worth (allocator slack), whatever the number of sets. */
  g_assert_cmpuint (rss_late, <, rss_early + 32 * 1024);
  test_daemon_stop_clean (d);
  if (lab)
    test_labsim_stop (lab);
  return 0;
}
