/* descatter-labsim's simulated GPIO chip (drivers/labsim/gpio_chip_server.c) and the line backend
 * that reaches it over its UNIX socket (drivers/gpio/gpio_lines_socket.c), in-process: the
 * protocol of drivers/gpio/gpio_wire.h spoken by hand (every malformed request answered with a
 * clear error, the chip still serving afterwards), the kernel's semantics (busy, out of range,
 * released on close), the edges a trigger pulse makes, and the peer going away and coming back
 * or falling silent (typed failure, bounded, then recovery). */
#include <errno.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <glib/gstdio.h>
#include <unistd.h>

#include "drivers/gpio/gpio_backends.h"
#include "drivers/labsim/gpio_chip_server.h"
#include "drivers/labsim/gpio_light.h"

typedef struct {
  GMutex lock;
  guint rising[8], falling[8];
} Edges;

static void
on_edge (gpointer data, guint offset, gboolean rising)
{
  Edges *e = data;
  g_mutex_lock (&e->lock);
  if (offset < 8)
    (rising ? e->rising : e->falling)[offset]++;
  g_mutex_unlock (&e->lock);
}

/* Where a test's chip listens: a fresh folder, the socket in it, and the chip's name for a
 * backend (labsim:PATH). The folder is removed with it (the chip removes its socket). */
typedef struct {
  char *dir, *path, *chip_name;
} ChipPlace;

static ChipPlace
chip_place (void)
{
  ChipPlace p;
  p.dir = g_dir_make_tmp ("gpiochip-XXXXXX", NULL);
  g_assert_nonnull (p.dir);
  p.path = g_build_filename (p.dir, "gpio.sock", NULL);
  p.chip_name = g_strdup_printf ("labsim:%s", p.path);
  return p;
}

static void
chip_place_clear (ChipPlace *p)
{
  g_rmdir (p->dir);
  g_free (p->dir);
  g_free (p->path);
  g_free (p->chip_name);
}
G_DEFINE_AUTO_CLEANUP_CLEAR_FUNC (ChipPlace, chip_place_clear)

/* A chip of 8 lines serving at the place, counting its edges in e. */
static DsGpioChipServer *
chip_serve (const ChipPlace *p, const char *label, Edges *e)
{
  g_autoptr (GError) error = NULL;
  DsGpioChipServer *chip = ds_gpio_chip_server_new (p->path, 8, label, on_edge, e, &error);
  g_assert_no_error (error);
  return chip;
}

