/* descatterd end to end on the in-process simulated lab: a real daemon process, real sockets,
 * the simulator's ground truth as the independent expectation. */
#include "tests/common/config_groups.h"
#include <fcntl.h>
#include <glib/gstdio.h>
#include <math.h>
#include <signal.h>
#include <string.h>
#include <unistd.h>

#include "tests/common/daemon_harness.h"
#include "tests/common/truth_check.h"
#include "drivers/sim/renderer.h"
#include "proc/separation.h"
#include "drivers/sim/scene.h"

/* The base configuration with a case's groups merged into it (descatterd refuses a group
 * given twice, and a reload rewrites the whole file). */
static char *
config_text (const char *extra)
{
  g_autofree char *joined = g_strdup_printf ("[camera]\nbackend=sim\n[illuminator]\nbackend=sim\n"
                                             "[sim]\nscene=%s\nseed=7\n%s",
                                             SCENE_FILE, extra ? extra : "");
  return test_config_groups_merge (joined);
}

static void
assert_accounting (JsonNode *status)
{
  gint64 acquired = test_json_int (status, "frames.acquired");
  gint64 folded = test_json_int (status, "frames.folded");
  gint64 dropped = test_json_int (status, "frames.dropped");
  g_assert_cmpint (acquired, ==, folded + dropped);
}

/* A capture through the socket equals the scene's ground truth within the noise model:
 * transmissive and scattered are compared with the renderer's noise-free truth over the
 * valid pixels. The bound is derived from the sensor model (see comments), not measured. */
static void
test_capture_matches_truth (void)
{
  g_autoptr (GError) error = NULL;
  g_autoptr (DsScene) scene = ds_scene_load (SCENE_FILE, &error);
  g_assert_no_error (error);
  double exposure = ds_scene_default_exposure_us (scene);
  g_autofree char *conf = config_text (NULL);
  TestDaemon *d = test_daemon_start (conf, NULL);
  g_autoptr (DsClient) c = test_daemon_connect (d);
  g_autoptr (JsonObject) args = json_object_new ();
  json_object_set_int_member (args, "phases", 8);
  json_object_set_boolean_member (args, "dark_frame", TRUE);
  json_object_set_double_member (args, "exposure_us", exposure);
  g_autoptr (DsMessage) m = test_daemon_call_ok (c, "capture", args);

  g_autoptr (DsRenderer) r = ds_renderer_new (scene, NULL, &error);
  g_assert_no_error (error);
  DsImage *tt = NULL, *tg = NULL;
  g_assert_true (ds_renderer_truth (r, exposure, 0.0, &tt, &tg, &error));
  g_autoptr (DsImage) truth_t = tt;
  g_autoptr (DsImage) truth_g = tg;

  TruthCheck tc;
  truth_check (m, scene, truth_t, truth_g, &tc);
  g_test_message ("rms error: transmissive %.2f DN (allowed %.2f), scattered %.2f DN (allowed %.2f), %"
                  G_GUINT64_FORMAT " of %" G_GUINT64_FORMAT " pixels valid",
                  tc.rms_transmissive, tc.allowed_transmissive, tc.rms_scattered,
                  tc.allowed_scattered, tc.valid, tc.pixels);
  /* Most pixels are valid, of those the sampling precondition keeps: the simulated illuminator's
   * edge blur is known to the daemon (as calibrate's edge-blur-px makes it known), so maxmin's
   * sets flag the positions its blurred edges keep from being fully lit or dark (proc's check of
   * the same geometry, separation.h). */
  DsSeparationParams sp;
  ds_separation_params_init (&sp, 8);
  sp.duty = ds_scene_duty (scene);
  sp.geometry.period_px = ds_scene_period_px (scene);
  sp.geometry.pixel_aperture = 1;
  sp.geometry.edge_blur_known = TRUE;
  sp.geometry.edge_blur_px = ds_scene_spec (scene)->edge_blur_px;
  DsSamplingCheck check;
  g_assert_true (ds_separation_check_sampling (&sp, &check, NULL));
  double kept = isnan (check.affected_fraction) ? 1.0 : 1.0 - check.affected_fraction;
  g_test_message ("the sampling precondition keeps %.2f of the pixel positions", kept);
  g_assert_cmpfloat ((double) tc.valid, >, kept * (double) tc.pixels / 2);
  g_assert_true (truth_check_passed (&tc));

  JsonObject *meta = json_node_get_object (m->reply->body);
  g_assert_cmpint (test_json_int (m->reply->body, "settings.phases"), ==, 8);
  /* The latency's parts: instants of one clock in their order, and the durations their
   * differences. */
  const char *order[] = { "started", "last_frame", "last_frame_verify_started", "last_frame_verified",
                          "last_frame_folded", "finished" };
  gint64 at[G_N_ELEMENTS (order)];
  for (guint i = 0; i < G_N_ELEMENTS (order); i++) {
    g_autofree char *path = g_strdup_printf ("monotonic_us.%s", order[i]);
    at[i] = test_json_int (m->reply->body, path);
    g_assert_cmpint (at[i], >, 0);
    if (i > 0)
      g_assert_cmpint (at[i], >=, at[i - 1]);
  }
  JsonObject *timing = json_object_get_object_member (meta, "timing_ms");
  const char *parts[] = { "last_frame_wait", "last_frame_verify", "last_frame_fold" };
  for (guint i = 0; i < G_N_ELEMENTS (parts); i++)
    g_assert_cmpfloat_with_epsilon (json_object_get_double_member (timing, parts[i]), (at[i + 2] - at[i + 1]) / 1000.0, 1e-9);
  g_assert_cmpfloat_with_epsilon (json_object_get_double_member (timing, "compute_after_last_frame"),
                                  (at[5] - at[1]) / 1000.0, 1e-9);
  g_assert_true (json_object_get_boolean_member (json_object_get_object_member (meta, "separation"), "dark_subtracted"));
  g_autoptr (DsMessage) st = test_daemon_call_ok (c, "status", NULL);
  assert_accounting (st->reply->body);
  g_assert_cmpint (test_daemon_stop (d), ==, 0);
  test_daemon_free (d);
}

