/* Per-frame results (continuous mode `results = per-frame`, docs/protocol.md) on a real daemon
 * with the in-process simulated lab.
 *
 * - equals-fresh-set: each per-frame result equals, bit for bit, a fresh proc/ phase set fed
 *   the result's own N frames (save_phases: the window's frames and dark frame come with the
 *   result) in the order the camera delivered them; the frames are the N consecutive frames
 *   ending with the result's newest_frame_id, and the results' newest frame ids are
 *   consecutive.
 * - lost-frame / refused-frame: a frame lost in transit ([sim] faults drop-next) or one showing
 *   the previous phase (stale-next, refused by the phase check) breaks the window: the next
 *   result comes only N good frames after the bad one, says so (window.since_break = N, the
 *   reason in window.last_break), and a window_broken event names the reason. The frame
 *   accounting stays exact (acquired = folded + dropped).
 * - spread-losses: a camera losing every 4th frame at N = 4 (drop-every) never gives N good
 *   frames in a row, so no result comes; but each phase's lost frame is retaken at once and
 *   comes (the loss moves back one phase each time), so no phase fails twice in a row, and the
 *   run goes on past twice phase-retries + 1 losses, each a window_broken naming its phase, as
 *   sets get through such a camera (retries per phase, docs/design.md, "The pipeline").
 * - phase-retries-exhausted: phase-retries + 1 losses of one phase in a row (drop-next) end the
 *   run as they end a set: a failed event naming the phase, counted in sets_failed.
 * - set-breaks: `set` exposure breaks the window (reason settings); the next result has the new
 *   exposure and comes N frames later.
 * - averages-refused: per-frame results with M > 1 are refused as bad_argument. */
#include <string.h>

#include "tests/common/daemon_harness.h"
#include "proc/image.h"
#include "proc/separation.h"

#define N_PHASES 4

static TestDaemon *
start_daemon (const char *faults)
{
  g_autofree char *conf = g_strdup_printf (
      "[camera]\nbackend=sim\ngrab-timeout-ms=50\n[illuminator]\nbackend=sim\nsettle-timeout-ms=50\n"
      "[acquisition]\nphases=%d\nphase-retries=3\n[sim]\nscene=%s\nseed=7\n%s%s\n",
      N_PHASES, SCENE_FILE, faults ? "faults=" : "", faults ? faults : "");
  return test_daemon_start (conf, NULL);
}

static void
start_per_frame (DsClient *c, gboolean dark, gboolean save_phases)
{
  g_autoptr (JsonObject) args = json_object_new ();
  json_object_set_int_member (args, "phases", N_PHASES);
  json_object_set_boolean_member (args, "dark_frame", dark);
  json_object_set_boolean_member (args, "save_phases", save_phases);
  json_object_set_string_member (args, "results", "per-frame");
  g_autoptr (DsMessage) m = test_daemon_call_ok (c, "start", args);
  g_assert_cmpstr (json_object_get_string_member (json_node_get_object (m->reply->body), "results"), ==,
                   "per-frame");
}

/* The next event of kind `kind` (others are logged; a failed set fails the test). */
static DsMessage *
next_event (DsClient *sub, const char *kind)
{
  for (;;) {
    g_autoptr (GError) error = NULL;
    /* The ctest timeout is the clock: results come at the camera's rate. */
    DsMessage *ev = ds_client_read (sub, 0, &error);
    g_assert_no_error (error);
    if (g_strcmp0 (ev->reply->event, kind) == 0)
      return ev;
    g_test_message ("event %s", ev->reply->event);
    if (g_strcmp0 (ev->reply->event, "failed") == 0)
      g_error ("failed: %s", json_object_get_string_member (json_node_get_object (ev->reply->body), "reason"));
    ds_message_free (ev);
  }
}

static guint
payload_index (const DsMessage *m, const char *name)
{
  for (guint i = 0; i < m->reply->n_payloads; i++)
    if (strcmp (m->reply->payloads[i].name, name) == 0)
      return i;
  g_error ("no payload %s", name);
}

static DsImage *
payload_image (const DsMessage *m, const char *name, guint bit_depth)
{
  guint i = payload_index (m, name);
  const DsPayloadInfo *info = &m->reply->payloads[i];
  DsSampleType type = strcmp (info->dtype, "u8") == 0 ? DS_SAMPLE_U8 : DS_SAMPLE_U16;
  gsize size = 0;
  const void *data = g_bytes_get_data (m->payloads[i], &size);
  g_autoptr (GError) error = NULL;
  DsImage *view = ds_image_new_view (type, bit_depth, info->width, info->height,
                                     (gsize) info->width * ds_sample_size (type), data, size, &error);
  g_assert_no_error (error);
  return view;
}

