/* `preview` end to end on the in-process simulated lab (docs/protocol.md, `preview`): a real
 * daemon process, one connection sending commands and another subscribed with frames; with
 * arguments (LABSIM SCENE) the same over GigE Vision and Modbus TCP against descatter-labsim.
 *
 * Each expectation is independent of the daemon's code:
 *   - no set: `sets_done` does not move and the spool folder stays empty (counts);
 *   - light phase K: the stripe phase of the frames, measured here with a DFT of the column
 *     profile at the scene's period, moves by K/N of a period from phase 0's (the simulator draws
 *     phase k shifted by kP/N: docs/registers.md, PHASE);
 *   - light off: the frames' mean is the dark level the `dark` command measures (another path:
 *     dark.c averages its own frames);
 *   - light all: every stripe lit. Light is linear in the illumination, and the N phases of
 *     square stripes with duty a (a N whole) light each point a N times in all, so the mean of
 *     the phases above the dark level is a times the all-on frame's;
 *   - off and cancel end it: state idle, the preview frame count stops. */
#include <glib/gstdio.h>
#include <math.h>
#include <string.h>

#include "tests/common/daemon_harness.h"
#include "tests/common/test_tree.h"

#define PHASES 4
#define PERIOD_PX 6.0  /* the scene's [illuminator] period-px */
#define DUTY 0.5       /* ... and duty; black level 0 */
#define FRAMES_AVERAGED 4

static guint
count_files (const char *dir_path)
{
  g_autoptr (GDir) dir = g_dir_open (dir_path, 0, NULL);
  guint n = 0;
  while (dir && g_dir_read_name (dir))
    n++;
  return n;
}

static JsonObject *
status_object (DsClient *c, DsMessage **keep)
{
  *keep = test_daemon_call_ok (c, "status", NULL);
  return json_node_get_object ((*keep)->reply->body);
}

static DsMessage *
preview (DsClient *c, const char *state, const char *light, gint phase)
{
  g_autoptr (JsonObject) args = json_object_new ();
  json_object_set_string_member (args, "state", state);
  if (light)
    json_object_set_string_member (args, "light", light);
  if (phase >= 0)
    json_object_set_int_member (args, "phase", phase);
  return test_daemon_call_ok (c, "preview", args);
}

/* What frames of one light tell: their mean and their stripe phase (cycles), averaged over
 * FRAMES_AVERAGED frames. */
typedef struct {
  double mean;
  double phase_cycles;
  double modulation; /* first harmonic amplitude / mean */
} FrameLook;

/* Reads `frame` events until FRAMES_AVERAGED of this light (and phase) came; other events and
 * frames of the light before are skipped. The column profile's DFT at the period over whole
 * periods: c = sum m(x) e^{-2 pi i x / P}, the stripes' centre at -arg(c) / 2 pi periods. */
static FrameLook
look (DsClient *sub, const char *light, gint phase)
{
  guint got = 0, skipped = 0;
  double sum = 0, re = 0, im = 0, dc = 0;
  while (got < FRAMES_AVERAGED) {
    g_autoptr (GError) error = NULL;
    g_autoptr (DsMessage) m = ds_client_read (sub, 30000, &error);
    g_assert_no_error (error);
    if (g_strcmp0 (m->reply->event, "frame") != 0)
      continue;
    JsonObject *b = json_node_get_object (m->reply->body);
    gboolean mine = strcmp (json_object_get_string_member (b, "light"), light) == 0 &&
                    (phase < 0 ? json_object_get_null_member (b, "phase")
                               : json_object_get_int_member (b, "phase") == phase);
    if (!mine) {
      g_assert_cmpuint (++skipped, <, 200);
      continue;
    }
    g_assert_cmpuint (m->reply->n_payloads, ==, 1);
    const DsPayloadInfo *pi = &m->reply->payloads[0];
    g_assert_cmpstr (pi->name, ==, "frame");
    g_assert_cmpstr (pi->dtype, ==, "u16");
    g_assert_cmpuint (json_object_get_int_member (b, "phases"), ==, PHASES);
    gsize len;
    const guint16 *px = g_bytes_get_data (m->payloads[0], &len);
    g_assert_cmpuint (len, ==, (gsize) pi->width * pi->height * 2);
    guint w = (guint) (floor (pi->width / PERIOD_PX) * PERIOD_PX);
    for (guint x = 0; x < w; x++) {
      double col = 0;
      for (guint y = 0; y < pi->height; y++)
        col += px[(gsize) y * pi->width + x];
      col /= pi->height;
      re += col * cos (2 * G_PI * x / PERIOD_PX);
      im -= col * sin (2 * G_PI * x / PERIOD_PX);
      dc += col;
    }
    double total = 0;
    for (gsize i = 0; i < (gsize) pi->width * pi->height; i++)
      total += px[i];
    sum += total / ((double) pi->width * pi->height);
    got++;
  }
  FrameLook l = { .mean = sum / got };
  l.phase_cycles = fmod (-atan2 (im, re) / (2 * G_PI) + 1.0, 1.0);
  l.modulation = 2 * hypot (re, im) / dc;
  return l;
}