/* Continuous mode with two subscribers: the fast one sees every result in order, the slow one
 * (which does not read at all for a while) loses results, counted by the daemon, and sees
 * whole results with gaps in seq when it reads again; acquisition goes on meanwhile. */
static void
test_continuous_slow_subscriber (void)
{
  /* A queue cap of about two results: beyond the socket buffers, the slow client's results drop. */
  g_autofree char *conf = config_text ("[daemon]\nmax-queued-bytes=1048576\n[acquisition]\nphases=4\n");
  g_autofree char *conf2 = g_strdup_printf ("%s", conf);
  TestDaemon *d = test_daemon_start (conf2, NULL);
  g_autoptr (DsClient) fast = test_daemon_connect (d);
  g_autoptr (DsClient) slow = test_daemon_connect (d);
  g_autoptr (DsClient) ctl = test_daemon_connect (d);
  g_autoptr (DsMessage) s1 = test_daemon_call_ok (fast, "subscribe", NULL);
  g_autoptr (DsMessage) s2 = test_daemon_call_ok (slow, "subscribe", NULL);
  g_autoptr (DsMessage) started = test_daemon_call_ok (ctl, "start", NULL);
  guint64 last = 0;
  const guint wanted = 12;
  for (guint i = 0; i < wanted;) {
    g_autoptr (GError) error = NULL;
    g_autoptr (DsMessage) ev = ds_client_read (fast, 60000, &error);
    g_assert_no_error (error);
    if (g_strcmp0 (ev->reply->event, "result") != 0)
      continue;
    g_assert_cmpuint (ev->reply->seq, ==, last + 1);
    last = ev->reply->seq;
    g_assert_cmpuint (ev->reply->n_payloads, ==, 3);
    i++;
  }
  g_autoptr (DsMessage) stopped = test_daemon_call_ok (ctl, "stop", NULL);
  g_autoptr (DsMessage) st = test_daemon_call_ok (ctl, "status", NULL);
  g_assert_cmpint (test_json_int (st->reply->body, "sets_done"), >=, wanted);
  g_assert_cmpint (test_json_int (st->reply->body, "clients.results_dropped"), >, 0);
  assert_accounting (st->reply->body);
  /* The slow client now reads: whole results, seq increasing with at least one gap. */
  guint64 prev = 0;
  gboolean gap = FALSE;
  guint seen = 0;
  for (;;) {
    g_autoptr (GError) error = NULL;
    g_autoptr (DsMessage) ev = ds_client_read (slow, 2000, &error);
    if (!ev)
      break;
    if (g_strcmp0 (ev->reply->event, "result") != 0)
      continue;
    g_assert_cmpuint (ev->reply->n_payloads, ==, 3);
    g_assert_cmpuint (g_bytes_get_size (ev->payloads[0]), ==, ev->reply->payloads[0].bytes);
    if (prev && ev->reply->seq > prev + 1)
      gap = TRUE;
    g_assert_cmpuint (ev->reply->seq, >, prev);
    prev = ev->reply->seq;
    seen++;
  }
  g_assert_true (gap || seen < last);
  g_assert_cmpint (test_daemon_stop (d), ==, 0);
  test_daemon_free (d);
}