/* The separation parameters written from the result's own settings, as a client would: the
 * estimator, pattern and period it says it used. */
static void
params_of (JsonNode *meta, DsSeparationParams *p)
{
  JsonObject *s = json_object_get_object_member (json_node_get_object (meta), "settings");
  ds_separation_params_init (p, (guint) json_object_get_int_member (s, "phases"));
  g_assert_true (ds_estimator_from_name (json_object_get_string_member (s, "estimator"), &p->estimator));
  p->pattern = strcmp (json_object_get_string_member (s, "pattern"), "sine") == 0 ? DS_PATTERN_SINE
                                                                                  : DS_PATTERN_SQUARE;
  p->duty = json_object_get_double_member (s, "duty");
  p->black_level = json_object_get_double_member (s, "black_level");
  p->geometry.period_px = json_object_get_double_member (s, "period_px");
  p->geometry.pixel_aperture = 1;
  p->detect_motion = json_object_get_boolean_member_with_default (s, "detect_motion", FALSE);
}

/* A fresh phase set over the result's frames; its planes must equal the result's bit for bit. */
static void
check_against_fresh_set (const DsMessage *m)
{
  JsonNode *meta = m->reply->body;
  DsSeparationParams p;
  params_of (meta, &p);
  JsonObject *raw = json_object_get_object_member (json_node_get_object (meta), "raw_frames");
  JsonArray *frames = json_object_get_array_member (raw, "frames");
  g_assert_cmpuint (json_array_get_length (frames), ==, N_PHASES);
  gint64 newest = test_json_int (meta, "window.newest_frame_id");
  guint w = (guint) test_json_int (meta, "width"), h = (guint) test_json_int (meta, "height");
  g_autoptr (GError) error = NULL;
  g_autoptr (DsPhaseSet) set = ds_phase_set_new (&p, w, h, &error);
  g_assert_no_error (error);
  if (json_object_has_member (raw, "black_bit_depth")) {
    g_autoptr (DsImage) black = payload_image (m, "black", (guint) json_object_get_int_member (raw, "black_bit_depth"));
    g_assert_true (ds_phase_set_set_dark (set, black, &error));
  }
  for (guint i = 0; i < N_PHASES; i++) {
    JsonObject *f = json_array_get_object_element (frames, i);
    /* The window's frames are the N consecutive frames ending with the newest (ids wrap at
     * 65535 in the simulated camera: compared modulo). */
    gint64 id = json_object_get_int_member (f, "frame_id");
    g_assert_cmpint ((id + N_PHASES - 1 - i) % 65535, ==, newest % 65535);
    g_autoptr (DsImage) img = payload_image (m, json_object_get_string_member (f, "payload"),
                                             (guint) json_object_get_int_member (f, "bit_depth"));
    g_assert_true (ds_phase_set_accumulate (set, (guint) json_object_get_int_member (f, "phase"), img, &error));
    g_assert_no_error (error);
  }
  g_autoptr (DsSeparation) sep = ds_phase_set_finalize (set, &error);
  g_assert_no_error (error);
  const char *names[] = { "transmissive", "scattered", "mask" };
  const DsImage *planes[] = { sep->transmissive, sep->scattered, sep->mask };
  for (guint i = 0; i < G_N_ELEMENTS (names); i++) {
    g_autoptr (GBytes) expected = ds_image_to_packed_bytes (planes[i]);
    if (!g_bytes_equal (expected, m->payloads[payload_index (m, names[i])]))
      g_error ("result with newest frame %" G_GINT64_FORMAT ": %s differs from a fresh set over its frames", newest,
               names[i]);
  }
}

