/* descatterd's single-frame estimator end to end on the in-process simulated lab: a capture
 * with `single_frame` and continuous mode with `[acquisition] single-frame`, checked against
 * the simulator's noise-free truth smoothed over the window the result says it used, and the
 * refusals. The independent expectation is the renderer's truth; the window comes from the
 * scene's stripe period (ceil(P) columns), not from the daemon. */
#include "tests/common/config_groups.h"
#include <math.h>
#include <string.h>

#include "tests/common/daemon_harness.h"
#include "tests/common/truth_check.h"
#include "drivers/sim/renderer.h"
#include "drivers/sim/scene.h"

static char *
config_text (const char *extra)
{
  g_autofree char *joined = g_strdup_printf ("[camera]\nbackend=sim\n[illuminator]\nbackend=sim\n"
                                             "[sim]\nscene=%s\nseed=7\n%s",
                                             SCENE_FILE, extra ? extra : "");
  return test_config_groups_merge (joined);
}

static const char *
json_string (JsonNode *node, const char *path)
{
  g_auto (GStrv) parts = g_strsplit (path, ".", -1);
  for (guint i = 0; parts[i]; i++) {
    g_assert_true (JSON_NODE_HOLDS_OBJECT (node));
    node = json_object_get_member (json_node_get_object (node), parts[i]);
    g_assert_nonnull (node);
  }
  return json_node_get_string (node);
}

/* The result's settings state the single-frame window: ceil(P) columns along x of the scene's
 * period, the estimator named; the separation's phases are the window's samples. */
static void
assert_window_stated (JsonNode *body, const DsScene *scene, const char *estimator, gint64 dark_frames)
{
  guint window = (guint) ceil (ds_scene_period_px (scene) - 1e-9);
  g_assert_cmpint (test_json_int (body, "settings.single_frame.window_px"), ==, window);
  g_assert_cmpstr (json_string (body, "settings.single_frame.window_axis"), ==, "x");
  g_assert_cmpstr (json_string (body, "settings.single_frame.estimator"), ==, estimator);
  g_assert_cmpint (test_json_int (body, "separation.phases"), ==, window);
  /* one frame lit, and the dark frame's when one is taken: nothing else went into it */
  g_assert_cmpint (test_json_int (body, "frames.folded"), ==, 1 + dark_frames);
}

/* maxmin over one frame's window against the truth. Each pixel's window is the ceil(P)
 * columns around it (clamped at the sides), so the expectation is the truth averaged over
 * them, and the resolution the window costs is the truth's range over them: where the scene
 * is uniform across the window (most of it) the single frame must equal the truth within the
 * noise, as a phase set of ceil(P) phases would; across an edge it may be anywhere in the
 * range. Noise (photon transfer, var = K S + sr^2): max and min are order statistics of ceil(P)/2
 * lit and unlit samples, biased by at most E[max of 3 normals] = 0.85 sigma each for the
 * scene's P = 6, so Ld = (max - min)/(1 - b) errs below 3 sigma and Lg = (min - b Ld)/m below
 * 6 sigma, as for a phase set (tests/common/truth_check.c); plus 2 % of the signal for the
 * stripes' blurred edges. Checked as RMS over the valid pixels. */