/* Bad requests get clear errors and the connection stays usable. */
static void
test_bad_requests (void)
{
  g_autofree char *conf = config_text (NULL);
  TestDaemon *d = test_daemon_start (conf, NULL);
  g_autoptr (DsClient) c = test_daemon_connect (d);
  struct {
    const char *cmd;
    const char *json_args;
    DsProtocolError code;
    const char *says;
  } cases[] = {
    { "capture", "{\"phases\": 1}", DS_PROTOCOL_ERROR_BAD_ARGUMENT, "phases" },
    { "capture", "{\"phases\": 2, \"estimator\": \"sine\"}", DS_PROTOCOL_ERROR_BAD_ARGUMENT, "3" },
    { "capture", "{\"exposure_us\": -5}", DS_PROTOCOL_ERROR_BAD_ARGUMENT, "exposure_us" },
    { "capture", "{\"outputs\": [\"nope\"]}", DS_PROTOCOL_ERROR_BAD_ARGUMENT, "outputs" },
    { "capture", "{\"path\": \"/etc/passwd\"}", DS_PROTOCOL_ERROR_BAD_ARGUMENT, "path" },
    { "selfdestruct", "{}", DS_PROTOCOL_ERROR_UNKNOWN_COMMAND, "selfdestruct" },
    /* The list comes from the server's and the service's dispatch tables: every command. */
    { "selfdestruct", "{}", DS_PROTOCOL_ERROR_UNKNOWN_COMMAND,
      "(commands: hello, subscribe, unsubscribe, status, capture, dark, start, stop, config, release, acquire, "
      "calibrate, cancel, set, preview)" },
  };
  for (guint i = 0; i < G_N_ELEMENTS (cases); i++) {
    g_autoptr (JsonNode) node = json_from_string (cases[i].json_args, NULL);
    g_autoptr (GError) error = NULL;
    g_autoptr (DsMessage) m = ds_client_call (c, cases[i].cmd, json_node_get_object (node), NULL, NULL, &error);
    g_assert_no_error (error);
    g_assert_false (m->reply->ok);
    g_assert_cmpint (m->reply->error_code, ==, cases[i].code);
    g_assert_nonnull (strstr (m->reply->error_message, cases[i].says));
  }
  g_autoptr (DsMessage) ok = test_daemon_call_ok (c, "status", NULL);
  g_assert_cmpint (test_daemon_stop (d), ==, 0);
  test_daemon_free (d);
}

/* The daemon started with its standard error going to a file of the test's folder: what it
 * logs can be read back. The test's own standard error is restored at once. */