static double
cycles_apart (double a, double b)
{
  double d = fmod (a - b + 10.5, 1.0) - 0.5;
  return d;
}

/* Every light on daemon d (phases = PHASES): frames to a frames subscriber, each light's frames
 * against the stripes and the dark level, no set counted, nothing in spool. */
static void
check_lights (TestDaemon *d, const char *spool)
{
  g_autoptr (DsClient) a = test_daemon_connect (d);
  g_autoptr (DsClient) sub = test_daemon_connect (d);
  g_autoptr (JsonObject) frames_on = json_object_new ();
  json_object_set_boolean_member (frames_on, "frames", TRUE);
  g_autoptr (DsMessage) s = test_daemon_call_ok (sub, "subscribe", frames_on);
  g_assert_true (json_object_get_boolean_member (json_node_get_object (s->reply->body), "frames"));
  g_autoptr (DsMessage) st0 = NULL;
  gint64 sets_before = json_object_get_int_member (status_object (a, &st0), "sets_done");

  /* Each phase: the reply, the state, and the stripes where phase k puts them. */
  FrameLook phase_look[PHASES];
  double phase_mean = 0;
  for (gint k = 0; k < PHASES; k++) {
    g_autoptr (DsMessage) r = preview (a, "on", "phase", k);
    JsonObject *ro = json_node_get_object (r->reply->body);
    g_assert_cmpstr (json_object_get_string_member (ro, "state"), ==, "preview");
    g_assert_cmpstr (json_object_get_string_member (ro, "light"), ==, "phase");
    g_assert_cmpint (json_object_get_int_member (ro, "phase"), ==, k);
    phase_look[k] = look (sub, "phase", k);
    phase_mean += phase_look[k].mean / PHASES;
    g_test_message ("phase %d: mean %.1f DN, stripes at %.3f cycles, modulation %.2f", k, phase_look[k].mean,
                    phase_look[k].phase_cycles, phase_look[k].modulation);
    g_assert_cmpfloat (phase_look[k].modulation, >, 0.2); /* stripes are there to measure */
    double moved = cycles_apart (phase_look[k].phase_cycles, phase_look[0].phase_cycles);
    g_assert_cmpfloat (fabs (cycles_apart (moved, (double) k / PHASES)), <, 0.03);
  }
  g_autoptr (DsMessage) st1 = NULL;
  JsonObject *so = status_object (a, &st1);
  g_assert_cmpstr (json_object_get_string_member (so, "state"), ==, "preview");
  JsonObject *po = json_object_get_object_member (so, "preview");
  g_assert_true (json_object_get_boolean_member (po, "on"));
  g_assert_cmpstr (json_object_get_string_member (po, "light"), ==, "phase");
  g_assert_cmpint (json_object_get_int_member (po, "phase"), ==, PHASES - 1);
  g_assert_cmpint (json_object_get_int_member (po, "frames"), >=, FRAMES_AVERAGED);

  g_autoptr (DsMessage) r_off = preview (a, "on", "off", -1);
  FrameLook off = look (sub, "off", -1);
  g_autoptr (DsMessage) r_all = preview (a, "on", NULL, -1); /* light defaults to all */
  g_assert_cmpstr (json_object_get_string_member (json_node_get_object (r_all->reply->body), "light"), ==, "all");
  FrameLook all = look (sub, "all", -1);
  g_test_message ("off: mean %.1f DN, modulation %.3f; all: mean %.1f DN, modulation %.3f; phases' mean %.1f DN",
                  off.mean, off.modulation, all.mean, all.modulation, phase_mean);
  g_assert_cmpfloat (all.modulation, <, 0.05);            /* no stripes */
  g_assert_cmpfloat (all.mean, >, phase_mean);
  double expect_all = off.mean + (phase_mean - off.mean) / DUTY;
  g_assert_cmpfloat (fabs (all.mean - expect_all), <, 0.03 * (expect_all - off.mean));

  /* Nothing was a set: no set counted, nothing spooled. */
  g_autoptr (DsMessage) st2 = NULL;
  so = status_object (a, &st2);
  g_assert_cmpint (json_object_get_int_member (so, "sets_done"), ==, sets_before);
  g_assert_cmpuint (count_files (spool), ==, 0);

  /* Off: idle, and no frame after. */
  g_autoptr (DsMessage) r_stop = preview (a, "off", NULL, -1);
  g_assert_cmpstr (json_object_get_string_member (json_node_get_object (r_stop->reply->body), "state"), ==, "idle");
  g_autoptr (DsMessage) st3 = NULL;
  so = status_object (a, &st3);
  g_assert_cmpstr (json_object_get_string_member (so, "state"), ==, "idle");
  po = json_object_get_object_member (so, "preview");
  g_assert_false (json_object_get_boolean_member (po, "on"));
  gint64 frames_at_off = json_object_get_int_member (po, "frames");
  g_usleep (300 * 1000);
  g_autoptr (DsMessage) st4 = NULL;
  g_assert_cmpint (json_object_get_int_member (json_object_get_object_member (status_object (a, &st4), "preview"),
                                               "frames"), ==, frames_at_off);

  /* The dark level, by the dark command's own frames (same exposure and gain). */
  g_autoptr (DsMessage) dark = test_daemon_call_ok (a, "dark", NULL);
  double dark_dn = json_object_get_double_member (json_node_get_object (dark->reply->body), "dark_mean_dn");
  g_test_message ("dark command: %.2f DN", dark_dn);
  g_assert_cmpfloat (fabs (off.mean - dark_dn), <, 0.5 + 0.01 * dark_dn);
  g_assert_cmpuint (count_files (spool), ==, 0);
}