static void
check_against_truth (const DsMessage *m, const DsScene *scene, const DsImage *truth_t, const DsImage *truth_g,
                     guint window)
{
  guint w = truth_t->width, h = truth_t->height;
  const float *t = truth_payload (m, "transmissive", "f32", w, h);
  const float *g = truth_payload (m, "scattered", "f32", w, h);
  const guint8 *mask = truth_payload (m, "mask", "u8", w, h);
  double K = ds_scene_system_gain (scene), sr = ds_scene_read_noise_dn (scene);
  double se_t = 0, se_g = 0, al_t = 0, al_g = 0, se_uniform = 0, al_uniform = 0;
  guint64 valid = 0, uniform = 0;
  for (guint y = 0; y < h; y++) {
    const float *tt = ds_image_row (truth_t, y), *tg = ds_image_row (truth_g, y);
    for (guint x = 0; x < w; x++) {
      gsize i = (gsize) y * w + x;
      if (mask[i] != 0)
        continue;
      guint s = x >= window / 2 ? x - window / 2 : 0;
      s = MIN (s, w - window);
      double mean_t = 0, mean_g = 0, lo_t = INFINITY, hi_t = -INFINITY, lo_g = INFINITY, hi_g = -INFINITY;
      double brightest = 0;
      for (guint j = s; j < s + window; j++) {
        mean_t += tt[j] / window;
        mean_g += tg[j] / window;
        lo_t = fmin (lo_t, tt[j]);
        hi_t = fmax (hi_t, tt[j]);
        lo_g = fmin (lo_g, tg[j]);
        hi_g = fmax (hi_g, tg[j]);
        brightest = fmax (brightest, tt[j] + tg[j]);
      }
      double sigma = sqrt (K * brightest + sr * sr);
      double et = t[i] - mean_t, eg = g[i] - mean_g;
      double allow_t = 3 * sigma + 0.02 * (mean_t + 0.5 * mean_g) + (hi_t - lo_t);
      double allow_g = 6 * sigma + 0.02 * (mean_g + mean_t) + (hi_g - lo_g) + (hi_t - lo_t);
      se_t += et * et;
      se_g += eg * eg;
      al_t += allow_t * allow_t;
      al_g += allow_g * allow_g;
      valid++;
      if (hi_t - lo_t <= 0.01 * mean_t + sigma) {
        double a = 3 * sigma + 0.02 * (mean_t + 0.5 * mean_g);
        se_uniform += et * et;
        al_uniform += a * a;
        uniform++;
      }
    }
  }
  g_assert_cmpuint (valid, >, (guint64) w * h / 2);
  g_assert_cmpuint (uniform, >, valid / 2);
  double rms_t = sqrt (se_t / valid), rms_g = sqrt (se_g / valid), rms_u = sqrt (se_uniform / uniform);
  g_test_message ("single frame against the truth over a %u-column window: transmissive rms %.2f DN (allowed %.2f), "
                  "scattered %.2f (allowed %.2f), uniform windows %.2f (allowed %.2f); %" G_GUINT64_FORMAT
                  " of %u pixels valid, %" G_GUINT64_FORMAT " with uniform windows",
                  window, rms_t, sqrt (al_t / valid), rms_g, sqrt (al_g / valid), rms_u, sqrt (al_uniform / uniform),
                  valid, w * h, uniform);
  g_assert_cmpfloat (rms_t, <=, sqrt (al_t / valid));
  g_assert_cmpfloat (rms_g, <=, sqrt (al_g / valid));
  g_assert_cmpfloat (rms_u, <=, sqrt (al_uniform / uniform));
}

typedef struct {
  DsScene *scene;
  DsImage *truth_t, *truth_g;
  double exposure;
  guint window;
} Fixture;

static void
fixture_load (Fixture *f)
{
  g_autoptr (GError) error = NULL;
  f->scene = ds_scene_load (SCENE_FILE, &error);
  g_assert_no_error (error);
  f->exposure = ds_scene_default_exposure_us (f->scene);
  g_autoptr (DsRenderer) r = ds_renderer_new (f->scene, NULL, &error);
  g_assert_no_error (error);
  g_assert_true (ds_renderer_truth (r, f->exposure, 0.0, &f->truth_t, &f->truth_g, &error));
  f->window = (guint) ceil (ds_scene_period_px (f->scene) - 1e-9);
}

static void
fixture_clear (Fixture *f)
{
  ds_scene_free (f->scene);
  ds_image_free (f->truth_t);
  ds_image_free (f->truth_g);
}

/* A capture with `single_frame`: one frame, the truth over the window, the window stated. */
static void
test_capture (void)
{
  Fixture f;
  fixture_load (&f);
  g_autofree char *conf = config_text (NULL);
  TestDaemon *d = test_daemon_start (conf, NULL);
  g_autoptr (DsClient) c = test_daemon_connect (d);
  g_autoptr (JsonObject) args = json_object_new ();
  json_object_set_boolean_member (args, "single_frame", TRUE);
  json_object_set_string_member (args, "estimator", "maxmin");
  json_object_set_boolean_member (args, "dark_frame", TRUE);
  json_object_set_double_member (args, "exposure_us", f.exposure);
  g_autoptr (DsMessage) m = test_daemon_call_ok (c, "capture", args);
  assert_window_stated (m->reply->body, f.scene, "maxmin", 1);
  JsonObject *sep = json_object_get_object_member (json_node_get_object (m->reply->body), "separation");
  g_assert_true (json_object_get_boolean_member (sep, "dark_subtracted"));
  check_against_truth (m, f.scene, f.truth_t, f.truth_g, f.window);
  g_autoptr (DsMessage) st = test_daemon_call_ok (c, "status", NULL);
  g_assert_cmpint (test_json_int (st->reply->body, "frames.acquired"), ==,
                   test_json_int (st->reply->body, "frames.folded") + test_json_int (st->reply->body, "frames.dropped"));
  g_assert_cmpint (test_daemon_stop (d), ==, 0);
  test_daemon_free (d);
  fixture_clear (&f);
}