static TestDaemon *
start_logging_to (const char *conf, char **log_path)
{
  g_autofree char *dir = g_dir_make_tmp ("descatterd-log-XXXXXX", NULL);
  *log_path = g_build_filename (dir, "stderr.log", NULL);
  int log_fd = g_open (*log_path, O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0600);
  g_assert_cmpint (log_fd, >=, 0);
  int saved = dup (STDERR_FILENO);
  g_assert_cmpint (dup2 (log_fd, STDERR_FILENO), ==, STDERR_FILENO);
  TestDaemon *d = test_daemon_start (conf, NULL);
  g_assert_cmpint (dup2 (saved, STDERR_FILENO), ==, STDERR_FILENO);
  close (saved);
  close (log_fd);
  return d;
}

/* Waits until the log holds `text` (30 s at most: a bound for a hang, not a timing); returns
 * the log. */
static char *
wait_for_log (const char *log_path, const char *text)
{
  for (guint i = 0; i < 600; i++) {
    char *log = NULL;
    if (g_file_get_contents (log_path, &log, NULL, NULL) && strstr (log, text))
      return log;
    g_free (log);
    g_usleep (50000);
  }
  g_error ("descatterd did not log \"%s\" within 30 s", text);
  return NULL;
}

static char *
running_config_text (DsClient *c)
{
  g_autoptr (DsMessage) m = test_daemon_call_ok (c, "config", NULL);
  return g_strdup (json_object_get_string_member (json_node_get_object (m->reply->body), "text"));
}

/* SIGHUP: a bad file is refused and the running configuration kept; a good one applies. Each
 * check waits for the daemon's log line of that SIGHUP: the signal is handled on the daemon's
 * loop, which a loaded machine may run late. */
static void
test_reload (void)
{
  g_autofree char *conf = config_text ("[acquisition]\nphases=6\n");
  g_autofree char *log_path = NULL;
  TestDaemon *d = start_logging_to (conf, &log_path);
  g_autoptr (DsClient) c = test_daemon_connect (d);
  g_assert_true (g_file_set_contents (d->config_path, "[acquisition]\nphases=banana\n", -1, NULL));
  GPid pid = (GPid) g_ascii_strtoll (g_subprocess_get_identifier (d->proc), NULL, 10);
  kill (pid, SIGHUP);
  g_free (wait_for_log (log_path, "reload refused"));
  g_autofree char *kept = running_config_text (c);
  g_assert_nonnull (strstr (kept, "phases=6"));
  g_autofree char *good = config_text ("[acquisition]\nphases=10\n");
  g_assert_true (g_file_set_contents (d->config_path, good, -1, NULL));
  kill (pid, SIGHUP);
  g_free (wait_for_log (log_path, "configuration reloaded"));
  g_autofree char *applied = running_config_text (c);
  g_assert_nonnull (strstr (applied, "phases=10"));
  /* And a capture without arguments now uses 10 phases. */
  g_autoptr (DsMessage) cap = test_daemon_call_ok (c, "capture", NULL);
  g_assert_cmpint (test_json_int (cap->reply->body, "settings.phases"), ==, 10);
  g_assert_cmpint (test_daemon_stop (d), ==, 0);
  test_daemon_free (d);
  g_autofree char *log_dir = g_path_get_dirname (log_path);
  g_unlink (log_path);
  g_rmdir (log_dir);
}

/* SIGHUP follows the key table's reload rule: a file changing keys that take effect only at
 * start (the operating model, the timing of automatic captures, a device setting) is refused
 * with a log line naming them, and nothing of it applies, not even its live keys; a file
 * changing only capture defaults applies. */