static void
test_preview_lights (void)
{
  g_autofree char *tmp = g_dir_make_tmp ("descatter-preview-XXXXXX", NULL);
  g_autofree char *spool = g_build_filename (tmp, "spool", NULL);
  g_autofree char *conf = g_strdup_printf ("[camera]\nbackend=sim\n[illuminator]\nbackend=sim\n"
                                           "[sim]\nscene=%s\nseed=7\n[acquisition]\nphases=%d\n"
                                           "[daemon]\nspool-dir=%s\n",
                                           SCENE_FILE, PHASES, spool);
  TestDaemon *d = test_daemon_start (conf, NULL);
  check_lights (d, spool);
  test_daemon_stop_clean (d);
  test_remove_tree (tmp);
}

static const char *labsim_path, *scene_path;

/* The same over GigE Vision (Aravis) and Modbus TCP: descatter-labsim's camera and controller,
 * the daemon's real backends. */
static void
test_preview_labsim (void)
{
  g_autofree char *tmp = g_dir_make_tmp ("descatter-preview-XXXXXX", NULL);
  g_autofree char *spool = g_build_filename (tmp, "spool", NULL);
  TestLabsim *l = test_labsim_start (labsim_path, scene_path, NULL);
  g_autofree char *conf = g_strdup_printf ("[camera]\nbackend=aravis\naddress=127.0.0.1\npixel-format=Mono16\n"
                                           "grab-timeout-ms=2000\n"
                                           "[illuminator]\nbackend=modbus\nmodbus-uri=tcp://127.0.0.1:%u\n"
                                           "modbus-timeout-ms=300\nperiod-px=%g\nduty=%g\n"
                                           "[acquisition]\nphases=%d\n[daemon]\nspool-dir=%s\n",
                                           l->modbus_port, PERIOD_PX, DUTY, PHASES, spool);
  TestDaemon *d = test_daemon_start (conf, NULL);
  check_lights (d, spool);
  test_daemon_stop_clean (d);
  test_labsim_stop (l);
  test_remove_tree (tmp);
}

