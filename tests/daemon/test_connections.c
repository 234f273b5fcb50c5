/* descatterd's connection policy (docs/protocol.md, "Connections") against a real daemon
 * process on the simulated lab: what a leaked connection, a misbehaving script, a slowloris
 * or an unauthenticated TCP peer can do to the lab's service (issue 10). Each test asserts
 * that a real client is still served, and how the others were told. */
#include <gio/gunixsocketaddress.h>
#include <glib/gstdio.h>
#include <signal.h>
#include <string.h>
#include <unistd.h>

#include "tests/common/daemon_harness.h"

static char *
sim_config (const char *daemon_extra)
{
  return g_strdup_printf ("[daemon]\n%s\n[camera]\nbackend=sim\n[illuminator]\nbackend=sim\n"
                          "[acquisition]\nphases=4\n[sim]\nscene=%s\n",
                          daemon_extra ? daemon_extra : "", SCENE_FILE);
}

static GSocketConnection *
raw_connect (GSocketAddress *addr)
{
  g_autoptr (GSocketClient) sc = g_socket_client_new ();
  g_autoptr (GError) error = NULL;
  GSocketConnection *c = g_socket_client_connect (sc, G_SOCKET_CONNECTABLE (addr), NULL, &error);
  g_assert_no_error (error);
  return c;
}

static GSocketConnection *
raw_connect_unix (TestDaemon *d)
{
  g_autoptr (GSocketAddress) addr = g_unix_socket_address_new (d->socket_path);
  return raw_connect (addr);
}

static void
raw_send (GSocketConnection *c, const char *text)
{
  g_autoptr (GError) error = NULL;
  GOutputStream *out = g_io_stream_get_output_stream (G_IO_STREAM (c));
  g_output_stream_write_all (out, text, strlen (text), NULL, NULL, &error);
  g_assert_no_error (error);
}

typedef enum { READ_LINE, READ_EOF, READ_TIMEOUT } ReadOutcome;

/* One line (without payloads), EOF or nothing within timeout_ms. Reads byte by byte so that
 * nothing after the line is consumed. */
static ReadOutcome
raw_read_line (GSocketConnection *c, guint timeout_ms, char **line)
{
  GSocket *sock = g_socket_connection_get_socket (c);
  GString *s = g_string_new (NULL);
  gint64 deadline = g_get_monotonic_time () + (gint64) timeout_ms * 1000;
  for (;;) {
    gint64 left = deadline - g_get_monotonic_time ();
    if (left <= 0 || !g_socket_condition_timed_wait (sock, G_IO_IN | G_IO_HUP, left, NULL, NULL)) {
      g_string_free (s, TRUE);
      return READ_TIMEOUT;
    }
    char ch;
    gssize n = g_socket_receive (sock, &ch, 1, NULL, NULL);
    if (n <= 0) {
      g_string_free (s, TRUE);
      return READ_EOF;
    }
    if (ch == '\n')
      break;
    g_string_append_c (s, ch);
  }
  if (line)
    *line = g_string_free (s, FALSE);
  else
    g_string_free (s, TRUE);
  return READ_LINE;
}

/* Reads the error line the server says goodbye with, then expects EOF. */
static void
expect_dismissed (GSocketConnection *c, guint timeout_ms, DsProtocolError code)
{
  g_autofree char *line = NULL;
  ReadOutcome o = raw_read_line (c, timeout_ms, &line);
  g_assert_cmpint (o, ==, READ_LINE);
  g_autoptr (GError) error = NULL;
  g_autoptr (DsReply) r = ds_reply_parse (line, strlen (line), &error);
  g_assert_no_error (error);
  g_assert_false (r->ok);
  g_assert_cmpint (r->error_code, ==, code);
  g_assert_cmpint (raw_read_line (c, timeout_ms, NULL), ==, READ_EOF);
}

static JsonNode *
status_of (TestDaemon *d)
{
  g_autoptr (DsClient) c = test_daemon_connect (d);
  g_autoptr (DsMessage) m = test_daemon_call_ok (c, "status", NULL);
  return json_node_ref (m->reply->body);
}

/* 300 strictly sequential clients (connect, one request, close — half of them without
 * reading the reply) while continuous acquisition keeps the main loop busy: each frees its
 * place at once, so none is refused even with four places. */