static void
test_reload_rule (void)
{
  g_autofree char *conf = config_text ("[acquisition]\nphases=6\n");
  g_autofree char *log_path = NULL;
  TestDaemon *d = start_logging_to (conf, &log_path);
  g_autoptr (DsClient) c = test_daemon_connect (d);
  GPid pid = (GPid) g_ascii_strtoll (g_subprocess_get_identifier (d->proc), NULL, 10);
  /* Another operating model: a copy of the one in use, under another name (a model named in
   * the file must load, or the reload is refused for that). */
  g_autoptr (DsMessage) st = test_daemon_call_ok (c, "status", NULL);
  JsonObject *om = json_object_get_object_member (json_node_get_object (st->reply->body), "operating_model");
  g_autofree char *model_text = NULL;
  g_assert_true (g_file_get_contents (json_object_get_string_member (om, "path"), &model_text, NULL, NULL));
  g_autofree char *model = g_build_filename (d->dir, "model.conf", NULL);
  g_assert_true (g_file_set_contents (model, model_text, -1, NULL));
  g_autofree char *extra = g_strdup_printf ("[acquisition]\nphases=10\noperating-model=%s\nsettle-ms=7\n"
                                            "link-mbit=100\n", model);
  g_autofree char *restart = config_text (extra);
  g_assert_true (g_file_set_contents (d->config_path, restart, -1, NULL));
  kill (pid, SIGHUP);
  g_autofree char *log = wait_for_log (log_path, "reload refused");
  g_assert_nonnull (strstr (log, "[acquisition] operating-model, settle-ms, link-mbit"));
  g_assert_nonnull (strstr (log, "need a restart"));
  g_autofree char *kept = running_config_text (c);
  g_assert_nonnull (strstr (kept, "phases=6\n"));
  g_assert_nonnull (strstr (kept, "settle-ms=3\n"));

  g_autofree char *live = config_text ("[acquisition]\nphases=10\n[camera]\nexposure-us=3000\n");
  g_assert_true (g_file_set_contents (d->config_path, live, -1, NULL));
  kill (pid, SIGHUP);
  g_free (wait_for_log (log_path, "configuration reloaded"));
  g_autofree char *applied = running_config_text (c);
  g_assert_nonnull (strstr (applied, "phases=10\n"));
  g_assert_nonnull (strstr (applied, "exposure-us=3000\n"));
  g_assert_cmpint (test_daemon_stop (d), ==, 0);
  test_daemon_free (d);
  g_autofree char *log_dir = g_path_get_dirname (log_path);
  g_unlink (log_path);
  g_rmdir (log_dir);
}

/* SIGTERM in the middle of continuous acquisition: clean exit (status 0) and every set in the
 * spool is complete (sidecar + all images), with no temporary files left. */
static void
test_sigterm_mid_set_leaves_whole_files (void)
{
  g_autofree char *tmp = g_dir_make_tmp ("descatter-spool-XXXXXX", NULL);
  g_autofree char *spool = g_build_filename (tmp, "spool", NULL);
  g_autofree char *extra = g_strdup_printf ("[daemon]\nspool-dir=%s\n[acquisition]\nphases=8\n", spool);
  g_autofree char *conf = config_text (extra);
  TestDaemon *d = test_daemon_start (conf, NULL);
  g_autoptr (DsClient) c = test_daemon_connect (d);
  g_autoptr (DsMessage) sub = test_daemon_call_ok (c, "subscribe", NULL);
  g_autoptr (DsMessage) st = test_daemon_call_ok (c, "start", NULL);
  /* Wait for two results, then stop while the third set is being acquired. */
  for (guint got = 0; got < 2;) {
    g_autoptr (DsMessage) ev = ds_client_read (c, 60000, NULL);
    g_assert_nonnull (ev);
    if (g_strcmp0 (ev->reply->event, "result") == 0)
      got++;
  }
  g_usleep (20000);
  g_assert_cmpint (test_daemon_stop (d), ==, 0);
  g_autoptr (GDir) dir = g_dir_open (spool, 0, NULL);
  g_assert_nonnull (dir);
  const char *name;
  guint sidecars = 0, files = 0;
  while ((name = g_dir_read_name (dir))) {
    files++;
    g_assert_false (g_str_has_prefix (name, "."));  /* no temporary file left */
    if (!g_str_has_suffix (name, ".json"))
      continue;
    sidecars++;
    g_autofree char *stem = g_strndup (name, strlen (name) - 5);
    const char *parts[] = { "-transmissive.tiff", "-scattered.tiff", "-mask.png" };
    for (guint i = 0; i < G_N_ELEMENTS (parts); i++) {
      g_autofree char *p = g_strdup_printf ("%s/%s%s", spool, stem, parts[i]);
      g_assert_true (g_file_test (p, G_FILE_TEST_EXISTS));
    }
  }
  g_assert_cmpuint (sidecars, >=, 2);
  g_assert_cmpuint (files, ==, 4 * sidecars); /* nothing without its sidecar */
  test_daemon_free (d);
  g_autofree char *cmd = g_strdup_printf ("rm -rf '%s'", tmp);
  g_assert_cmpint (system (cmd), ==, 0);
}

