/* Load: 64 concurrent clients on one descatterd (simulated lab, continuous acquisition) for a
 * bounded time, mixing captures, status calls, subscribers that read, subscribers that never
 * read, clients that vanish in the middle of a payload, clients that send malformed or
 * oversized lines and clients that never send anything. Afterwards the daemon still answers,
 * acquisition went on, the frame accounting adds up, and its memory stayed bounded.
 * Usage: test_load SCENE [SECONDS] (ctest runs a short version; docs/reliability.md the long). */
#include <stdio.h>
#include <string.h>

#include "tests/common/daemon_harness.h"

typedef enum {
  ROLE_CAPTURE,
  ROLE_STATUS,
  ROLE_SUBSCRIBER,
  ROLE_STUCK_SUBSCRIBER,
  ROLE_HANGUP_MID_PAYLOAD,
  ROLE_GARBAGE,
  ROLE_SILENT,
  ROLE_N
} Role;

typedef struct {
  TestDaemon *daemon;
  Role role;
  gint64 deadline;
  guint ok, errors;
  gboolean failed;
  char failure[256];
} Worker;

static void
fail (Worker *w, const char *what)
{
  w->failed = TRUE;
  g_strlcpy (w->failure, what, sizeof w->failure);
}

static gpointer
worker_main (gpointer data)
{
  Worker *w = data;
  g_autoptr (DsClient) c = ds_client_connect (w->daemon->socket_path, NULL);
  if (!c) {
    fail (w, "connect refused");
    return NULL;
  }
  switch (w->role) {
  case ROLE_CAPTURE:
    while (g_get_monotonic_time () < w->deadline) {
      g_autoptr (JsonObject) args = json_object_new ();
      json_object_set_int_member (args, "phases", 4);
      g_autoptr (GError) error = NULL;
      g_autoptr (DsMessage) m = ds_client_call (c, "capture", args, NULL, NULL, &error);
      if (!m) {
        fail (w, error->message);
        return NULL;
      }
      /* busy is an honest answer under load; anything else must be a result. */
      if (m->reply->ok)
        w->ok++;
      else if (m->reply->error_code == DS_PROTOCOL_ERROR_BUSY)
        w->errors++;
      else {
        fail (w, m->reply->error_message);
        return NULL;
      }
    }
    break;
  case ROLE_STATUS:
    while (g_get_monotonic_time () < w->deadline) {
      g_autoptr (GError) error = NULL;
      g_autoptr (DsMessage) m = ds_client_call (c, "status", NULL, NULL, NULL, &error);
      if (!m || !m->reply->ok) {
        fail (w, m ? m->reply->error_message : error->message);
        return NULL;
      }
      w->ok++;
      g_usleep (20000);
    }
    break;
  case ROLE_SUBSCRIBER:
  case ROLE_STUCK_SUBSCRIBER: {
    g_autoptr (DsMessage) s = ds_client_call (c, "subscribe", NULL, NULL, NULL, NULL);
    if (!s || !s->reply->ok) {
      fail (w, "subscribe failed");
      return NULL;
    }
    if (w->role == ROLE_STUCK_SUBSCRIBER) {
      /* Never reads: the daemon must drop its results, not buffer them. */
      g_usleep ((gulong) MAX (0, w->deadline - g_get_monotonic_time ()));
      break;
    }
    while (g_get_monotonic_time () < w->deadline) {
      g_autoptr (GError) error = NULL;
      g_autoptr (DsMessage) ev = ds_client_read (c, 1000, &error);
      if (ev)
        w->ok++;
      else if (!g_error_matches (error, G_IO_ERROR, G_IO_ERROR_TIMED_OUT)) {
        fail (w, error->message);
        return NULL;
      }
    }
    break;
  }
  case ROLE_HANGUP_MID_PAYLOAD:
    /* Asks for a result and closes before reading its payload; over and over. */
    while (g_get_monotonic_time () < w->deadline) {
      g_autoptr (DsClient) c2 = ds_client_connect (w->daemon->socket_path, NULL);
      if (!c2)
        continue;
      g_autoptr (DsMessage) s = ds_client_call (c2, "subscribe", NULL, NULL, NULL, NULL);
      g_usleep (50000);
      w->ok++;
    }
    break;
  case ROLE_GARBAGE: {
    GSocketClient *sc = g_socket_client_new ();
    g_autoptr (GSocketAddress) addr = g_unix_socket_address_new (w->daemon->socket_path);
    g_autoptr (GSocketConnection) conn = g_socket_client_connect (sc, G_SOCKET_CONNECTABLE (addr), NULL, NULL);
    g_object_unref (sc);
    if (!conn) {
      fail (w, "garbage connect");
      return NULL;
    }
    GOutputStream *out = g_io_stream_get_output_stream (G_IO_STREAM (conn));
    GInputStream *in = g_io_stream_get_input_stream (G_IO_STREAM (conn));
    g_autofree char *big = g_malloc (200000);
    memset (big, 'x', 200000);
    const char *bad[] = { "not json\n", "{\"cmd\": 5}\n", "[[[[[[[[[[[[[[[[]]]]]]]]]]]]]]]]\n",
                          "{\"cmd\":\"capture\",\"args\":{\"phases\":\"many\"}}\n" };
    char buf[4096];
    for (guint i = 0; g_get_monotonic_time () < w->deadline; i++) {
      gboolean oversized = i % 5 == 4;
      if (oversized) {
        if (!g_output_stream_write_all (out, big, 200000, NULL, NULL, NULL) ||
            !g_output_stream_write_all (out, "\n", 1, NULL, NULL, NULL))
          break;
      } else if (!g_output_stream_write_all (out, bad[i % 4], strlen (bad[i % 4]), NULL, NULL, NULL))
        break;
      gssize n = g_input_stream_read (in, buf, sizeof buf - 1, NULL, NULL);
      if (n <= 0) {
        fail (w, "daemon closed a connection that sent a bad line");
        return NULL;
      }
      buf[n] = 0;
      if (!strstr (buf, "\"ok\":false") && !strstr (buf, "\"ok\" : false")) {
        fail (w, "bad line not answered with an error");
        return NULL;
      }
      w->ok++;
    }
    break;
  }
  case ROLE_SILENT:
    g_usleep ((gulong) MAX (0, w->deadline - g_get_monotonic_time ()));
    break;
  case ROLE_N:
    break;
  }
  return NULL;
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  if (argc < 2) {
    fprintf (stderr, "usage: test_load SCENE [SECONDS]\n");
    return 2;
  }
  double seconds = argc > 2 ? g_ascii_strtod (argv[2], NULL) : 10;
  const guint64 queue_cap = 1 << 20;
  g_autofree char *conf = g_strdup_printf (
      /* 64 workers hold up to two connections each (garbage and hang-up clients), plus churn. */
      "[daemon]\nmax-clients=160\nmax-queued-bytes=%" G_GUINT64_FORMAT "\n"
      "[camera]\nbackend=sim\n[illuminator]\nbackend=sim\n[acquisition]\nphases=4\n"
      "[sim]\nscene=%s\n", queue_cap, argv[1]);
  TestDaemon *d = test_daemon_start (conf, NULL);
  g_autoptr (DsClient) ctl = test_daemon_connect (d);
  g_autoptr (DsMessage) st0 = test_daemon_call_ok (ctl, "start", NULL);
  /* A subscriber of the test's own that never reads, for the whole run: however slowly a
   * loaded (or sanitized) daemon completes sets, its queue must overflow and results be
   * dropped (counted), never buffered without bound. */
  g_autoptr (DsClient) stuck = test_daemon_connect (d);
  g_autoptr (DsMessage) stuck_sub = test_daemon_call_ok (stuck, "subscribe", NULL);
  /* Baseline once continuous acquisition runs with no other client. */
  g_usleep (1000000);
  guint64 rss0 = test_daemon_rss_kib (d);
  g_autoptr (DsMessage) s0 = test_daemon_call_ok (ctl, "status", NULL);
  gint64 sets0 = test_json_int (s0->reply->body, "sets_done");

  const guint n = 64;
  static const guint mix[ROLE_N] = { 8, 8, 12, 12, 8, 8, 8 }; /* sums to 64 */
  Worker workers[64];
  GThread *threads[64];
  gint64 deadline = g_get_monotonic_time () + (gint64) (seconds * G_USEC_PER_SEC);
  guint k = 0;
  for (guint r = 0; r < ROLE_N; r++)
    for (guint i = 0; i < mix[r]; i++, k++) {
      workers[k] = (Worker) { .daemon = d, .role = (Role) r, .deadline = deadline };
      threads[k] = g_thread_new ("client", worker_main, &workers[k]);
    }
  g_assert_cmpuint (k, ==, n);
  guint64 rss_peak = 0;
  while (g_get_monotonic_time () < deadline) {
    rss_peak = MAX (rss_peak, test_daemon_rss_kib (d));
    g_usleep (200000);
  }
  for (guint i = 0; i < n; i++)
    g_thread_join (threads[i]);
  guint ok[ROLE_N] = { 0 };
  for (guint i = 0; i < n; i++) {
    if (workers[i].failed)
      g_error ("client %u (role %d): %s", i, workers[i].role, workers[i].failure);
    ok[workers[i].role] += workers[i].ok;
  }
  g_autoptr (DsMessage) s1 = test_daemon_call_ok (ctl, "status", NULL);
  gint64 sets1 = test_json_int (s1->reply->body, "sets_done");
  /* The never-reading subscriber overflows after a few more results at the latest (its queue
   * holds at most queue_cap bytes of ~0.4 MB results, plus what the socket buffers). */
  for (guint i = 0; i < 600 && test_json_int (s1->reply->body, "clients.results_dropped") == 0; i++) {
    g_usleep (200000);
    g_clear_pointer (&s1, ds_message_free);
    s1 = test_daemon_call_ok (ctl, "status", NULL);
  }
  g_autoptr (DsMessage) stop = test_daemon_call_ok (ctl, "stop", NULL);
  printf ("load: %.0f s, sets %" G_GINT64_FORMAT ", captures %u, status calls %u, results read %u, "
          "bad lines answered %u; RSS %" G_GUINT64_FORMAT " KiB -> peak %" G_GUINT64_FORMAT " KiB\n",
          seconds, sets1 - sets0, ok[ROLE_CAPTURE], ok[ROLE_STATUS], ok[ROLE_SUBSCRIBER],
          ok[ROLE_GARBAGE], rss0, rss_peak);
  /* Every role was served. */
  g_assert_cmpuint (ok[ROLE_CAPTURE], >, 0);
  g_assert_cmpuint (ok[ROLE_STATUS], >, 0);
  g_assert_cmpuint (ok[ROLE_SUBSCRIBER], >, 0);
  g_assert_cmpuint (ok[ROLE_GARBAGE], >, 0);
  /* Acquisition went on (sets completed while the clients hammered the socket). */
  g_assert_cmpint (sets1, >, sets0);
  gint64 acquired = test_json_int (s1->reply->body, "frames.acquired");
  gint64 folded = test_json_int (s1->reply->body, "frames.folded");
  gint64 dropped = test_json_int (s1->reply->body, "frames.dropped");
  g_assert_cmpint (acquired, ==, folded + dropped);
  g_assert_cmpint (test_json_int (s1->reply->body, "clients.results_dropped"), >, 0);
  /* Memory: each of the 64 clients may hold at most its queue cap (plus the result images the
   * daemon itself keeps: a few). Anything beyond means a queue grew without bound. */
  guint64 bound_kib = rss0 + n * (queue_cap / 1024) + 64 * 1024;
  g_assert_cmpuint (rss_peak, <, bound_kib);
  g_assert_cmpint (test_daemon_stop (d), ==, 0);
  test_daemon_free (d);
  return 0;
}