static void
test_sequential_clients_free_their_place (void)
{
  g_autofree char *conf = sim_config ("max-clients=4");
  TestDaemon *d = test_daemon_start (conf, NULL);
  g_autoptr (DsClient) ctl = test_daemon_connect (d);
  g_autoptr (DsMessage) st = test_daemon_call_ok (ctl, "start", NULL);
  g_autoptr (DsClient) sub = test_daemon_connect (d);
  g_autoptr (DsMessage) su = test_daemon_call_ok (sub, "subscribe", NULL);
  guint refused = 0;
  for (guint i = 0; i < 300; i++) {
    GSocketConnection *c = raw_connect_unix (d);
    raw_send (c, "{\"id\":1,\"cmd\":\"status\"}\n");
    if (i % 2 == 0) {
      g_autofree char *line = NULL;
      g_assert_cmpint (raw_read_line (c, 10000, &line), ==, READ_LINE);
      refused += strstr (line, "\"ok\":false") != NULL;
    }
    g_object_unref (c);
  }
  g_autoptr (JsonNode) s = status_of (d);
  g_test_message ("300 sequential clients: %u refused, %" G_GINT64_FORMAT " refused in all", refused,
                  test_json_int (s, "clients.refused"));
  g_assert_cmpuint (refused, ==, 0);
  g_assert_cmpint (test_json_int (s, "clients.refused"), ==, 0);
  g_autoptr (DsMessage) sp = test_daemon_call_ok (ctl, "stop", NULL);
  g_assert_cmpint (test_daemon_stop (d), ==, 0);
  test_daemon_free (d);
}

/* 64 connections that never send anything (twice max-clients) cannot lock the lab out: the
 * one quiet longest makes room, a real client is served, the displaced are told `limit`. */
static void
test_silent_connections_do_not_lock_out (void)
{
  g_autofree char *conf = sim_config ("max-clients=32");
  TestDaemon *d = test_daemon_start (conf, NULL);
  GSocketConnection *silent[64];
  for (guint i = 0; i < G_N_ELEMENTS (silent); i++)
    silent[i] = raw_connect_unix (d);
  /* Newcomers are protected for a second (they get that long to send a request); after it
   * every silent one is fair game. The second runs from the daemon's accept, which on a loaded
   * machine can come well after the connect: a newcomer refused `limit` (none quiet that long
   * yet) tries again until one is served; a lab locked out for good fails at the bound. */
  g_usleep (1200 * 1000);
  gint64 give_up = g_get_monotonic_time () + 30 * G_USEC_PER_SEC;
  g_autoptr (DsReply) r = NULL;
  for (;;) {
    GSocketConnection *c = raw_connect_unix (d);
    raw_send (c, "{\"id\":1,\"cmd\":\"status\"}\n");
    g_autofree char *line = NULL;
    g_assert_cmpint (raw_read_line (c, 20000, &line), ==, READ_LINE);
    g_object_unref (c);
    g_autoptr (GError) error = NULL;
    r = ds_reply_parse (line, strlen (line), &error);
    g_assert_no_error (error);
    if (r->ok)
      break;
    g_assert_cmpint (r->error_code, ==, DS_PROTOCOL_ERROR_LIMIT);
    g_assert_cmpint (g_get_monotonic_time (), <, give_up);
    g_clear_pointer (&r, ds_reply_free);
    g_usleep (100 * 1000);
  }
  gint64 evicted = test_json_int (r->body, "clients.evicted");
  g_test_message ("64 silent connections, max-clients 32: %" G_GINT64_FORMAT " evicted, %" G_GINT64_FORMAT
                  " refused", evicted, test_json_int (r->body, "clients.refused"));
  g_assert_cmpint (test_json_int (r->body, "clients.connected"), <=, 32);
  /* The first silent ones were displaced with a reason. */
  expect_dismissed (silent[0], 5000, DS_PROTOCOL_ERROR_LIMIT);
  for (guint i = 0; i < G_N_ELEMENTS (silent); i++)
    g_object_unref (silent[i]);
  g_assert_cmpint (test_daemon_stop (d), ==, 0);
  test_daemon_free (d);
}

/* idle-timeout-ms: a silent connection and a slowloris (one byte every 100 ms, never a whole
 * line) are closed; a subscriber and a client waiting for its capture are not. */