static void
test_equals_fresh_set (void)
{
  TestDaemon *d = start_daemon (NULL);
  g_autoptr (DsClient) sub = test_daemon_connect (d);
  g_autoptr (DsClient) c = test_daemon_connect (d);
  g_autoptr (DsMessage) s = test_daemon_call_ok (sub, "subscribe", NULL);
  start_per_frame (c, TRUE, TRUE);
  gint64 last = -1;
  guint results = 0;
  while (results < 3 * N_PHASES) {
    g_autoptr (DsMessage) m = next_event (sub, "result");
    g_assert_cmpint (test_json_int (m->reply->body, "window.frames"), ==, N_PHASES);
    g_assert_cmpint (test_json_int (m->reply->body, "window.span"), ==, N_PHASES);
    gint64 id = test_json_int (m->reply->body, "window.newest_frame_id");
    /* a result for every frame; a reader slower than the camera is told what it skipped */
    if (last >= 0)
      g_assert_cmpint (id % 65535, ==, (last + 1 + (gint64) m->reply->skipped) % 65535);
    last = id;
    check_against_fresh_set (m);
    results++;
  }
  g_autoptr (DsMessage) stop = test_daemon_call_ok (c, "stop", NULL);
  g_autoptr (DsMessage) st = test_daemon_call_ok (c, "status", NULL);
  TestFrames f = test_daemon_frames (c);
  g_assert_cmpint (f.dropped, ==, f.aborted); /* nothing refused on a still scene */
  g_assert_cmpint (test_json_int (st->reply->body, "frame_results"), >=, results);
  g_assert_cmpint (test_json_int (st->reply->body, "window.breaks"), ==, 0);
  test_daemon_stop_clean (d);
}

/* Frames from `from` to `to`: the simulated camera's ids wrap from 65535 to 1. */
static gint64
id_delta (gint64 from, gint64 to)
{
  return ((to - from) % 65535 + 65535) % 65535;
}

/* A bad frame after `faults-after` good ones (the fault's own -next count: one frame). */
static void
test_break (gconstpointer data)
{
  const char *const *k = data; /* faults, expected reason */
  TestDaemon *d = start_daemon (k[0]);
  g_autoptr (DsClient) sub = test_daemon_connect (d);
  g_autoptr (DsClient) c = test_daemon_connect (d);
  g_autoptr (DsMessage) s = test_daemon_call_ok (sub, "subscribe", NULL);
  start_per_frame (c, FALSE, FALSE);
  gint64 last = -1;
  gboolean broken = FALSE, after = FALSE;
  while (!after) {
    g_autoptr (GError) error = NULL;
    g_autoptr (DsMessage) ev = ds_client_read (sub, 0, &error);
    g_assert_no_error (error);
    JsonNode *body = ev->reply->body;
    if (g_strcmp0 (ev->reply->event, "window_broken") == 0) {
      g_test_message ("window_broken: %s", json_object_get_string_member (json_node_get_object (body), "message"));
      g_assert_cmpstr (json_object_get_string_member (json_node_get_object (body), "reason"), ==, k[1]);
      g_assert_false (broken);
      broken = TRUE;
      continue;
    }
    if (g_strcmp0 (ev->reply->event, "failed") == 0)
      g_error ("failed: %s", json_object_get_string_member (json_node_get_object (body), "reason"));
    if (g_strcmp0 (ev->reply->event, "result") != 0)
      continue;
    gint64 id = test_json_int (body, "window.newest_frame_id");
    if (!broken) {
      /* Before the fault: one result per frame, consecutive. */
      if (last >= 0)
        g_assert_cmpint (id_delta (last, id), ==, 1 + (gint64) ev->reply->skipped);
      g_assert_cmpint (test_json_int (body, "window.breaks"), ==, 0);
      last = id;
      continue;
    }
    /* The first result after the break: N good frames after the bad one (lost: its id never
     * came; refused: it came and was dropped), so no result holds a frame from before it. */
    g_test_message ("last result before the break: frame %" G_GINT64_FORMAT ", first after: %" G_GINT64_FORMAT,
                    last, id);
    g_assert_cmpint (last, >=, 0);
    g_assert_cmpint (id_delta (last, id), ==, N_PHASES + 1 + (gint64) ev->reply->skipped);
    g_assert_cmpint (test_json_int (body, "window.since_break"), ==, N_PHASES);
    g_assert_cmpint (test_json_int (body, "window.breaks"), ==, 1);
    g_assert_cmpstr (json_object_get_string_member (json_object_get_object_member (json_node_get_object (body),
                                                                                   "window"), "last_break"), ==, k[1]);
    after = TRUE;
  }
  g_autoptr (DsMessage) stop = test_daemon_call_ok (c, "stop", NULL);
  g_autoptr (DsMessage) st = test_daemon_call_ok (c, "status", NULL);
  g_assert_cmpint (test_json_int (st->reply->body, "window.breaks"), ==, 1);
  TestFrames f = test_daemon_frames (c); /* asserts acquired = folded + dropped */
  if (strcmp (k[1], "wrong_phase") == 0)
    g_assert_cmpint (f.wrong_phase, ==, 1);
  else
    g_assert_cmpint (f.timeouts, ==, 1);
  test_daemon_stop_clean (d);
}