static int
raw_connect (const char *path)
{
  struct sockaddr_un a = { .sun_family = AF_UNIX };
  g_strlcpy (a.sun_path, path, sizeof a.sun_path);
  int fd = socket (AF_UNIX, SOCK_STREAM, 0);
  g_assert_cmpint (connect (fd, (struct sockaddr *) &a, sizeof a), ==, 0);
  struct timeval tv = { .tv_sec = 5 }; /* a missing answer fails the test instead of hanging it */
  setsockopt (fd, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
  return fd;
}

/* Sends bytes as given and returns the one reply line, or NULL at EOF. */
static char *
raw_call_bytes (int fd, const char *bytes, gsize len)
{
  g_assert_cmpint (send (fd, bytes, len, MSG_NOSIGNAL), ==, (gssize) len);
  GString *out = g_string_new (NULL);
  char c;
  gssize r;
  while ((r = recv (fd, &c, 1, 0)) == 1 && c != '\n')
    g_string_append_c (out, c);
  g_assert_cmpint (r, >=, 0); /* not a receive timeout */
  if (r == 0 && out->len == 0) {
    g_string_free (out, TRUE);
    return NULL;
  }
  return g_string_free (out, FALSE);
}

static char *
raw_call (int fd, const char *request)
{
  g_autofree char *line = g_strdup_printf ("%s\n", request);
  return raw_call_bytes (fd, line, strlen (line));
}

#define ASSERT_REPLY(fd, request, prefix)                                                          \
  do {                                                                                             \
    g_autofree char *r_ = raw_call (fd, request);                                                  \
    g_assert_nonnull (r_);                                                                         \
    if (!g_str_has_prefix (r_, prefix))                                                            \
      g_error ("\"%s\" -> \"%s\", expected \"%s...\"", request, r_, prefix);                      \
  } while (0)

static void
test_protocol (void)
{
  g_auto (ChipPlace) place = chip_place ();
  const char *path = place.path;
  Edges e = { 0 };
  DsGpioChipServer *chip = chip_serve (&place, "test-chip", &e);

  int a = raw_connect (path);
  ASSERT_REPLY (a, "info", "ok lines=8 label=test-chip");
  ASSERT_REPLY (a, "set 1", "err state set before request");
  ASSERT_REPLY (a, "get", "err state");
  ASSERT_REPLY (a, "", "err invalid empty request");
  ASSERT_REPLY (a, "frobnicate 1", "err invalid unknown request \"frobnicate\"");
  ASSERT_REPLY (a, "request t", "err invalid expected: request CONSUMER");
  ASSERT_REPLY (a, "request t 0,99 0,0", "err range line 99 beyond the chip's 8 lines");
  ASSERT_REPLY (a, "request t 8 0", "err range line 8");
  ASSERT_REPLY (a, "request t 1,1 0,0", "err invalid line 1 requested twice");
  ASSERT_REPLY (a, "request t 1,2 0", "err invalid values \"0\": expected 2 of 0 or 1");
  ASSERT_REPLY (a, "request t 1,2 0,2", "err invalid values");
  ASSERT_REPLY (a, "request t -1 0", "err invalid offsets");
  ASSERT_REPLY (a, "request t 1,,2 0,0", "err invalid offsets");
  ASSERT_REPLY (a, "request t 99999999999999999999 0", "err invalid offsets");
  ASSERT_REPLY (a, "request t\t1 0", "err invalid");
  {
    g_autofree char *r = raw_call_bytes (a, "get\0junk\n", 9);
    g_assert_true (g_str_has_prefix (r, "err invalid NUL byte"));
  }
  /* Nothing refused may have driven a line. */
  for (guint i = 0; i < 8; i++)
    g_assert_cmpint (ds_gpio_chip_server_level (chip, i), ==, 0);
  g_assert_cmpuint (e.rising[1] + e.rising[2], ==, 0);

  ASSERT_REPLY (a, "request first 1,2 1,0", "ok 8");
  g_assert_cmpint (ds_gpio_chip_server_level (chip, 1), ==, 1);
  g_assert_cmpint (ds_gpio_chip_server_level (chip, 2), ==, 0);
  ASSERT_REPLY (a, "get", "ok 1,0");
  ASSERT_REPLY (a, "set 0,1", "ok");
  ASSERT_REPLY (a, "get", "ok 0,1");
  ASSERT_REPLY (a, "set 1", "err invalid expected: set VAL[,VAL...] with 2 values");
  ASSERT_REPLY (a, "set 1,1,1", "err invalid");
  ASSERT_REPLY (a, "set 0,7", "err invalid");
  ASSERT_REPLY (a, "get", "ok 0,1"); /* the refused sets changed nothing */
  ASSERT_REPLY (a, "request again 3 0", "err state this connection already holds lines");
  g_assert_cmpuint (e.rising[1], ==, 1);
  g_assert_cmpuint (e.falling[1], ==, 1);
  g_assert_cmpuint (e.rising[2], ==, 1);

  /* Another connection: line 2 busy, naming its holder; line 3 free. */
  int b = raw_connect (path);
  ASSERT_REPLY (b, "request second 3,2 0,0", "err busy line 2 is busy: held by \"first\"");
  ASSERT_REPLY (b, "request second 3 1", "ok 8");
  /* Closing a connection releases its lines (levels kept): now they can be requested. */
  close (a);
  int c = raw_connect (path);
  ASSERT_REPLY (c, "info", "ok"); /* the chip has seen the close before it answers c */
  ASSERT_REPLY (c, "request third 1,2 0,1", "ok 8");

  /* Hostile bytes: an over-long line is refused and its connection closed; the chip still serves. */
  int d = raw_connect (path);
  char junk[700];
  memset (junk, 'x', sizeof junk);
  g_autofree char *r = raw_call_bytes (d, junk, sizeof junk);
  g_assert_true (g_str_has_prefix (r, "err invalid request longer than 512 bytes"));
  char tail;
  gssize tail_r = recv (d, &tail, 1, 0); /* closed by the chip (reset: it left bytes unread) */
  g_assert_true (tail_r == 0 || (tail_r < 0 && errno == ECONNRESET));
  close (d);
  GRand *rand = g_rand_new_with_seed (16);
  for (guint i = 0; i < 300; i++) {
    int f = raw_connect (path);
    char buf[64];
    guint n = (guint) g_rand_int_range (rand, 1, sizeof buf);
    for (guint k = 0; k < n; k++)
      buf[k] = (char) g_rand_int_range (rand, 1, 256);
    buf[n - 1] = '\n';
    if (send (f, buf, n, MSG_NOSIGNAL) < 0)
      g_error ("send: %s", g_strerror (errno));
    close (f);
  }
  g_rand_free (rand);
  ASSERT_REPLY (b, "get", "ok 1");
  ASSERT_REPLY (c, "get", "ok 0,1");
  DsGpioChipStats st;
  ds_gpio_chip_server_stats (chip, &st);
  g_assert_cmpuint (st.requests_ok, ==, 3);
  close (b);
  close (c);
  ds_gpio_chip_server_free (chip);
  g_assert_false (g_file_test (path, G_FILE_TEST_EXISTS)); /* the socket is removed */
}

/* The trigger backend over the socket: each fire is one rising and one falling edge on the
 * chip's line, in the order the polarity says; the chip's level is idle in between. */
static void
test_trigger_edges (void)
{
  g_auto (ChipPlace) place = chip_place ();
  const char *chip_name = place.chip_name;
  Edges e = { 0 };
  g_autoptr (GError) error = NULL;
  DsGpioChipServer *chip = chip_serve (&place, NULL, &e);

  DsTrigger *high = ds_gpio_trigger_open_from_config (chip_name, 0, 50, FALSE, &error);
  g_assert_no_error (error);
  DsTrigger *low = ds_gpio_trigger_open_from_config (chip_name, 5, 50, TRUE, &error);
  g_assert_no_error (error);
  g_assert_cmpint (ds_gpio_chip_server_level (chip, 5), ==, 1); /* active-low idles high at once */
  g_assert_cmpuint (e.rising[5], ==, 1);
  for (guint i = 0; i < 5; i++) {
    g_assert_true (high->ops->fire (high->backend, &error));
    g_assert_no_error (error);
    g_assert_true (low->ops->fire (low->backend, &error));
    g_assert_no_error (error);
  }
  g_assert_cmpuint (e.rising[0], ==, 5);
  g_assert_cmpuint (e.falling[0], ==, 5);
  g_assert_cmpuint (e.falling[5], ==, 5);
  g_assert_cmpuint (e.rising[5], ==, 1 + 5);
  g_assert_cmpint (ds_gpio_chip_server_level (chip, 0), ==, 0);
  g_assert_cmpint (ds_gpio_chip_server_level (chip, 5), ==, 1);

  /* The GPIO illuminator drives the chip's lines as well: 4 stripe lines and an enable line. */
  DsIlluminator *ill = ds_gpio_illuminator_open_from_config (chip_name, "1,2,3,4", 6, &error);
  g_assert_no_error (error);
  ds_illuminator_close (ill);

  /* Busy (another consumer holds line 0) and out of range, with the kernel's codes. */
  DsTrigger *again = ds_gpio_trigger_open_from_config (chip_name, 0, 50, FALSE, &error);
  g_assert_null (again);
  g_assert_error (error, DS_TRIGGER_ERROR, DS_DEVICE_ERROR_BUSY);
  g_assert_nonnull (strstr (error->message, "line 0 is busy: held by \"descatter-trigger\""));
  g_clear_error (&error);
  again = ds_gpio_trigger_open_from_config (chip_name, 8, 50, FALSE, &error);
  g_assert_null (again);
  g_assert_error (error, DS_TRIGGER_ERROR, DS_DEVICE_ERROR_DISCONNECTED);
  g_assert_nonnull (strstr (error->message, "line 8 beyond the chip's 8 lines"));
  g_clear_error (&error);
  ds_trigger_close (high);
  again = ds_gpio_trigger_open_from_config (chip_name, 0, 50, FALSE, &error); /* released: free again */
  g_assert_no_error (error);
  ds_trigger_close (again);
  ds_trigger_close (low);
  ds_gpio_chip_server_free (chip);
}

static void
test_bad_chip (void)
{
  g_autoptr (GError) error = NULL;
  DsTrigger *t = ds_gpio_trigger_open_from_config ("labsim:/nonexistent/gpio.sock", 0, 50, FALSE, &error);
  g_assert_null (t);
  g_assert_error (error, DS_TRIGGER_ERROR, DS_DEVICE_ERROR_DISCONNECTED);
  g_assert_nonnull (strstr (error->message, "cannot open the chip"));
  g_assert_nonnull (strstr (error->message, "--gpio-chip /nonexistent/gpio.sock"));
  g_clear_error (&error);
  t = ds_gpio_trigger_open_from_config ("labsim:relative.sock", 0, 50, FALSE, &error);
  g_assert_null (t);
  g_assert_error (error, DS_TRIGGER_ERROR, DS_DEVICE_ERROR_INVALID);
  g_assert_nonnull (strstr (error->message, "absolute path"));
}

/* The chip goes away between two pulses and comes back: the fire in between fails
 * DISCONNECTED, the next one after the return requests the line again and pulses. */
static void
test_peer_gone_and_back (void)
{
  g_auto (ChipPlace) place = chip_place ();
  const char *chip_name = place.chip_name;
  Edges e = { 0 };
  g_autoptr (GError) error = NULL;
  DsGpioChipServer *chip = chip_serve (&place, NULL, &e);
  DsTrigger *t = ds_gpio_trigger_open_from_config (chip_name, 0, 50, FALSE, &error);
  g_assert_no_error (error);
  g_assert_true (t->ops->fire (t->backend, &error));
  ds_gpio_chip_server_free (chip);

  g_assert_false (t->ops->fire (t->backend, &error));
  g_assert_error (error, DS_TRIGGER_ERROR, DS_DEVICE_ERROR_DISCONNECTED);
  g_assert_nonnull (strstr (error->message, "went away"));
  g_clear_error (&error);
  g_assert_false (t->ops->fire (t->backend, &error)); /* still gone: the new request fails */
  g_assert_error (error, DS_TRIGGER_ERROR, DS_DEVICE_ERROR_DISCONNECTED);
  g_assert_nonnull (strstr (error->message, "cannot open the chip"));
  g_clear_error (&error);

  Edges e2 = { 0 };
  chip = chip_serve (&place, NULL, &e2);
  g_assert_true (t->ops->fire (t->backend, &error));
  g_assert_no_error (error);
  g_assert_true (t->ops->fire (t->backend, &error));
  g_assert_cmpuint (e2.rising[0], ==, 2);
  g_assert_cmpuint (e2.falling[0], ==, 2);
  ds_trigger_close (t);
  ds_gpio_chip_server_free (chip);
}

/* A socket that accepts and never answers (a wedged chip): the request fails TIMEOUT instead of
 * hanging. */
static void
test_silent_peer (void)
{
  g_auto (ChipPlace) place = chip_place ();
  struct sockaddr_un a = { .sun_family = AF_UNIX };
  g_strlcpy (a.sun_path, place.path, sizeof a.sun_path);
  int fd = socket (AF_UNIX, SOCK_STREAM, 0);
  g_assert_cmpint (bind (fd, (struct sockaddr *) &a, sizeof a), ==, 0);
  g_assert_cmpint (listen (fd, 4), ==, 0); /* connections queue; nobody reads them */
  g_autoptr (GError) error = NULL;
  DsTrigger *t = ds_gpio_trigger_open_from_config (place.chip_name, 0, 50, FALSE, &error);
  g_assert_null (t);
  g_assert_error (error, DS_TRIGGER_ERROR, DS_DEVICE_ERROR_TIMEOUT);
  g_assert_nonnull (strstr (error->message, "no answer within"));
  close (fd);
  unlink (place.path);
}

/* labsim reads the light of the stripe lines the GPIO illuminator drives: for every phase of
 * several geometries, the lit run's centre is k/N of the period (the illuminator's mapping,
 * written as a condition per line, against labsim's reading, a run and its centre). */
static void
test_light_from_lines (void)
{
  /* duty x L even: the lit groups tile [k/N - duty/2, k/N + duty/2) exactly. */
  const struct { guint L, N; double duty; } geo[] = { { 8, 4, 0.5 }, { 6, 3, 1.0 / 3 }, { 12, 6, 0.5 },
                                                       { 16, 8, 0.75 }, { 4, 2, 0.5 }, { 12, 4, 1.0 / 6 } };
  for (guint g = 0; g < G_N_ELEMENTS (geo); g++)
    for (guint k = 0; k < geo[g].N; k++) {
      int v[DS_GPIO_MAX_LINES];
      g_autoptr (GError) error = NULL;
      g_assert_true (ds_gpio_stripe_values (geo[g].L, geo[g].N, geo[g].duty, k, v, &error));
      guint phase = 99, n_phases = 0;
      g_assert_cmpint (ds_gpio_light_read (v, geo[g].L, &phase, &n_phases), ==, DS_GPIO_LIGHT_STRIPE);
      /* phase / n_phases == k / N, compared in integers */
      if (phase * geo[g].N != k * n_phases)
        g_error ("L=%u N=%u duty=%g phase %u: labsim reads %u/%u", geo[g].L, geo[g].N, geo[g].duty, k, phase,
                 n_phases);
    }
  /* An odd number of lit groups cannot be centred on a group boundary: 12 lines, duty 1/4,
   * phase 0 lights lines 11, 0, 1, whose light [11/12, 14/12) is centred half a group late. */
  int odd[DS_GPIO_MAX_LINES];
  g_assert_true (ds_gpio_stripe_values (12, 4, 0.25, 0, odd, NULL));
  guint odd_phase, odd_n;
  g_assert_cmpint (ds_gpio_light_read (odd, 12, &odd_phase, &odd_n), ==, DS_GPIO_LIGHT_STRIPE);
  g_assert_cmpuint (odd_phase, ==, 1);
  g_assert_cmpuint (odd_n, ==, 24);
  const int dark[4] = { 0, 0, 0, 0 }, all[4] = { 1, 1, 1, 1 }, two_runs[6] = { 1, 0, 1, 1, 0, 0 };
  const int wrap[6] = { 1, 0, 0, 0, 1, 1 }; /* lines 4, 5, 0: centre 5.5/6 = 11/12 */
  guint phase, n_phases;
  g_assert_cmpint (ds_gpio_light_read (dark, 4, &phase, &n_phases), ==, DS_GPIO_LIGHT_DARK);
  g_assert_cmpint (ds_gpio_light_read (all, 4, &phase, &n_phases), ==, DS_GPIO_LIGHT_ALL);
  g_assert_cmpint (ds_gpio_light_read (two_runs, 6, &phase, &n_phases), ==, DS_GPIO_LIGHT_GARBLED);
  g_assert_cmpint (ds_gpio_light_read (wrap, 6, &phase, &n_phases), ==, DS_GPIO_LIGHT_STRIPE);
  g_assert_cmpuint (phase, ==, 11);
  g_assert_cmpuint (n_phases, ==, 12);
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  g_test_add_func ("/gpio-chip/protocol", test_protocol);
  g_test_add_func ("/gpio-chip/trigger-edges", test_trigger_edges);
  g_test_add_func ("/gpio-chip/bad-chip", test_bad_chip);
  g_test_add_func ("/gpio-chip/peer-gone-and-back", test_peer_gone_and_back);
  g_test_add_func ("/gpio-chip/silent-peer", test_silent_peer);
  g_test_add_func ("/gpio-chip/light-from-lines", test_light_from_lines);
  return g_test_run ();
}