static void
test_idle_timeout (void)
{
  g_autofree char *conf = sim_config ("idle-timeout-ms=600");
  TestDaemon *d = test_daemon_start (conf, NULL);
  GSocketConnection *silent = raw_connect_unix (d);
  GSocketConnection *slow = raw_connect_unix (d);
  g_autoptr (DsClient) sub = test_daemon_connect (d);
  g_autoptr (DsMessage) su = test_daemon_call_ok (sub, "subscribe", NULL);
  const char *request = "{\"id\":1,\"cmd\":\"status\",\"args\":{}}                                        \n";
  gboolean slow_closed = FALSE;
  for (const char *p = request; *p && !slow_closed; p++) {
    GOutputStream *out = g_io_stream_get_output_stream (G_IO_STREAM (slow));
    if (g_output_stream_write (out, p, 1, NULL, NULL) != 1)
      slow_closed = TRUE;
    else if (raw_read_line (slow, 100, NULL) != READ_TIMEOUT)
      slow_closed = TRUE; /* the error line, then EOF */
  }
  /* Closed long before its request could complete (it would take 7 s). */
  g_assert_true (slow_closed);
  expect_dismissed (silent, 5000, DS_PROTOCOL_ERROR_LIMIT);
  /* The subscriber was quiet all along and is still served. */
  g_autoptr (DsMessage) st = test_daemon_call_ok (sub, "status", NULL);
  g_assert_cmpint (test_json_int (st->reply->body, "clients.timed_out"), >=, 2);
  /* A capture that takes longer than the idle timeout keeps its connection. */
  g_autoptr (DsClient) cap = test_daemon_connect (d);
  g_autoptr (JsonObject) args = json_object_new ();
  json_object_set_int_member (args, "averages", 4);
  json_object_set_int_member (args, "phases", 4);
  gint64 t0 = g_get_monotonic_time ();
  g_autoptr (DsMessage) m = test_daemon_call_ok (cap, "capture", args);
  g_test_message ("capture took %.2f s with idle-timeout-ms 600", (double) (g_get_monotonic_time () - t0) / 1e6);
  g_object_unref (silent);
  g_object_unref (slow);
  g_assert_cmpint (test_daemon_stop (d), ==, 0);
  test_daemon_free (d);
}

/* Unauthenticated TCP connections are closed after auth-timeout-ms and can never take the
 * places reserved for local clients: with 20 of them open, a UNIX client is served at once. */
/* Each read only guards against a daemon that never answers: a loaded machine (load 13, the
 * other suites running) delayed one answer past 5 s. */
#define READ_GUARD_MS 30000

static void
test_tcp_cannot_lock_out_unix (void)
{
  g_autoptr (GError) error = NULL;
  g_autofree char *dir = g_dir_make_tmp ("descatterd-token-XXXXXX", &error);
  g_assert_no_error (error);
  g_autofree char *token_path = g_build_filename (dir, "token", NULL);
  g_assert_true (g_file_set_contents (token_path, "0123456789abcdef-token\n", -1, NULL));
  guint port = 30000 + (guint) (getpid () % 20000);
  g_autofree char *extra = g_strdup_printf ("max-clients=8\nmax-tcp-clients=4\nauth-timeout-ms=800\n"
                                            "tcp-listen=127.0.0.1:%u\ntcp-token-file=%s", port, token_path);
  g_autofree char *conf = sim_config (extra);
  TestDaemon *d = test_daemon_start (conf, NULL);
  g_autoptr (GSocketAddress) tcp_addr = g_inet_socket_address_new_from_string ("127.0.0.1", port);
  GSocketConnection *tcp[20];
  for (guint i = 0; i < G_N_ELEMENTS (tcp); i++)
    tcp[i] = raw_connect (tcp_addr);
  /* At once, before any timeout: the UNIX places are free. */
  GSocketConnection *local[4];
  for (guint i = 0; i < G_N_ELEMENTS (local); i++) {
    local[i] = raw_connect_unix (d);
    raw_send (local[i], "{\"id\":1,\"cmd\":\"hello\"}\n");
    g_autofree char *line = NULL;
    g_assert_cmpint (raw_read_line (local[i], READ_GUARD_MS, &line), ==, READ_LINE);
    g_assert_nonnull (strstr (line, "\"ok\":true"));
  }
  /* TCP beyond its four places was refused; the four it got owe the token and are closed
   * once auth-timeout-ms has passed. */
  guint refused = 0, timed_out = 0;
  for (guint i = 0; i < G_N_ELEMENTS (tcp); i++) {
    g_autofree char *line = NULL;
    g_assert_cmpint (raw_read_line (tcp[i], READ_GUARD_MS, &line), ==, READ_LINE);
    g_autoptr (DsReply) r = ds_reply_parse (line, strlen (line), &error);
    g_assert_no_error (error);
    g_assert_false (r->ok);
    refused += r->error_code == DS_PROTOCOL_ERROR_LIMIT;
    timed_out += r->error_code == DS_PROTOCOL_ERROR_UNAUTHORIZED;
    g_assert_cmpint (raw_read_line (tcp[i], READ_GUARD_MS, NULL), ==, READ_EOF);
  }
  g_test_message ("20 silent TCP connections, 4 TCP places: %u refused, %u closed without token", refused,
                  timed_out);
  g_assert_cmpuint (refused + timed_out, ==, G_N_ELEMENTS (tcp));
  g_assert_cmpuint (timed_out, <=, 4);
  g_assert_cmpuint (timed_out, >=, 1);
  /* A TCP client with the token is served now that the places are free. */
  GSocketConnection *good = raw_connect (tcp_addr);
  raw_send (good, "{\"id\":1,\"cmd\":\"hello\",\"args\":{\"token\":\"0123456789abcdef-token\"}}\n"
                  "{\"id\":2,\"cmd\":\"status\"}\n");
  for (guint i = 0; i < 2; i++) {
    g_autofree char *line = NULL;
    g_assert_cmpint (raw_read_line (good, READ_GUARD_MS, &line), ==, READ_LINE);
    g_assert_nonnull (strstr (line, "\"ok\":true"));
  }
  g_object_unref (good);
  for (guint i = 0; i < G_N_ELEMENTS (tcp); i++)
    g_object_unref (tcp[i]);
  for (guint i = 0; i < G_N_ELEMENTS (local); i++)
    g_object_unref (local[i]);
  g_assert_cmpint (test_daemon_stop (d), ==, 0);
  test_daemon_free (d);
  g_unlink (token_path);
  g_rmdir (dir);
}