/* The phase a window_broken event's message names ("lost: phase K: camera: ..."). */
static gint64
broken_phase (JsonNode *body)
{
  const char *msg = json_object_get_string_member (json_node_get_object (body), "message");
  const char *p = strstr (msg, "phase ");
  g_assert_nonnull (p);
  return g_ascii_strtoll (p + strlen ("phase "), NULL, 10);
}

static void
test_spread_losses (void)
{
  /* phase-retries=3 (start_daemon): a shared budget would end the run at the 4th loss. */
  TestDaemon *d = start_daemon ("faults-after=13,drop-every=4");
  g_autoptr (DsClient) sub = test_daemon_connect (d);
  g_autoptr (DsClient) c = test_daemon_connect (d);
  g_autoptr (DsMessage) s = test_daemon_call_ok (sub, "subscribe", NULL);
  start_per_frame (c, FALSE, FALSE);
  guint breaks = 0, results_after = 0;
  gint64 last_phase = -1;
  while (breaks < 2 * (3 + 1) + 1) {
    g_autoptr (GError) error = NULL;
    g_autoptr (DsMessage) ev = ds_client_read (sub, 0, &error);
    g_assert_no_error (error);
    JsonNode *body = ev->reply->body;
    if (g_strcmp0 (ev->reply->event, "failed") == 0)
      g_error ("failed: %s", json_object_get_string_member (json_node_get_object (body), "reason"));
    if (g_strcmp0 (ev->reply->event, "result") == 0 && breaks > 0)
      results_after++;
    if (g_strcmp0 (ev->reply->event, "window_broken") != 0)
      continue;
    g_assert_cmpstr (json_object_get_string_member (json_node_get_object (body), "reason"), ==, "lost");
    gint64 phase = broken_phase (body);
    g_test_message ("loss %u: phase %" G_GINT64_FORMAT, breaks + 1, phase);
    /* Three good frames, then the fourth trigger is lost: one phase before the last loss's. */
    if (last_phase >= 0)
      g_assert_cmpint (phase, ==, (last_phase + N_PHASES - 1) % N_PHASES);
    last_phase = phase;
    breaks++;
  }
  /* Never N good frames in a row after the first loss. */
  g_assert_cmpuint (results_after, ==, 0);
  g_autoptr (DsMessage) st = test_daemon_call_ok (c, "status", NULL);
  g_assert_true (json_object_get_boolean_member (json_node_get_object (st->reply->body), "continuous"));
  g_assert_cmpint (test_json_int (st->reply->body, "sets_failed"), ==, 0);
  g_autoptr (DsMessage) stop = test_daemon_call_ok (c, "stop", NULL);
  /* The window's frames are counted in status when the run returns for the command. */
  for (;;) {
    g_autoptr (DsMessage) now = test_daemon_call_ok (c, "status", NULL);
    if (strcmp (json_object_get_string_member (json_node_get_object (now->reply->body), "state"), "idle") == 0)
      break;
    g_usleep (20 * 1000);
  }
  TestFrames f = test_daemon_frames (c); /* asserts acquired = folded + dropped */
  g_assert_cmpint (f.timeouts, >=, breaks);
  test_daemon_stop_clean (d);
}

static void
test_retries_exhausted (void)
{
  /* The 14th trigger is phase 1's (main); it and its three retakes are lost. */
  TestDaemon *d = start_daemon ("faults-after=13,drop-next=4");
  g_autoptr (DsClient) sub = test_daemon_connect (d);
  g_autoptr (DsClient) c = test_daemon_connect (d);
  g_autoptr (DsMessage) s = test_daemon_call_ok (sub, "subscribe", NULL);
  start_per_frame (c, FALSE, FALSE);
  guint breaks = 0;
  for (;;) {
    g_autoptr (GError) error = NULL;
    g_autoptr (DsMessage) ev = ds_client_read (sub, 0, &error);
    g_assert_no_error (error);
    JsonNode *body = ev->reply->body;
    if (g_strcmp0 (ev->reply->event, "window_broken") == 0) {
      g_assert_cmpint (broken_phase (body), ==, 1);
      breaks++;
      continue;
    }
    if (g_strcmp0 (ev->reply->event, "failed") != 0)
      continue;
    const char *reason = json_object_get_string_member (json_node_get_object (body), "reason");
    g_test_message ("failed: %s", reason);
    g_assert_true (g_str_has_prefix (reason, "per-frame results: retries exhausted: phase 1: camera: "));
    break;
  }
  /* phase-retries = 3 retakes, each a break, and the 4th loss ends the run. */
  g_assert_cmpuint (breaks, ==, 4);
  g_autoptr (DsMessage) st = test_daemon_call_ok (c, "status", NULL);
  g_assert_cmpint (test_json_int (st->reply->body, "sets_failed"), ==, 1);
  g_autoptr (DsMessage) stop = test_daemon_call_ok (c, "stop", NULL);
  test_daemon_stop_clean (d);
}