/* Cancel ends preview; a capture sent during preview ends it and runs; preview over a running
 * stream is refused `busy`; bad arguments are refused with `bad_argument`. */
static void
test_preview_ends_and_refusals (void)
{
  g_autofree char *conf = g_strdup_printf ("[camera]\nbackend=sim\n[illuminator]\nbackend=sim\n"
                                           "[sim]\nscene=%s\nseed=7\n[acquisition]\nphases=%d\n",
                                           SCENE_FILE, PHASES);
  TestDaemon *d = test_daemon_start (conf, NULL);
  g_autoptr (DsClient) a = test_daemon_connect (d);

  g_autoptr (DsMessage) r1 = preview (a, "on", "all", -1);
  g_autoptr (DsMessage) cancel = test_daemon_call_ok (a, "cancel", NULL);
  g_assert_cmpstr (json_object_get_string_member (json_node_get_object (cancel->reply->body), "state"), ==, "idle");
  g_autoptr (DsMessage) st1 = NULL;
  JsonObject *so = status_object (a, &st1);
  g_assert_cmpstr (json_object_get_string_member (so, "state"), ==, "idle");
  g_assert_false (json_object_get_boolean_member (json_object_get_object_member (so, "preview"), "on"));

  g_autoptr (DsMessage) r2 = preview (a, "on", "phase", 1);
  g_autoptr (JsonObject) small = json_object_new ();
  json_object_set_int_member (small, "averages", 1);
  g_autoptr (DsMessage) cap = test_daemon_call_ok (a, "capture", small);
  g_autoptr (DsMessage) st2 = NULL;
  so = status_object (a, &st2);
  /* The capture's reply may come before the thread says idle again (`acquiring` a moment
   * longer): what matters is that preview is over and does not resume. */
  g_assert_cmpstr (json_object_get_string_member (so, "state"), !=, "preview");
  g_assert_false (json_object_get_boolean_member (json_object_get_object_member (so, "preview"), "on"));

  g_autoptr (DsMessage) start = test_daemon_call_ok (a, "start", NULL);
  g_autoptr (JsonObject) on = json_object_new ();
  json_object_set_string_member (on, "state", "on");
  g_autoptr (GError) error = NULL;
  g_autoptr (DsMessage) busy = ds_client_call (a, "preview", on, NULL, NULL, &error);
  g_assert_no_error (error);
  g_assert_false (busy->reply->ok);
  g_assert_cmpint (busy->reply->error_code, ==, DS_PROTOCOL_ERROR_BUSY);
  g_autoptr (DsMessage) stop = test_daemon_call_ok (a, "stop", NULL);

  static const char *const bad[] = {
    "{\"state\": \"on\", \"light\": \"phase\"}",              /* phase missing */
    "{\"state\": \"on\", \"light\": \"phase\", \"phase\": 4}", /* 4 of 4 phases */
    "{\"state\": \"on\", \"phase\": 1}",                      /* phase without light phase */
    "{\"state\": \"on\", \"light\": \"half\"}",
    "{\"state\": \"off\", \"light\": \"all\"}",
    "{\"light\": \"all\"}",                                   /* state missing */
  };
  for (guint i = 0; i < G_N_ELEMENTS (bad); i++) {
    g_autoptr (JsonNode) args = json_from_string (bad[i], NULL);
    g_autoptr (GError) e = NULL;
    g_autoptr (DsMessage) m = ds_client_call (a, "preview", json_node_get_object (args), NULL, NULL, &e);
    g_assert_no_error (e);
    g_test_message ("%s: %s", bad[i], m->reply->error_message);
    g_assert_false (m->reply->ok);
    g_assert_cmpint (m->reply->error_code, ==, DS_PROTOCOL_ERROR_BAD_ARGUMENT);
  }
  test_daemon_stop_clean (d);
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  if (argc >= 3) {
    /* test_preview LABSIM SCENE: over the wire (binds UDP 3956). */
    labsim_path = argv[1];
    scene_path = argv[2];
    g_test_add_func ("/daemon/preview/labsim", test_preview_labsim);
  } else {
    g_test_add_func ("/daemon/preview/lights", test_preview_lights);
    g_test_add_func ("/daemon/preview/ends-and-refusals", test_preview_ends_and_refusals);
  }
  return g_test_run ();
}