/* Automatic operating point: a capture asking for a target error picks its own estimator, N, M
 * and exposure from its pilot frames (docs/accuracy.md); the error it achieves against the
 * simulator's truth is within a factor 1.5 of the error it predicted, or, where the prediction
 * says it is a lower bound (an illuminator that cannot change its period), not far below it. */
static void
test_automatic_operating_point (void)
{
  g_autoptr (GError) error = NULL;
  g_autoptr (DsScene) scene = ds_scene_load (SCENE_FILE, &error);
  g_assert_no_error (error);
  g_autofree char *conf = config_text (NULL);
  TestDaemon *d = test_daemon_start (conf, NULL);
  g_autoptr (DsClient) c = test_daemon_connect (d);
  g_autoptr (JsonObject) args = json_object_new ();
  json_object_set_double_member (args, "target_error", 0.05);
  json_object_set_double_member (args, "exposure_us", ds_scene_default_exposure_us (scene));
  g_autoptr (DsMessage) m = test_daemon_call_ok (c, "capture", args);
  JsonObject *settings = json_object_get_object_member (json_node_get_object (m->reply->body), "settings");
  JsonObject *op = json_object_get_object_member (settings, "operating_point");
  g_assert_nonnull (op);
  double predicted = json_object_get_double_member (op, "predicted_error");
  double exposure = json_object_get_double_member (settings, "exposure_us");
  g_assert_cmpfloat (predicted, <=, 0.05);
  g_autoptr (DsRenderer) r = ds_renderer_new (scene, NULL, &error);
  g_assert_no_error (error);
  DsImage *tt = NULL, *tg = NULL;
  g_assert_true (ds_renderer_truth (r, exposure, 0.0, &tt, &tg, &error));
  g_autoptr (DsImage) truth_t = tt;
  g_autoptr (DsImage) truth_g = tg;
  /* Relative RMSE of transmissive over the valid pixels, as the study defines it. */
  const float *t = NULL;
  const guint8 *mask = NULL;
  for (guint i = 0; i < m->reply->n_payloads; i++) {
    if (strcmp (m->reply->payloads[i].name, "transmissive") == 0)
      t = g_bytes_get_data (m->payloads[i], NULL);
    if (strcmp (m->reply->payloads[i].name, "mask") == 0)
      mask = g_bytes_get_data (m->payloads[i], NULL);
  }
  g_assert_nonnull (t);
  g_assert_nonnull (mask);
  double se = 0, st = 0;
  guint w = truth_t->width;
  for (guint y = 0; y < truth_t->height; y++) {
    const float *tr = ds_image_row (truth_t, y);
    for (guint x = 0; x < w; x++) {
      if (mask[(gsize) y * w + x] & 0x29) /* saturated, non-finite, dark exceeds: as the study */
        continue;
      double e = t[(gsize) y * w + x] - tr[x];
      se += e * e;
      st += (double) tr[x] * tr[x];
    }
  }
  double achieved = sqrt (se / st);
  gboolean lower_bound = json_object_get_boolean_member (op, "lower_bound");
  g_test_message ("automatic: %s N=%" G_GINT64_FORMAT " M=%" G_GINT64_FORMAT ", predicted %.4f%s, achieved %.4f",
                  json_object_get_string_member (settings, "estimator"),
                  json_object_get_int_member (settings, "phases"), json_object_get_int_member (settings, "averages"),
                  predicted, lower_bound ? " (lower bound)" : "", achieved);
  g_assert_cmpfloat (achieved, >=, predicted / 1.5);
  if (!lower_bound)
    g_assert_cmpfloat (achieved, <=, 1.5 * predicted);
  else
    g_assert_cmpuint (json_array_get_length (json_object_get_array_member (op, "lower_bound_reasons")), >, 0);
  g_assert_cmpint (test_daemon_stop (d), ==, 0);
  test_daemon_free (d);
}

