/* Benchmark: descatterd's acquisition rate, latency and memory at real resolutions against a
 * fast fake GigE Vision camera (fake_rig.h), each figure a ratio to a baseline measured in the
 * same run (docs/benchmarks.md, "Daemon rate"):
 *   rate     frames folded per second in continuous mode / a bare Aravis trigger-and-grab loop
 *            against the same camera (the ceiling); with a 3 ms Modbus settle, against the
 *            same loop that also sets the phase over Modbus before each trigger;
 *   latency  last frame -> result ready (the daemon's own monotonic stamps) per megapixel, and
 *            against the library alone finalizing the same set in this process;
 *   memory   peak RSS above idle over one 8-phase capture / the planes that must exist.
 * Every run also checks its results (the separation equals the closed-form scene, every frame
 * is accounted for), so the reduced form that ctest runs can fail.
 *
 * Usage: bench-daemon-rate [--quick] [--sizes WxH,WxH] [--seconds S] [--rounds N (<= 8)]
 * Binds UDP 127.0.0.1:3956: run it in a private network namespace, as an unprivileged user
 * (as root Aravis receives through a packet socket with a 5 ms ring timeout), e.g.
 *   unshare -n sh -c 'ip link set lo up && setpriv --reuid=nobody --regid=nogroup \
 *     --clear-groups build/tests/bench/bench-daemon-rate' */
#include <arv.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "../daemon/daemon_harness.h"
#include "drivers/modbus/modbus_illuminator.h"
#include "fake_rig.h"
#include "proc/separation.h"

#define N_PHASES 8

static int failures;

#define CHECK(cond, ...)                                                                          \
  do {                                                                                            \
    if (!(cond)) {                                                                                \
      fprintf (stderr, "FAIL: " __VA_ARGS__);                                                     \
      fprintf (stderr, "\n");                                                                     \
      failures++;                                                                                 \
    }                                                                                             \
  } while (0)

static int
compare_double (const void *a, const void *b)
{
  double x = *(const double *) a, y = *(const double *) b;
  return (x > y) - (x < y);
}

