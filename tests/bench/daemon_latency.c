/* Benchmark (not a test): descatterd on the simulated lab.
 *  1. latency from the last frame of a set to the result arriving in a client, split into the
 *     daemon's finalize time and delivery (socket transfer of the payloads);
 *  2. daemon memory (RSS) against the number of subscribers in continuous mode.
 * Usage: bench-daemon SCENE [--quick]. Prints numbers; asserts nothing about time. */
#include <stdio.h>
#include <string.h>

#include "tests/common/daemon_harness.h"

static int
compare_double (const void *a, const void *b)
{
  double x = *(const double *) a, y = *(const double *) b;
  return (x > y) - (x < y);
}

int
main (int argc, char **argv)
{
  if (argc < 2) {
    fprintf (stderr, "usage: bench-daemon SCENE [--quick]\n");
    return 2;
  }
  gboolean quick = argc > 2 && strcmp (argv[2], "--quick") == 0;
  g_autofree char *conf = g_strdup_printf (
      "[daemon]\nmax-clients=64\n[camera]\nbackend=sim\n[illuminator]\nbackend=sim\n[acquisition]\nphases=8\n[sim]\nscene=%s\n", argv[1]);
  TestDaemon *d = test_daemon_start (conf, NULL);
  g_autoptr (DsClient) c = test_daemon_connect (d);

  guint n = quick ? 3 : 20;
  double lat[64], fin[64];
  guint64 bytes = 0;
  for (guint i = 0; i < n; i++) {
    g_autoptr (DsMessage) m = test_daemon_call_ok (c, "capture", NULL);
    gint64 now = g_get_monotonic_time ();
    gint64 last = test_json_int (m->reply->body, "monotonic_us.last_frame");
    gint64 done = test_json_int (m->reply->body, "monotonic_us.finished");
    lat[i] = (double) (now - last) / 1000.0;
    fin[i] = (double) (done - last) / 1000.0;
    bytes = 0;
    for (guint p = 0; p < m->reply->n_payloads; p++)
      bytes += m->reply->payloads[p].bytes;
  }
  qsort (lat, n, sizeof lat[0], compare_double);
  qsort (fin, n, sizeof fin[0], compare_double);
  g_autoptr (DsMessage) st = test_daemon_call_ok (c, "status", NULL);
  gint64 w = test_json_int (st->reply->body, "devices.camera.width");
  gint64 h = test_json_int (st->reply->body, "devices.camera.height");
  printf ("latency, last frame -> result in client (%" G_GINT64_FORMAT "x%" G_GINT64_FORMAT
          ", %.2f MB of payloads, %u sets): median %.2f ms (finalize %.2f ms, delivery %.2f ms), max %.2f ms\n",
          w, h, bytes / 1e6, n, lat[n / 2], fin[n / 2], lat[n / 2] - fin[n / 2], lat[n - 1]);
  printf ("  goal: <= 2 ms + transfer for 1 MP; scaled to 1 MP: finalize %.2f ms\n",
          fin[n / 2] * 1e6 / (double) (w * h));

  /* Memory against subscribers. */
  g_autoptr (DsMessage) started = test_daemon_call_ok (c, "start", NULL);
  guint counts[] = { 0, 8, 32 };
  GPtrArray *subs = g_ptr_array_new_with_free_func ((GDestroyNotify) ds_client_free);
  for (guint k = 0; k < G_N_ELEMENTS (counts); k++) {
    while (subs->len < counts[k]) {
      DsClient *s = test_daemon_connect (d);
      g_autoptr (DsMessage) ok = test_daemon_call_ok (s, "subscribe", NULL);
      g_ptr_array_add (subs, s);
    }
    /* Let a few results go out; the subscribers never read (worst case: full queues). */
    g_usleep (quick ? 1500000 : 5000000);
    printf ("memory: %2u stuck subscribers -> RSS %" G_GUINT64_FORMAT " KiB\n", counts[k], test_daemon_rss_kib (d));
  }
  g_ptr_array_unref (subs);
  g_autoptr (DsMessage) stopped = test_daemon_call_ok (c, "stop", NULL);
  test_daemon_stop (d);
  test_daemon_free (d);
  return 0;
}