/* `set` changes the exposure between two frames: the window breaks ("settings"), and the next
 * result, N frames after it, has the new exposure. */
static void
test_set_breaks (void)
{
  TestDaemon *d = start_daemon (NULL);
  g_autoptr (DsClient) sub = test_daemon_connect (d);
  g_autoptr (DsClient) c = test_daemon_connect (d);
  g_autoptr (DsMessage) s = test_daemon_call_ok (sub, "subscribe", NULL);
  start_per_frame (c, FALSE, FALSE);
  g_autoptr (DsMessage) first = next_event (sub, "result");
  double exposure = json_object_get_double_member (
      json_object_get_object_member (json_node_get_object (first->reply->body), "settings"), "exposure_us");
  g_autoptr (JsonObject) args = json_object_new ();
  json_object_set_double_member (args, "exposure_us", exposure / 2);
  g_autoptr (DsMessage) set = test_daemon_call_ok (c, "set", args);
  g_autoptr (DsMessage) broken = next_event (sub, "window_broken");
  g_assert_cmpstr (json_object_get_string_member (json_node_get_object (broken->reply->body), "reason"), ==,
                   "settings");
  g_autoptr (DsMessage) after = next_event (sub, "result");
  JsonObject *settings = json_object_get_object_member (json_node_get_object (after->reply->body), "settings");
  g_assert_cmpfloat (json_object_get_double_member (settings, "exposure_us"), ==, exposure / 2);
  g_assert_cmpint (test_json_int (after->reply->body, "window.since_break"), ==, N_PHASES);
  g_assert_cmpstr (json_object_get_string_member (json_object_get_object_member (
                       json_node_get_object (after->reply->body), "window"), "last_break"), ==, "settings");
  g_autoptr (DsMessage) stop = test_daemon_call_ok (c, "stop", NULL);
  test_daemon_frames (c);
  test_daemon_stop_clean (d);
}

static void
test_averages_refused (void)
{
  TestDaemon *d = start_daemon (NULL);
  g_autoptr (DsClient) c = test_daemon_connect (d);
  g_autoptr (JsonObject) args = json_object_new ();
  json_object_set_int_member (args, "averages", 2);
  json_object_set_string_member (args, "results", "per-frame");
  g_autoptr (GError) error = NULL;
  g_autoptr (DsMessage) m = ds_client_call (c, "start", args, NULL, NULL, &error);
  g_assert_no_error (error);
  g_assert_false (m->reply->ok);
  g_assert_cmpint (m->reply->error_code, ==, DS_PROTOCOL_ERROR_BAD_ARGUMENT);
  g_assert_nonnull (strstr (m->reply->error_message, "averages"));
  g_autoptr (DsMessage) st = test_daemon_call_ok (c, "status", NULL);
  g_assert_false (json_object_get_boolean_member (json_node_get_object (st->reply->body), "continuous"));
  test_daemon_stop_clean (d);
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  /* The 14th trigger (phase 1 of the fourth cycle: the first cycles confirmed the templates). */
  static const char *const lost[] = { "faults-after=13,drop-next=1", "lost" };
  static const char *const refused[] = { "faults-after=13,stale-next=1", "wrong_phase" };
  g_test_add_func ("/window-stream/equals-fresh-set", test_equals_fresh_set);
  g_test_add_data_func ("/window-stream/lost-frame", lost, test_break);
  g_test_add_data_func ("/window-stream/refused-frame", refused, test_break);
  g_test_add_func ("/window-stream/spread-losses", test_spread_losses);
  g_test_add_func ("/window-stream/phase-retries-exhausted", test_retries_exhausted);
  g_test_add_func ("/window-stream/set-breaks", test_set_breaks);
  g_test_add_func ("/window-stream/averages-refused", test_averages_refused);
  return g_test_run ();
}