/* Continuous mode from the configuration: every result is one frame, checked as a capture's. */
static void
test_continuous (void)
{
  Fixture f;
  fixture_load (&f);
  g_autofree char *extra = g_strdup_printf ("[acquisition]\nsingle-frame=true\nestimator=maxmin\ndark-frame=true\n"
                                            "[camera]\nexposure-us=%g\n",
                                            f.exposure);
  g_autofree char *conf = config_text (extra);
  TestDaemon *d = test_daemon_start (conf, NULL);
  g_autoptr (DsClient) c = test_daemon_connect (d);
  g_autoptr (DsClient) ctl = test_daemon_connect (d);
  g_autoptr (DsMessage) sub = test_daemon_call_ok (c, "subscribe", NULL);
  g_autoptr (DsMessage) started = test_daemon_call_ok (ctl, "start", NULL);
  for (guint n = 0; n < 3;) {
    g_autoptr (GError) error = NULL;
    g_autoptr (DsMessage) ev = ds_client_read (c, 60000, &error);
    g_assert_no_error (error);
    if (g_strcmp0 (ev->reply->event, "result") != 0)
      continue;
    assert_window_stated (ev->reply->body, f.scene, "maxmin", 1);
    check_against_truth (ev, f.scene, f.truth_t, f.truth_g, f.window);
    n++;
  }
  g_autoptr (DsMessage) stopped = test_daemon_call_ok (ctl, "stop", NULL);
  g_assert_cmpint (test_daemon_stop (d), ==, 0);
  test_daemon_free (d);
  fixture_clear (&f);
}

/* robust, and the automatic operating point, are refused with the reason; sine is taken and
 * names itself. */
static void
test_refusals_and_sine (void)
{
  Fixture f;
  fixture_load (&f);
  g_autofree char *conf = config_text (NULL);
  TestDaemon *d = test_daemon_start (conf, NULL);
  g_autoptr (DsClient) c = test_daemon_connect (d);
  struct {
    const char *json_args;
    const char *says;
  } cases[] = {
    { "{\"single_frame\": true, \"estimator\": \"robust\"}", "robust" },
    { "{\"single_frame\": true, \"target_error\": 0.05}", "target_error" },
    { "{\"single_frame\": 1}", "single_frame" },
  };
  for (guint i = 0; i < G_N_ELEMENTS (cases); i++) {
    g_autoptr (JsonNode) node = json_from_string (cases[i].json_args, NULL);
    g_autoptr (GError) error = NULL;
    g_autoptr (DsMessage) m = ds_client_call (c, "capture", json_node_get_object (node), NULL, NULL, &error);
    g_assert_no_error (error);
    g_assert_false (m->reply->ok);
    g_assert_cmpint (m->reply->error_code, ==, DS_PROTOCOL_ERROR_BAD_ARGUMENT);
    g_assert_nonnull (strstr (m->reply->error_message, cases[i].says));
  }
  g_autoptr (JsonObject) args = json_object_new ();
  json_object_set_boolean_member (args, "single_frame", TRUE);
  json_object_set_string_member (args, "estimator", "sine");
  json_object_set_boolean_member (args, "dark_frame", FALSE);
  g_autoptr (DsMessage) m = test_daemon_call_ok (c, "capture", args);
  assert_window_stated (m->reply->body, f.scene, "sine", 0);
  g_assert_cmpint (test_daemon_stop (d), ==, 0);
  test_daemon_free (d);
  fixture_clear (&f);
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  g_test_add_func ("/daemon-single-frame/capture", test_capture);
  g_test_add_func ("/daemon-single-frame/continuous", test_continuous);
  g_test_add_func ("/daemon-single-frame/refusals-and-sine", test_refusals_and_sine);
  return g_test_run ();
}
