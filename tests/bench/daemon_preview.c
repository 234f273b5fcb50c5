/* Benchmark: what preview costs the daemon against continuous acquisition at the same size, on
 * the fast fake GigE Vision rig (fake_rig.h), each figure a ratio to continuous mode measured in
 * the same run (docs/benchmarks.md, "Preview"):
 *   memory   the daemon's resident set (VmRSS, sampled every 50 ms over each slice, mean);
 *   CPU      the daemon's CPU time per second of wall time, all threads (thread_cpu.h), and per
 *            frame acquired;
 *   rate     frames acquired per second.
 * Three modes alternate slice by slice (C P F C P F ...), so that a drift of the machine falls
 * on all of them: C continuous (`start`, every frame folded into 8-phase sets), P preview
 * (light all, nobody asking for frames), F preview with one `subscribe {"frames": true}` client
 * reading every frame it gets. The medians of the slices are compared.
 * Every run checks what it measured, so the reduced form that ctest runs can fail: continuous
 * slices publish sets, preview slices publish none and acquire frames, the frames client gets
 * 1 MP frames of the rig's size, and every figure is finite and positive.
 *
 * Usage: bench-daemon-preview [--quick] [--size WxH] [--seconds S (per slice)] [--slices N]
 * Binds UDP 127.0.0.1:3956: run it in a private network namespace, as an unprivileged user
 * (tests/bench/run_rate_bench.sh). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "tests/common/daemon_harness.h"
#include "fake_rig.h"
#include "thread_cpu.h"

#define N_PHASES 8
#define MAX_SLICES 16

static int failures;

#define CHECK(cond, ...)                                                                          \
  do {                                                                                            \
    if (!(cond)) {                                                                                \
      fprintf (stderr, "FAIL: " __VA_ARGS__);                                                     \
      fprintf (stderr, "\n");                                                                     \
      failures++;                                                                                 \
    }                                                                                             \
  } while (0)

typedef enum { MODE_CONTINUOUS = 0, MODE_PREVIEW, MODE_PREVIEW_FRAMES, N_MODES } Mode;
static const char *const mode_name[N_MODES] = { "continuous", "preview", "preview + frames client" };

typedef struct {
  double rss_mib, cpu_per_s, cpu_ms_per_frame, fps;
  gint64 sets, frames;
  guint64 client_frames;
} Slice;

static char *
rig_config (guint modbus_port)
{
  return g_strdup_printf ("[daemon]\nmax-clients=8\n"
                          "[camera]\nbackend=aravis\naddress=127.0.0.1\npixel-format=Mono16\nexposure-us=1000\n"
                          "grab-timeout-ms=2000\n"
                          "[illuminator]\nbackend=modbus\nmodbus-uri=tcp://127.0.0.1:%u\nperiod-px=%g\nduty=0.5\n"
                          "[acquisition]\nphases=%d\ndark-frame=false\n",
                          modbus_port, FAKE_RIG_PERIOD_PX, N_PHASES);
}

static guint64
rss_kib (GPid pid)
{
  g_autofree char *path = g_strdup_printf ("/proc/%d/status", pid);
  g_autofree char *text = NULL;
  if (!g_file_get_contents (path, &text, NULL, NULL))
    return 0;
  const char *at = strstr (text, "VmRSS:");
  return at ? g_ascii_strtoull (at + 6, NULL, 10) : 0;
}

/* The frames client: reads events until told to stop, counting `frame` events of the rig's size. */
typedef struct {
  DsClient *client;
  guint width, height;
  gint stop;
  guint64 frames, wrong;
} FrameReader;

static gpointer
read_frames (gpointer data)
{
  FrameReader *r = data;
  while (!g_atomic_int_get (&r->stop)) {
    g_autoptr (GError) error = NULL;
    g_autoptr (DsMessage) m = ds_client_read (r->client, 200, &error);
    if (!m || g_strcmp0 (m->reply->event, "frame") != 0)
      continue;
    if (m->reply->n_payloads == 1 && m->reply->payloads[0].width == r->width &&
        m->reply->payloads[0].height == r->height)
      r->frames++;
    else
      r->wrong++;
  }
  return NULL;
}

static void
set_mode (DsClient *c, Mode mode, gboolean on)
{
  g_autoptr (JsonObject) args = json_object_new ();
  if (mode == MODE_CONTINUOUS) {
    g_autoptr (DsMessage) m = test_daemon_call_ok (c, on ? "start" : "stop", NULL);
    return;
  }
  json_object_set_string_member (args, "state", on ? "on" : "off");
  g_autoptr (DsMessage) m = test_daemon_call_ok (c, "preview", args);
}