/* Reads one whole message (line and payloads); FALSE at EOF or after timeout_ms, with what
 * was missing in *why. */
static DsReply *
raw_read_message (GSocketConnection *c, guint timeout_ms, char **why)
{
  g_autofree char *line = NULL;
  ReadOutcome o = raw_read_line (c, timeout_ms, &line);
  if (o != READ_LINE) {
    *why = g_strdup (o == READ_EOF ? "EOF instead of a reply" : "no reply");
    return NULL;
  }
  g_autoptr (GError) error = NULL;
  g_autoptr (DsReply) r = ds_reply_parse (line, strlen (line), &error);
  g_assert_no_error (error);
  GInputStream *in = g_io_stream_get_input_stream (G_IO_STREAM (c));
  for (guint i = 0; i < r->n_payloads; i++) {
    g_autofree guint8 *buf = g_malloc (r->payloads[i].bytes);
    gsize got = 0;
    g_input_stream_read_all (in, buf, r->payloads[i].bytes, &got, NULL, NULL);
    if (got != r->payloads[i].bytes) {
      *why = g_strdup_printf ("payload %s cut after %zu of %" G_GUINT64_FORMAT " bytes", r->payloads[i].name,
                              got, r->payloads[i].bytes);
      return NULL;
    }
  }
  return g_steal_pointer (&r);
}

/* SIGTERM while clients wait for captures (one running, the others queued, none reading yet,
 * so that a finished result is still in its queue): every one of them gets its whole reply,
 * the result or `cancelled`, never a bare or early EOF. Repeated at several moments. */
static void
test_sigterm_answers_every_waiting_capture (void)
{
  g_autofree char *conf = sim_config (NULL);
  guint cancelled = 0, results = 0;
  for (guint round = 0; round < 6; round++) {
    TestDaemon *d = test_daemon_start (conf, NULL);
    GSocketConnection *c[4];
    for (guint i = 0; i < G_N_ELEMENTS (c); i++) {
      c[i] = raw_connect_unix (d);
      raw_send (c[i], "{\"id\":\"waiting\",\"cmd\":\"capture\",\"args\":{\"phases\":4}}\n");
    }
    g_usleep (round * 200 * 1000);
    g_subprocess_send_signal (d->proc, SIGTERM);
    for (guint i = 0; i < G_N_ELEMENTS (c); i++) {
      g_autofree char *why = NULL;
      g_autoptr (DsReply) r = raw_read_message (c[i], 20000, &why);
      if (!r)
        g_error ("round %u, client %u: %s", round, i, why);
      g_assert_cmpstr (json_node_get_string (r->id), ==, "waiting");
      if (r->ok)
        results++;
      else {
        g_assert_cmpint (r->error_code, ==, DS_PROTOCOL_ERROR_CANCELLED);
        cancelled++;
      }
      g_object_unref (c[i]);
    }
    /* It stops by itself after the one SIGTERM, with a clean exit. */
    g_autoptr (GError) error = NULL;
    g_assert_true (g_subprocess_wait (d->proc, NULL, &error));
    g_assert_true (g_subprocess_get_if_exited (d->proc));
    g_assert_cmpint (g_subprocess_get_exit_status (d->proc), ==, 0);
    g_clear_object (&d->proc);
    test_daemon_free (d);
  }
  g_test_message ("SIGTERM with 4 waiting captures, 6 rounds: %u results, %u cancelled", results, cancelled);
  g_assert_cmpuint (cancelled, >, 0);
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  signal (SIGPIPE, SIG_IGN);
  g_test_add_func ("/connections/sequential-clients", test_sequential_clients_free_their_place);
  g_test_add_func ("/connections/silent-lockout", test_silent_connections_do_not_lock_out);
  g_test_add_func ("/connections/idle-timeout", test_idle_timeout);
  g_test_add_func ("/connections/tcp-cannot-lock-out-unix", test_tcp_cannot_lock_out_unix);
  g_test_add_func ("/connections/sigterm-answers-waiting-captures", test_sigterm_answers_every_waiting_capture);
  return g_test_run ();
}