static double
median (double *v, guint n)
{
  qsort (v, n, sizeof *v, compare_double);
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

/* "median (min..max)" of n values (sorts them). */
static const char *
spread (double *v, guint n)
{
  static char buf[4][64];
  static guint next;
  char *b = buf[next++ % 4];
  double m = median (v, n);
  g_snprintf (b, 64, "%.3f (%.3f..%.3f over %u rounds)", m, v[0], v[n - 1], n);
  return b;
}

/* ---- the ceiling: a bare Aravis loop, configured as the daemon configures the camera ---- */

static double
bare_loop_here (guint w, guint h, double seconds, guint modbus_port)
{
  g_autoptr (GError) e = NULL;
  g_autoptr (ArvCamera) cam = arv_camera_new ("127.0.0.1", &e);
  if (!cam) {
    fprintf (stderr, "bare loop: %s\n", e->message);
    failures++;
    return NAN;
  }
  arv_camera_set_acquisition_mode (cam, ARV_ACQUISITION_MODE_CONTINUOUS, NULL);
  arv_camera_set_pixel_format (cam, ARV_PIXEL_FORMAT_MONO_16, NULL);
  arv_camera_set_region (cam, 0, 0, (gint) w, (gint) h, NULL);
  arv_camera_set_trigger (cam, "Software", NULL);
  arv_camera_gv_auto_packet_size (cam, NULL);
  /* The negotiated GVSP packet size decides how many packets a frame takes: say it, since the
   * daemon negotiates its own the same way and a loaded machine can make them differ. */
  fprintf (stderr, "bare loop: GVSP packet size %u bytes\n", arv_camera_gv_get_packet_size (cam, NULL));
  g_autoptr (DsIlluminator) ill = NULL;
  if (modbus_port) {
    g_autofree char *uri = g_strdup_printf ("tcp://127.0.0.1:%u", modbus_port);
    ill = ds_modbus_illuminator_open (uri, 1, 200, &e);
    DsStripePattern p = { .kind = DS_STRIPES_SQUARE, .period_px = FAKE_RIG_PERIOD_PX, .duty = 0.5,
                          .black_level = 0, .intensity = 1, .n_phases = N_PHASES };
    if (!ill || !ill->ops->set_pattern (ill->backend, &p, &e)) {
      fprintf (stderr, "bare loop: illuminator: %s\n", e->message);
      failures++;
      return NAN;
    }
  }
  guint payload = arv_camera_get_payload (cam, NULL);
  g_autoptr (ArvStream) stream = arv_camera_create_stream (cam, NULL, NULL, &e);
  if (!stream) {
    fprintf (stderr, "bare loop: %s\n", e->message);
    failures++;
    return NAN;
  }
  g_object_set (stream, "socket-buffer", ARV_GV_STREAM_SOCKET_BUFFER_AUTO, "packet-resend",
                ARV_GV_STREAM_PACKET_RESEND_ALWAYS, NULL);
  for (guint i = 0; i < 8; i++)
    arv_stream_push_buffer (stream, arv_buffer_new_allocate (payload));
  arv_camera_start_acquisition (cam, NULL);
  guint64 frames = 0, k = 0;
  guint lost = 0;
  gint64 t0 = 0, end = 0;
  /* The first frames warm up (ARP-free loopback, but socket buffers and page faults). */
  for (guint i = 0;; i++) {
    if (i == 3) {
      t0 = g_get_monotonic_time ();
      end = t0 + (gint64) (seconds * 1e6);
      frames = 0;
    }
    if (t0 && g_get_monotonic_time () >= end)
      break;
    if (ill && !ill->ops->set_phase (ill->backend, (guint) (k++ % N_PHASES), 500, &e)) {
      fprintf (stderr, "bare loop: set_phase: %s\n", e->message);
      failures++;
      break;
    }
    arv_camera_software_trigger (cam, NULL);
    ArvBuffer *b = arv_stream_timeout_pop_buffer (stream, 2000000);
    if (!b) {
      /* A lost trigger or frame: trigger again, as the daemon does. */
      if (++lost > 10) {
        fprintf (stderr, "bare loop: more than 10 frames lost\n");
        failures++;
        break;
      }
      continue;
    }
    if (arv_buffer_get_status (b) == ARV_BUFFER_STATUS_SUCCESS)
      frames++;
    arv_stream_push_buffer (stream, b);
  }
  double rate = frames / ((g_get_monotonic_time () - t0) / 1e6);
  arv_camera_stop_acquisition (cam, NULL);
  return rate;
}

/* The loop runs in a process of its own, as the daemon does, so that both receive the same
 * way (and neither shares its process with the fake camera's threads). */
static const char *self_path;

static double
bare_loop (guint w, guint h, double seconds, guint modbus_port)
{
  g_autofree char *ws = g_strdup_printf ("%u", w), *hs = g_strdup_printf ("%u", h);
  g_autofree char *ss = g_strdup_printf ("%g", seconds), *ps = g_strdup_printf ("%u", modbus_port);
  g_autoptr (GError) e = NULL;
  g_autoptr (GSubprocess) p = g_subprocess_new (G_SUBPROCESS_FLAGS_STDOUT_PIPE, &e, self_path,
                                                "--bare-loop", ws, hs, ss, ps, NULL);
  g_autofree char *out = NULL;
  if (!p || !g_subprocess_communicate_utf8 (p, NULL, NULL, &out, NULL, &e) ||
      !g_subprocess_get_successful (p)) {
    fprintf (stderr, "bare loop: %s\n", e ? e->message : "failed");
    failures++;
    return NAN;
  }
  return g_ascii_strtod (out, NULL);
}

/* ---- the daemon ---- */

static TestDaemon *
start_daemon (FakeRig *rig)
{
  g_autofree char *conf = g_strdup_printf (
      "[daemon]\nmax-clients=8\n"
      "[camera]\nbackend=aravis\naddress=127.0.0.1\npixel-format=Mono16\nexposure-us=1000\n"
      "grab-timeout-ms=2000\n"
      "[illuminator]\nbackend=modbus\nmodbus-uri=tcp://127.0.0.1:%u\nperiod-px=%g\nduty=0.5\n"
      "[acquisition]\nphases=%d\ndark-frame=false\n",
      fake_rig_modbus_port (rig), FAKE_RIG_PERIOD_PX, N_PHASES);
  return test_daemon_start (conf, NULL);
}

static JsonObject *
obj (JsonNode *node, const char *member)
{
  return json_object_get_object_member (json_node_get_object (node), member);
}

/* One capture, checked against the closed form; returns its reply. */
static DsMessage *
checked_capture (DsClient *c, guint w, guint h)
{
  g_autoptr (DsMessage) m = test_daemon_call_ok (c, "capture", NULL);
  JsonNode *body = m->reply->body;
  CHECK (test_json_int (body, "width") == w && test_json_int (body, "height") == h,
         "result is %" G_GINT64_FORMAT "x%" G_GINT64_FORMAT ", camera %ux%u",
         test_json_int (body, "width"), test_json_int (body, "height"), w, h);
  gint64 acquired = test_json_int (body, "frames.acquired");
  gint64 folded = test_json_int (body, "frames.folded");
  gint64 dropped = test_json_int (body, "frames.dropped");
  CHECK (acquired == folded + dropped, "accounting: acquired %" G_GINT64_FORMAT " != folded %"
         G_GINT64_FORMAT " + dropped %" G_GINT64_FORMAT, acquired, folded, dropped);
  CHECK (folded == N_PHASES, "folded %" G_GINT64_FORMAT " frames, expected %d", folded, N_PHASES);
  guint bad = 0;
  for (guint p = 0; p < m->reply->n_payloads && p < 2; p++) {
    gsize size = 0;
    const float *v = g_bytes_get_data (m->payloads[p], &size);
    double expect = p == 0 ? FAKE_RIG_DIRECT_DN : FAKE_RIG_SCATTERED_EXPECTED;
    CHECK (size == (gsize) w * h * 4, "payload %u: %zu bytes", p, size);
    for (gsize i = 0; i < size / 4; i++)
      bad += fabs (v[i] - expect) > 1e-3;
  }
  CHECK (m->reply->n_payloads >= 2 && bad == 0,
         "%u pixels differ from the closed form (transmissive %g, scattered %g)", bad,
         FAKE_RIG_DIRECT_DN, FAKE_RIG_SCATTERED_EXPECTED);
  return g_steal_pointer (&m);
}

/* Waits (polling status) until a set completes; returns its status message and the time. The
 * folded counter moves by a whole set at once, so a rate is measured between two set ends. */
static DsMessage *
at_set_end (DsClient *c, gint64 *when)
{
  g_autoptr (DsMessage) s0 = test_daemon_call_ok (c, "status", NULL);
  gint64 done0 = test_json_int (s0->reply->body, "sets_done");
  for (;;) {
    DsMessage *s = test_daemon_call_ok (c, "status", NULL);
    *when = g_get_monotonic_time ();
    if (test_json_int (s->reply->body, "sets_done") != done0)
      return s;
    ds_message_free (s);
    g_usleep (2000);
  }
}

/* Frames folded per second in continuous mode, from the daemon's own counters. */
static double
daemon_rate (DsClient *c, double seconds, double *finalize_ms)
{
  g_autoptr (DsMessage) started = test_daemon_call_ok (c, "start", NULL);
  g_usleep (300000);
  gint64 t0, t1;
  g_autoptr (DsMessage) s0 = at_set_end (c, &t0);
  gint64 f0 = test_json_int (s0->reply->body, "frames.folded");
  g_usleep ((gulong) (seconds * 1e6));
  g_autoptr (DsMessage) s1 = at_set_end (c, &t1);
  gint64 f1 = test_json_int (s1->reply->body, "frames.folded");
  g_autoptr (DsMessage) stopped = test_daemon_call_ok (c, "stop", NULL);
  gint64 acquired = test_json_int (s1->reply->body, "frames.acquired");
  gint64 dropped = test_json_int (s1->reply->body, "frames.dropped");
  /* A set may fail on a starved machine (the camera's heartbeat answered too late: control
   * lost, reconnected); its frames are then `aborted`. Reported, not a wrong result. */
  if (test_json_int (s1->reply->body, "sets_failed") > 0)
    printf ("  (continuous mode: %" G_GINT64_FORMAT " set(s) failed: %s)\n",
            test_json_int (s1->reply->body, "sets_failed"),
            json_object_get_string_member (json_node_get_object (s1->reply->body), "last_error"));
  /* Frames of the set in progress are acquired but not yet folded or aborted. */
  CHECK (acquired - dropped - f1 >= 0 && acquired - dropped - f1 <= N_PHASES,
         "accounting: acquired %" G_GINT64_FORMAT ", dropped %" G_GINT64_FORMAT ", folded %"
         G_GINT64_FORMAT, acquired, dropped, f1);
  if (dropped) {
    /* Transport losses happen on a loaded machine (a socket buffer overflows); drops that say
     * the sequencing went wrong must not. */
    JsonObject *by = json_object_get_object_member (obj (s1->reply->body, "frames"), "dropped_by_reason");
    g_autofree char *why = json_to_string (json_object_get_member (obj (s1->reply->body, "frames"),
                                                                   "dropped_by_reason"), FALSE);
    printf ("  (continuous mode: %" G_GINT64_FORMAT " frames dropped: %s)\n", dropped, why);
    static const char *const wrong[] = { "wrong_phase", "unverifiable", "preview" };
    for (guint i = 0; i < G_N_ELEMENTS (wrong); i++)
      CHECK (json_object_get_int_member (by, wrong[i]) == 0, "%s drops on a clean rig", wrong[i]);
  }
  {
    JsonObject *sm = obj (s1->reply->body, "stage_mean_ms");
    printf ("  stage means (ms): set_phase %.2f trigger %.2f grab %.2f verify %.2f fold %.2f "
            "finalize %.2f\n", json_object_get_double_member (sm, "set_phase"),
            json_object_get_double_member (sm, "trigger"), json_object_get_double_member (sm, "grab"),
            json_object_get_double_member (sm, "verify"), json_object_get_double_member (sm, "fold"),
            json_object_get_double_member (sm, "finalize"));
  }
  if (finalize_ms)
    *finalize_ms = json_object_get_double_member (obj (s1->reply->body, "stage_mean_ms"), "finalize");
  return (f1 - f0) / ((t1 - t0) / 1e6);
}

/* ---- latency baseline: the library alone ---- */

static double
library_finalize_ms (guint w, guint h, guint reps)
{
  DsSeparationParams p;
  ds_separation_params_init (&p, N_PHASES);
  g_autoptr (DsPhaseSet) set = ds_phase_set_new (&p, w, h, NULL);
  g_autoptr (DsImage) frame = ds_image_new (DS_SAMPLE_U16, w, h, NULL);
  frame->bit_depth = 12;
  DsSeparation *keep = NULL;
  double t[16];
  reps = MIN (reps, 16);
  for (guint r = 0; r < reps + 1; r++) {
    ds_phase_set_reset (set);
    for (guint k = 0; k < N_PHASES; k++) {
      for (guint y = 0; y < h; y++) {
        guint16 *row = ds_image_row (frame, y);
        for (guint x = 0; x < w; x++)
          row[x] = (guint16) ((x / 8 + k) % 2 ? 1302 : 302);
      }
      ds_phase_set_accumulate (set, k, frame, NULL);
    }
    gint64 t0 = g_get_monotonic_time ();
    keep = ds_phase_set_finalize_reusing (set, keep, NULL);
    if (r > 0) /* the first finalize pays for fresh planes */
      t[r - 1] = (g_get_monotonic_time () - t0) / 1000.0;
  }
  ds_separation_free (keep);
  return median (t, reps);
}

/* ---- memory ---- */

static guint64
status_kib (TestDaemon *d, const char *key)
{
  GPid pid = (GPid) atoi (g_subprocess_get_identifier (d->proc));
  g_autofree char *path = g_strdup_printf ("/proc/%d/status", pid);
  g_autofree char *text = NULL;
  if (!g_file_get_contents (path, &text, NULL, NULL))
    return 0;
  const char *at = strstr (text, key);
  return at ? g_ascii_strtoull (at + strlen (key), NULL, 10) : 0;
}

int
main (int argc, char **argv)
{
  self_path = argv[0];
  if (argc == 6 && strcmp (argv[1], "--bare-loop") == 0) {
    double fps = bare_loop_here ((guint) atoi (argv[2]), (guint) atoi (argv[3]),
                                 g_ascii_strtod (argv[4], NULL), (guint) atoi (argv[5]));
    printf ("%.3f\n", fps);
    return failures ? 1 : 0;
  }
  gboolean quick = FALSE;
  const char *sizes = "1024x1024,2048x2048";
  double seconds = 3.0;
  guint rounds = 0;
  for (int i = 1; i < argc; i++) {
    if (strcmp (argv[i], "--quick") == 0)
      quick = TRUE;
    else if (strcmp (argv[i], "--sizes") == 0 && i + 1 < argc)
      sizes = argv[++i];
    else if (strcmp (argv[i], "--seconds") == 0 && i + 1 < argc)
      seconds = g_ascii_strtod (argv[++i], NULL);
    else if (strcmp (argv[i], "--rounds") == 0 && i + 1 < argc) {
      int r = atoi (argv[++i]); /* CLAMP evaluates its argument more than once */
      rounds = (guint) CLAMP (r, 1, 8);
    } else {
      fprintf (stderr, "usage: bench-daemon-rate [--quick] [--sizes WxH,WxH] [--seconds S] [--rounds N]\n");
      return 2;
    }
  }
  if (quick) {
    seconds = 1.0;
    if (strcmp (sizes, "1024x1024,2048x2048") == 0)
      sizes = "1024x1024";
  }
  if (rounds == 0)
    rounds = quick ? 1 : 3;
  if (geteuid () == 0)
    printf ("note: running as root: Aravis then receives through a packet socket (5 ms ring "
            "timeout); the figures are not those of the service (run as an unprivileged user)\n");
  double load[3] = { 0 };
  if (getloadavg (load, 3) == 3)
    printf ("machine load (1/5/15 min): %.2f %.2f %.2f, %ld cores\n", load[0], load[1], load[2],
            sysconf (_SC_NPROCESSORS_ONLN));

  g_auto (GStrv) list = g_strsplit (sizes, ",", -1);
  for (guint si = 0; list[si]; si++) {
    guint w = 0, h = 0;
    if (sscanf (list[si], "%ux%u", &w, &h) != 2 || w < 64 || h < 64) {
      fprintf (stderr, "bad size \"%s\"\n", list[si]);
      return 2;
    }
    double mp = (double) w * h / 1e6;
    if (getloadavg (load, 3) == 3)
      printf ("%ux%u: load before %.2f\n", w, h, load[0]);
    FakeRig *rig = fake_rig_new (w, h, N_PHASES, 0);
    if (!rig)
      return 1;

    /* Rate: alternate ceiling and daemon so that a change of load hits both. */
    double ratio[8], ceil_fps[8], dmn_fps[8];
    double fin_ms = NAN;
    guint64 idle_kib = 0, peak_kib = 0;
    double lat[16];
    guint n_lat = 0;
    for (guint r = 0; r < rounds; r++) {
      ceil_fps[r] = bare_loop (w, h, seconds, 0);
      TestDaemon *d = start_daemon (rig);
      g_autoptr (DsClient) c = test_daemon_connect (d);
      if (r == 0) {
        idle_kib = status_kib (d, "VmRSS:");
        /* Latency and memory from single captures (no continuous mode yet). */
        guint n = quick ? 3 : 11;
        for (guint i = 0; i < n; i++) {
          g_autoptr (DsMessage) m = checked_capture (c, w, h);
          if (i > 0) /* the first set configures the camera and learns the phase offset */
            lat[n_lat++] = (test_json_int (m->reply->body, "monotonic_us.finished") -
                            test_json_int (m->reply->body, "monotonic_us.last_frame")) / 1000.0;
          if (i == 0)
            peak_kib = status_kib (d, "VmHWM:");
        }
      }
      dmn_fps[r] = daemon_rate (c, seconds, &fin_ms);
      ratio[r] = dmn_fps[r] / ceil_fps[r];
      g_clear_pointer (&c, ds_client_free);
      test_daemon_stop (d);
      test_daemon_free (d);
    }
    double lib_ms = library_finalize_ms (w, h, quick ? 3 : 9);
    double lat_ms = median (lat, n_lat);
    printf ("%ux%u Mono16 (%.2f MP), 8 phases:\n", w, h, mp);
    printf ("  rate: daemon %.1f frames folded/s, bare Aravis loop %.1f frames/s -> ratio %s; "
            "goal >= %.2f\n",
            median (dmn_fps, rounds), median (ceil_fps, rounds), spread (ratio, rounds),
            mp > 2 ? 0.90 : 0.95);
    printf ("  latency, last frame -> result ready: %.2f ms = %.2f ms/MP (goal <= 1); library "
            "finalize alone %.2f ms -> daemon/library %.2f\n",
            lat_ms, lat_ms / mp, lib_ms, lat_ms / lib_ms);
    /* What must exist for an 8-phase maxmin set: max and min accumulators (u16) and the result
     * planes (transmissive, scattered f32, mask u8): 13 bytes per pixel. */
    double minimum_mb = 13.0 * w * h / 1e6;
    double above_mb = (peak_kib > idle_kib ? peak_kib - idle_kib : 0) * 1024.0 / 1e6;
    printf ("  memory: peak RSS above idle over the first capture %.1f MB; minimum %.1f MB "
            "-> %.2fx (goal <= 3)\n", above_mb, minimum_mb, above_mb / minimum_mb);

    if (si == 0) {
      /* The illuminator's settle time: 3 ms per phase, set over Modbus TCP. */
      fake_rig_set_settle_us (rig, 3000);
      double sr[8], sc[8], sd[8];
      for (guint r = 0; r < rounds; r++) {
        sc[r] = bare_loop (w, h, seconds, fake_rig_modbus_port (rig));
        TestDaemon *d = start_daemon (rig);
        g_autoptr (DsClient) c = test_daemon_connect (d);
        g_autoptr (DsMessage) m = checked_capture (c, w, h);
        sd[r] = daemon_rate (c, seconds, NULL);
        sr[r] = sd[r] / sc[r];
        g_clear_pointer (&c, ds_client_free);
        test_daemon_stop (d);
        test_daemon_free (d);
      }
      printf ("  with a Modbus illuminator settling 3 ms: daemon %.1f frames/s, bare loop with "
              "set_phase %.1f frames/s -> ratio %s; goal >= 0.85\n",
              median (sd, rounds), median (sc, rounds), spread (sr, rounds));
    }
    fake_rig_free (rig);
  }
  if (getloadavg (load, 3) == 3)
    printf ("machine load at the end (1/5/15 min): %.2f %.2f %.2f\n", load[0], load[1], load[2]);
  if (failures)
    fprintf (stderr, "%d check(s) failed\n", failures);
  return failures ? 1 : 0;
}