/* One slice of `mode`: settles 0.3 s, then measures for `seconds`. */
static Slice
measure (DsClient *c, TestDaemon *td, FrameReader *reader, Mode mode, double seconds)
{
  GPid pid = (GPid) atoi (g_subprocess_get_identifier (td->proc));
  set_mode (c, mode, TRUE);
  g_usleep (300000);
  guint64 client0 = reader->frames;
  g_autoptr (DsMessage) s0 = test_daemon_call_ok (c, "status", NULL);
  g_autoptr (ThreadCpu) cpu0 = thread_cpu_read (pid);
  gint64 t0 = g_get_monotonic_time ();
  double rss_sum = 0;
  guint rss_n = 0;
  while (g_get_monotonic_time () - t0 < (gint64) (seconds * 1e6)) {
    rss_sum += (double) rss_kib (pid);
    rss_n++;
    g_usleep (50000);
  }
  g_autoptr (DsMessage) s1 = test_daemon_call_ok (c, "status", NULL);
  g_autoptr (ThreadCpu) cpu1 = thread_cpu_read (pid);
  double dt = (g_get_monotonic_time () - t0) / 1e6;
  Slice s = { 0 };
  s.client_frames = reader->frames - client0;
  set_mode (c, mode, FALSE);
  ThreadCpuTotals cpu = { 0 };
  thread_cpu_add_delta (&cpu, cpu0, cpu1);
  s.frames = test_json_int (s1->reply->body, "frames.acquired") - test_json_int (s0->reply->body, "frames.acquired");
  s.sets = test_json_int (s1->reply->body, "sets_done") - test_json_int (s0->reply->body, "sets_done");
  s.fps = s.frames / dt;
  s.cpu_per_s = thread_cpu_totals_sum (&cpu) / 1e9 / dt;
  s.cpu_ms_per_frame = s.frames > 0 ? thread_cpu_totals_sum (&cpu) / 1e6 / (double) s.frames : NAN;
  s.rss_mib = rss_n ? rss_sum / rss_n / 1024.0 : NAN;
  return s;
}

static int
compare_double (const void *a, const void *b)
{
  double x = *(const double *) a, y = *(const double *) b;
  return (x > y) - (x < y);
}