/* A featureless milky medium (no objects) with an illuminator of black level 0: its scattered
 * light raises the off-stripe level. descatterd --sim knows the simulated illuminator as a
 * calibration would, so the pilot's pattern check takes the excess over that calibrated black
 * level as scattered light, and the result's operating_point.assumptions says so
 * (daemon/operating/pattern_check.h). */
static void
test_automatic_assumption_in_result (void)
{
  g_autofree char *dir = g_dir_make_tmp ("featureless-XXXXXX", NULL);
  g_autofree char *scene_path = g_build_filename (dir, "featureless.scene", NULL);
  const char *scene_text = "[scene]\nname=featureless\n"
                           "[sensor]\nwidth=128\nheight=64\nbit-depth=12\npixel-pitch-um=5\n"
                           "quantum-efficiency=0.4\nsystem-gain=0.25\nread-noise-e=6\ndark-current-e-per-s=20\n"
                           "full-well-e=20000\nexposure-us=5000\n"
                           "[illuminator]\npattern=square\nperiod-px=12\nduty=0.5\nirradiance=0.5\n"
                           "[medium]\nthickness-mm=10\nmua=0.002\nmus=0.3\ng=0.7\nn=1.33\nmodel=monte-carlo\n"
                           "photons=200000\n"
                           "[camera]\nmagnification=0.05\nacceptance-half-angle-deg=10\n";
  g_assert_true (g_file_set_contents (scene_path, scene_text, -1, NULL));
  g_autofree char *conf = g_strdup_printf ("[camera]\nbackend=sim\n[illuminator]\nbackend=sim\n"
                                           "[sim]\nscene=%s\nseed=7\n", scene_path);
  TestDaemon *d = test_daemon_start (conf, NULL);
  g_autoptr (DsClient) c = test_daemon_connect (d);
  g_autoptr (JsonObject) args = json_object_new ();
  json_object_set_double_member (args, "target_error", 0.2);
  g_autoptr (DsMessage) m = test_daemon_call_ok (c, "capture", args);
  JsonObject *settings = json_object_get_object_member (json_node_get_object (m->reply->body), "settings");
  JsonObject *op = json_object_get_object_member (settings, "operating_point");
  g_assert_nonnull (op);
  JsonArray *assumed = json_object_get_array_member (op, "assumptions");
  gboolean named = FALSE;
  for (guint i = 0; i < json_array_get_length (assumed); i++) {
    const char *a = json_array_get_string_element (assumed, i);
    g_test_message ("assumption: %s", a);
    named |= strstr (a, "taken as scattered light") != NULL && strstr (a, "calibrated black level is 0.00") != NULL;
  }
  g_assert_true (named);
  g_assert_cmpint (test_daemon_stop (d), ==, 0);
  test_daemon_free (d);
  g_unlink (scene_path);
  g_rmdir (dir);
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  g_test_add_func ("/daemon-sim/capture-matches-truth", test_capture_matches_truth);
  g_test_add_func ("/daemon-sim/continuous-slow-subscriber", test_continuous_slow_subscriber);
  g_test_add_func ("/daemon-sim/bad-requests", test_bad_requests);
  g_test_add_func ("/daemon-sim/reload", test_reload);
  g_test_add_func ("/daemon-sim/reload-rule", test_reload_rule);
  g_test_add_func ("/daemon-sim/sigterm-mid-set", test_sigterm_mid_set_leaves_whole_files);
  g_test_add_func ("/daemon-sim/automatic-operating-point", test_automatic_operating_point);
  g_test_add_func ("/daemon-sim/automatic-assumption-in-result", test_automatic_assumption_in_result);
  return g_test_run ();
}