static double
median_of (const Slice *s, guint n, gsize offset)
{
  double v[MAX_SLICES];
  for (guint i = 0; i < n; i++)
    v[i] = *(const double *) ((const char *) &s[i] + offset);
  qsort (v, n, sizeof *v, compare_double);
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

int
main (int argc, char **argv)
{
  gboolean quick = FALSE;
  g_autofree char *size = NULL;
  double seconds = 0;
  gint slices = 0;
  GOptionEntry entries[] = {
    { "quick", 0, 0, G_OPTION_ARG_NONE, &quick, "reduced run (ctest): 256x256, 2 slices of 1 s", NULL },
    { "size", 0, 0, G_OPTION_ARG_STRING, &size, "frame size (default 1024x1024)", "WxH" },
    { "seconds", 0, 0, G_OPTION_ARG_DOUBLE, &seconds, "per slice (default 3)", "S" },
    { "slices", 0, 0, G_OPTION_ARG_INT, &slices, "slices of each mode (default 5, at most 16)", "N" },
    { NULL },
  };
  g_autoptr (GOptionContext) ctx = g_option_context_new ("- preview's memory and CPU against continuous mode");
  g_option_context_add_main_entries (ctx, entries, NULL);
  g_autoptr (GError) error = NULL;
  if (!g_option_context_parse (ctx, &argc, &argv, &error)) {
    fprintf (stderr, "bench-daemon-preview: %s\n", error->message);
    return 2;
  }
  guint w = quick ? 256 : 1024, h = quick ? 256 : 1024;
  if (size && sscanf (size, "%ux%u", &w, &h) != 2) {
    fprintf (stderr, "bench-daemon-preview: --size WxH, not %s\n", size);
    return 2;
  }
  if (seconds <= 0)
    seconds = quick ? 1.0 : 3.0;
  if (slices <= 0)
    slices = quick ? 2 : 5;
  slices = MIN (slices, MAX_SLICES);

  FakeRig *rig = fake_rig_new (w, h, N_PHASES, 0);
  if (!rig)
    return 1;
  g_autofree char *conf = rig_config (fake_rig_modbus_port (rig));
  TestDaemon *td = test_daemon_start (conf, NULL);
  g_autoptr (DsClient) c = test_daemon_connect (td);
  g_autoptr (DsClient) fc = test_daemon_connect (td);
  /* The first set configures the camera and learns the phase offset. */
  g_autoptr (DsMessage) first = test_daemon_call_ok (c, "capture", NULL);
  FrameReader reader = { .client = fc, .width = w, .height = h };
  Slice s[N_MODES][MAX_SLICES];
  GThread *reading = NULL;
  for (gint j = 0; j < slices; j++)
    for (guint m = 0; m < N_MODES; m++) {
      if (m == MODE_PREVIEW_FRAMES) {
        g_autoptr (JsonObject) args = json_object_new ();
        json_object_set_boolean_member (args, "frames", TRUE);
        g_autoptr (DsMessage) sub = test_daemon_call_ok (fc, "subscribe", args);
        g_atomic_int_set (&reader.stop, 0);
        reading = g_thread_new ("frames-client", read_frames, &reader);
      }
      s[m][j] = measure (c, td, &reader, m, seconds);
      if (m == MODE_PREVIEW_FRAMES) {
        g_atomic_int_set (&reader.stop, 1);
        g_thread_join (reading);
        g_autoptr (DsMessage) unsub = test_daemon_call_ok (fc, "unsubscribe", NULL);
      }
      printf ("  slice %d %-24s %6.1f fps, CPU %.3f s/s (%.3f ms/frame), RSS %.1f MiB, %" G_GINT64_FORMAT " sets",
              j, mode_name[m], s[m][j].fps, s[m][j].cpu_per_s, s[m][j].cpu_ms_per_frame, s[m][j].rss_mib,
              s[m][j].sets);
      if (m == MODE_PREVIEW_FRAMES)
        printf (", client got %" G_GUINT64_FORMAT " frames", s[m][j].client_frames);
      printf ("\n");
      if (m == MODE_CONTINUOUS)
        CHECK (s[m][j].sets > 0, "continuous slice %d published no set", j);
      else
        CHECK (s[m][j].sets == 0 && s[m][j].frames > 0,
               "preview slice %d: %" G_GINT64_FORMAT " sets (none expected), %" G_GINT64_FORMAT " frames", j,
               s[m][j].sets, s[m][j].frames);
      if (m == MODE_PREVIEW_FRAMES)
        CHECK (s[m][j].client_frames > 0, "the frames client got no frame in slice %d", j);
    }
  CHECK (reader.wrong == 0, "the frames client got %" G_GUINT64_FORMAT " frames not of %ux%u", reader.wrong, w, h);
  g_clear_pointer (&c, ds_client_free);
  g_clear_pointer (&fc, ds_client_free);
  test_daemon_stop_clean (td);
  fake_rig_free (rig);

  double med[N_MODES][4];
  static const gsize offs[4] = { G_STRUCT_OFFSET (Slice, rss_mib), G_STRUCT_OFFSET (Slice, cpu_per_s),
                                 G_STRUCT_OFFSET (Slice, cpu_ms_per_frame), G_STRUCT_OFFSET (Slice, fps) };
  for (guint m = 0; m < N_MODES; m++)
    for (guint k = 0; k < 4; k++) {
      med[m][k] = median_of (s[m], (guint) slices, offs[k]);
      CHECK (isfinite (med[m][k]) && med[m][k] > 0, "%s: a figure is not finite and positive", mode_name[m]);
    }
  printf ("preview at %ux%u Mono16 (%d slices of %.1f s per mode, medians; ratios to continuous, same run; "
          "daemon run as %s):\n", w, h, slices, seconds, g_get_user_name ());
  printf ("  %-24s %10s %12s %14s %10s\n", "mode", "RSS MiB", "CPU s/s", "CPU ms/frame", "fps");
  for (guint m = 0; m < N_MODES; m++)
    printf ("  %-24s %10.1f %12.3f %14.3f %10.1f\n", mode_name[m], med[m][0], med[m][1], med[m][2], med[m][3]);
  for (guint m = 1; m < N_MODES; m++)
    printf ("  %-24s RSS x%.2f, CPU/s x%.2f, CPU/frame x%.2f, rate x%.2f\n", mode_name[m],
            med[m][0] / med[0][0], med[m][1] / med[0][1], med[m][2] / med[0][2], med[m][3] / med[0][3]);
  if (failures)
    fprintf (stderr, "bench-daemon-preview: %d check(s) failed\n", failures);
  return failures ? 1 : 0;
}
