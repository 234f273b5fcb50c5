/* `descatterd --check` runs exactly the validation that start-up runs (issue 10): for every
 * configuration the check refuses, starting the daemon with it fails with the same message
 * and leaves nothing behind (no socket file); a configuration the check accepts starts.
 * Each case is one the issue found passing --check and then failing (or misbehaving) at start.
 * The programs are run as processes, as an administrator would. */
#include "tests/common/config_groups.h"
#include <gio/gio.h>
#include <glib/gstdio.h>
#include <signal.h>
#include <string.h>
#include <unistd.h>

static char *dir;

typedef struct {
  int status;      /* exit status, or -1 when it did not exit by itself in time */
  char *first_error; /* the first "descatterd: " line on stderr */
} Run;

static void
run_free (Run *r)
{
  g_free (r->first_error);
}

static Run
run_descatterd (const char *const *args, guint timeout_s)
{
  g_autoptr (GPtrArray) argv = g_ptr_array_new ();
  g_ptr_array_add (argv, (gpointer) DESCATTERD_PATH);
  for (guint i = 0; args[i]; i++)
    g_ptr_array_add (argv, (gpointer) args[i]);
  g_ptr_array_add (argv, NULL);
  g_autoptr (GError) error = NULL;
  g_autoptr (GSubprocess) p = g_subprocess_newv ((const char *const *) argv->pdata,
                                                 G_SUBPROCESS_FLAGS_STDOUT_SILENCE | G_SUBPROCESS_FLAGS_STDERR_PIPE,
                                                 &error);
  g_assert_no_error (error);
  Run r = { .status = -1 };
  gint64 deadline = g_get_monotonic_time () + (gint64) timeout_s * G_USEC_PER_SEC;
  while (g_get_monotonic_time () < deadline && g_subprocess_get_identifier (p))
    g_usleep (10000);
  if (g_subprocess_get_identifier (p)) {
    g_subprocess_force_exit (p);
    g_subprocess_wait (p, NULL, NULL);
  } else
    r.status = g_subprocess_get_if_exited (p) ? g_subprocess_get_exit_status (p) : 128;
  g_autoptr (GDataInputStream) err = g_data_input_stream_new (g_subprocess_get_stderr_pipe (p));
  char *line;
  while (!r.first_error && (line = g_data_input_stream_read_line (err, NULL, NULL, NULL))) {
    if (g_str_has_prefix (line, "descatterd: "))
      r.first_error = g_strdup (line + strlen ("descatterd: "));
    g_free (line);
  }
  return r;
}

static char *
write_file (const char *name, const char *data, gssize len)
{
  char *path = g_build_filename (dir, name, NULL);
  g_autoptr (GError) error = NULL;
  g_file_set_contents (path, data, len, &error);
  g_assert_no_error (error);
  return path;
}

typedef struct {
  const char *what;
  const char *config;       /* appended to the [daemon] socket line; %s = the test folder */
  const char *extra_arg;    /* an option after --config, or NULL */
  const char *extra_value;
  const char *must_mention;
} Case;

#define SIM "[camera]\nbackend=sim\n[illuminator]\nbackend=sim\n"
#define REAL_CAMERA "[camera]\nbackend=aravis\naddress=127.0.0.1\n"
#define REAL "[camera]\nbackend=aravis\naddress=127.0.0.1\n[illuminator]\nbackend=modbus\nmodbus-uri=tcp://127.0.0.1:1502\n"

/* A loopback port nothing listens on now (bound to 0, read back, closed). */
static guint16
free_port (GSocket **keep)
{
  g_autoptr (GError) error = NULL;
  g_autoptr (GSocket) s = g_socket_new (G_SOCKET_FAMILY_IPV4, G_SOCKET_TYPE_STREAM, G_SOCKET_PROTOCOL_TCP, &error);
  g_assert_no_error (error);
  g_autoptr (GInetAddress) lo = g_inet_address_new_loopback (G_SOCKET_FAMILY_IPV4);
  g_autoptr (GSocketAddress) any = g_inet_socket_address_new (lo, 0);
  g_assert_true (g_socket_bind (s, any, TRUE, &error));
  g_assert_true (g_socket_listen (s, &error));
  g_autoptr (GSocketAddress) got = g_socket_get_local_address (s, &error);
  guint16 port = g_inet_socket_address_get_port (G_INET_SOCKET_ADDRESS (got));
  if (keep)
    *keep = g_steal_pointer (&s);
  else
    g_socket_close (s, NULL);
  return port;
}

#define MASK_SCENE "[sensor]\nwidth=64\nheight=48\n[illuminator]\nperiod-px=8\nirradiance=1\n" \
                   "[object.m]\nshape=mask\nmask=%s\n"

static char *
write_mask_scene (const char *name, const char *mask)
{
  g_autofree char *text = g_strdup_printf (MASK_SCENE, mask);
  return write_file (name, text, -1);
}

static void
test_check_equals_start (void)
{
  g_autofree char *sock = g_build_filename (dir, "d.sock", NULL);
  g_autofree char *short_token = write_file ("short-token", "only-15-chars\n", -1);
  g_autofree char *token_dir = g_build_filename (dir, "token-is-a-dir", NULL);
  g_mkdir (token_dir, 0700);
  g_autofree char *not_scene = write_file ("not.scene", "this is not a scene\n", -1);
  g_autofree char *not_model = write_file ("not-model.csv", "a,b\n1,2\n", -1);
  g_autofree char *good_token = write_file ("good-token", "a-token-of-more-than-16-characters\n", -1);
  g_autofree char *a_file = write_file ("a-file", "", 0);
  g_autofree char *spool_under_file = g_build_filename (a_file, "spool", NULL);
  g_autofree char *not_image = write_file ("not-an-image.png", "this is text\n", -1);
  /* a 10 x 10 greyscale PGM: an image, but not the sensor's 64 x 48 */
  g_autoptr (GString) pgm = g_string_new ("P5\n10 10\n255\n");
  for (int i = 0; i < 100; i++)
    g_string_append_c (pgm, (char) 255);
  g_autofree char *small_mask = write_file ("small-mask.pgm", pgm->str, (gssize) pgm->len);
  g_autofree char *missing_mask_path = g_build_filename (dir, "missing-mask.png", NULL);
  g_autofree char *scene_missing_mask = write_mask_scene ("missing-mask.scene", missing_mask_path);
  g_autofree char *scene_text_mask = write_mask_scene ("text-mask.scene", not_image);
  g_autofree char *scene_small_mask = write_mask_scene ("small-mask.scene", small_mask);
  g_autofree char *scene_costly = write_file ("costly.scene", "[sensor]\nwidth=64\nheight=48\n[illuminator]\n"
                                              "period-px=8\nirradiance=1\n[medium]\nthickness-mm=3\nmua=0.02\n"
                                              "mus=2\nphotons=1e10\n", -1);
  g_autofree char *port = g_strdup_printf ("%u", free_port (NULL));
  g_autoptr (GSocket) holder = NULL;
  g_autofree char *held_port = g_strdup_printf ("%u", free_port (&holder));
  g_autofree char *long_socket = g_strdup_printf ("%s/%s.sock", dir,
                                                  "a-socket-name-that-makes-the-path-longer-than-sun-path-"
                                                  "allows-on-linux-which-is-108-bytes");
  const Case cases[] = {
    { "roi with three numbers", SIM "[camera]\nroi=1,2,3\n", NULL, NULL, "roi" },
    { "empty roi", SIM "[camera]\nroi=0,0,0,0\n", NULL, NULL, "roi" },
    { "modbus-uri not a Modbus URI", REAL_CAMERA "[illuminator]\nbackend=modbus\nmodbus-uri=http://x\n", NULL, NULL,
      "modbus-uri" },
    { "modbus-uri port out of range", REAL_CAMERA "[illuminator]\nbackend=modbus\nmodbus-uri=tcp://127.0.0.1:99999\n",
      NULL, NULL, "99999" },
    { "gpio-lines with a hole", "[camera]\nbackend=aravis\naddress=127.0.0.1\n[illuminator]\nbackend=gpio\n"
      "gpio-chip=gpiochip0\ngpio-lines=17,,18\n", NULL, NULL, "gpio-lines" },
    { "gpio-lines with a line twice", "[camera]\nbackend=aravis\naddress=127.0.0.1\n[illuminator]\nbackend=gpio\n"
      "gpio-chip=gpiochip0\ngpio-lines=17,18,17\n", NULL, NULL, "twice" },
    { "garbage faults", SIM "[sim]\nfaults=garbage\n", NULL, NULL, "faults" },
    { "missing scene", SIM "[sim]\nscene=/nonexistent/milk.scene\n", NULL, NULL, "scene" },
    { "not a scene", SIM "[sim]\nscene=%NOT_SCENE%\n", NULL, NULL, "scene" },
    { "missing scene on the command line", SIM, "--scene", "/nonexistent/milk.scene", "--scene" },
    { "missing operating model", SIM "[acquisition]\noperating-model=/nonexistent/model.csv\n", NULL, NULL,
      "operating-model" },
    { "not an operating model", SIM "[acquisition]\noperating-model=%NOT_MODEL%\n", NULL, NULL, "operating-model" },
    { "short token", SIM "[daemon]\ntcp-token-file=%SHORT_TOKEN%\n", NULL, NULL, "16 characters" },
    { "missing token", SIM "[daemon]\ntcp-token-file=/nonexistent/token\n", NULL, NULL, "tcp-token-file" },
    { "token file that is a folder", SIM "[daemon]\ntcp-token-file=%TOKEN_DIR%\n", NULL, NULL, "tcp-token-file" },
    { "relative socket", SIM "[daemon]\nsocket=run/d.sock\n", NULL, NULL, "absolute" },
    { "relative spool-dir", SIM "[daemon]\nspool-dir=spool\n", NULL, NULL, "absolute" },
    { "socket longer than sun_path", SIM "[daemon]\nsocket=%LONG_SOCKET%\n", NULL, NULL, "at most 107" },
    { "--socket longer than sun_path", SIM, "--socket", "%LONG_SOCKET%", "at most 107" },
    { "non-loopback TCP without a token", SIM "[daemon]\ntcp-listen=0.0.0.0:7420\n", NULL, NULL, "token" },
    { "--tcp not an address", SIM, "--tcp", "localhost:7420", "--tcp" },
    { "line trigger with the software trigger", REAL "[camera]\ntrigger=line0\n", NULL, NULL, "[trigger] backend" },
    { "Aravis camera with the simulated illuminator", "[camera]\nbackend=aravis\naddress=127.0.0.1\n"
      "[illuminator]\nbackend=sim\n", NULL, NULL, "[illuminator] backend = sim" },
    { "no devices chosen", "[acquisition]\nphases=8\n", NULL, NULL, "backend is not set" },
    { "a key twice", SIM "[acquisition]\nphases=8\nphases=4\n", NULL, NULL, "set twice" },
    { "a locale key", SIM "[camera]\nbackend[fr]=aravis\n", NULL, NULL, "localized" },
    { "a key without a name", SIM "[acquisition]\n=8\n", NULL, NULL, "without a key name" },
    /* what start creates, binds or opens */
    { "spool-dir under a regular file", SIM "[daemon]\nspool-dir=%SPOOL_UNDER_FILE%\n", NULL, NULL,
      "cannot be created" },
    { "tcp-listen and [http] listen on one address", SIM "[daemon]\ntcp-listen=127.0.0.1:%PORT%\n[http]\n"
      "listen=127.0.0.1:%PORT%\n", NULL, NULL, "same address" },
    { "--http on tcp-listen's address", SIM "[daemon]\ntcp-listen=127.0.0.1:%PORT%\n", "--http", "127.0.0.1:%PORT%",
      "same address" },
    { "[http] listen on the wildcard of tcp-listen's port", SIM "[daemon]\ntcp-listen=127.0.0.1:%PORT%\n[http]\n"
      "listen=0.0.0.0:%PORT%\ntoken-file=%GOOD_TOKEN%\n", NULL, NULL, "same address" },
    { "tcp-listen on a port another program holds", SIM "[daemon]\ntcp-listen=127.0.0.1:%HELD_PORT%\n", NULL, NULL,
      "cannot listen there" },
    { "[http] listen on a port another program holds", SIM "[http]\nlisten=127.0.0.1:%HELD_PORT%\n", NULL, NULL,
      "cannot listen there" },
    { "a mask file that is missing", SIM "[sim]\nscene=%SCENE_MISSING_MASK%\n", NULL, NULL, "[object.m] mask" },
    { "a mask file that is not an image", SIM "[sim]\nscene=%SCENE_TEXT_MASK%\n", NULL, NULL, "[object.m] mask" },
    { "a mask of another size than the sensor", SIM "[sim]\nscene=%SCENE_SMALL_MASK%\n", NULL, NULL, "10x10" },
    { "a scene over its render cost ceiling", SIM "[sim]\nscene=%SCENE_COSTLY%\n", NULL, NULL, "max-render-s" },
    { "--scene over its render cost ceiling", SIM, "--scene", "%SCENE_COSTLY%", "max-render-s" },
  };
  for (guint i = 0; i < G_N_ELEMENTS (cases); i++) {
    /* Every case binds (if it ever got that far) in the test folder, unless it is about the
     * socket itself. */
    g_autofree char *body = strstr (cases[i].config, "socket=")
                                ? g_strdup (cases[i].config)
                                : g_strdup_printf ("[daemon]\nsocket=%s\n%s", sock, cases[i].config);
    const struct { const char *key, *value; } subst[] = {
      { "%NOT_SCENE%", not_scene }, { "%NOT_MODEL%", not_model }, { "%SHORT_TOKEN%", short_token },
      { "%TOKEN_DIR%", token_dir }, { "%LONG_SOCKET%", long_socket }, { "%GOOD_TOKEN%", good_token },
      { "%SPOOL_UNDER_FILE%", spool_under_file }, { "%PORT%", port }, { "%HELD_PORT%", held_port },
      { "%SCENE_MISSING_MASK%", scene_missing_mask }, { "%SCENE_TEXT_MASK%", scene_text_mask },
      { "%SCENE_SMALL_MASK%", scene_small_mask }, { "%SCENE_COSTLY%", scene_costly },
    };
    g_autofree char *extra_value = g_strdup (cases[i].extra_value);
    for (guint k = 0; k < G_N_ELEMENTS (subst); k++) {
      g_autoptr (GString) b = g_string_new (body);
      g_string_replace (b, subst[k].key, subst[k].value, 0);
      g_free (body);
      body = g_strdup (b->str);
      if (extra_value && strstr (extra_value, subst[k].key)) {
        g_autoptr (GString) v = g_string_new (extra_value);
        g_string_replace (v, subst[k].key, subst[k].value, 0);
        g_free (extra_value);
        extra_value = g_strdup (v->str);
      }
    }
    /* The section given again by a case ([daemon], [camera]...) goes into the base's group of
     * that name (descatterd refuses a group given twice); a key given twice is refused, and no
     * case does that but the one that means to. */
    g_autofree char *grouped = test_config_groups_merge (body);
    g_autofree char *conf = write_file ("case.conf", grouped, -1);
    const char *check_args[] = { "--check", "--config", conf, cases[i].extra_arg, extra_value, NULL };
    const char *start_args[] = { "--config", conf, "--no-socket-activation", cases[i].extra_arg, extra_value, NULL };
    if (!cases[i].extra_arg) {
      check_args[3] = NULL;
      start_args[3] = NULL;
    }
    Run check = run_descatterd (check_args, 20);
    Run start = run_descatterd (start_args, 20);
    g_test_message ("%s: --check: %d \"%s\"; start: %d \"%s\"", cases[i].what, check.status, check.first_error,
                    start.status, start.first_error);
    if (check.status != 1 || !check.first_error || !strstr (check.first_error, cases[i].must_mention))
      g_error ("%s: --check exited %d with \"%s\" (expected 1, mentioning \"%s\")", cases[i].what, check.status,
               check.first_error, cases[i].must_mention);
    if (start.status != 1 || g_strcmp0 (start.first_error, check.first_error) != 0)
      g_error ("%s: start exited %d with \"%s\"; --check said \"%s\"", cases[i].what, start.status,
               start.first_error, check.first_error);
    /* Refused before anything was bound: no stray socket file (a long path used to be cut
     * short by bind and leave one). */
    g_assert_false (g_file_test (sock, G_FILE_TEST_EXISTS));
    g_assert_false (g_file_test (long_socket, G_FILE_TEST_EXISTS));
    g_autofree char *cut = g_strndup (long_socket, 107);
    g_assert_false (g_file_test (cut, G_FILE_TEST_EXISTS));
    run_free (&check);
    run_free (&start);
    g_unlink (conf);
  }
  g_unlink (short_token);
  g_unlink (good_token);
  g_unlink (a_file);
  g_unlink (not_image);
  g_unlink (small_mask);
  g_unlink (scene_missing_mask);
  g_unlink (scene_text_mask);
  g_unlink (scene_small_mask);
  g_unlink (scene_costly);
  g_rmdir (token_dir);
  g_unlink (not_scene);
  g_unlink (not_model);
}

/* A configuration --check accepts is one the daemon starts with. */
static void
test_check_accepts_what_starts (void)
{
  g_autofree char *sock = g_build_filename (dir, "ok.sock", NULL);
  /* what start creates and binds: a spool two folders deep that does not exist yet, TCP and
   * HTTP on two ports of their own */
  g_autofree char *spool_top = g_build_filename (dir, "spool", NULL);
  g_autofree char *spool = g_build_filename (spool_top, "a", "b", NULL);
  guint16 tcp_port = free_port (NULL), http_port = free_port (NULL);
  if (http_port == tcp_port)
    http_port = free_port (NULL);
  g_autofree char *body = g_strdup_printf ("[daemon]\nsocket=%s\nspool-dir=%s\ntcp-listen=127.0.0.1:%u\n"
                                           "[http]\nlisten=127.0.0.1:%u\n" SIM "[sim]\nscene=%s\n", sock, spool,
                                           tcp_port, http_port, SCENE_FILE);
  g_autofree char *conf = write_file ("ok.conf", body, -1);
  const char *check_args[] = { "--check", "--config", conf, NULL };
  Run check = run_descatterd (check_args, 20);
  g_assert_cmpint (check.status, ==, 0);
  g_assert_null (check.first_error);
  /* --check tried the spool and left nothing behind */
  g_assert_false (g_file_test (spool_top, G_FILE_TEST_EXISTS));
  const char *start_args[] = { "--config", conf, "--no-socket-activation", NULL };
  g_autoptr (GError) error = NULL;
  g_autoptr (GPtrArray) argv = g_ptr_array_new ();
  g_ptr_array_add (argv, (gpointer) DESCATTERD_PATH);
  for (guint i = 0; start_args[i]; i++)
    g_ptr_array_add (argv, (gpointer) start_args[i]);
  g_ptr_array_add (argv, NULL);
  g_autoptr (GSubprocess) p = g_subprocess_newv ((const char *const *) argv->pdata, G_SUBPROCESS_FLAGS_STDERR_SILENCE |
                                                 G_SUBPROCESS_FLAGS_STDOUT_SILENCE, &error);
  g_assert_no_error (error);
  /* The socket once the daemon is up: however long a loaded machine takes (the harness allows
   * 120 s too), bounded for a daemon that never opens it. */
  for (guint i = 0; i < 2400 && !g_file_test (sock, G_FILE_TEST_EXISTS); i++)
    g_usleep (50000);
  g_assert_true (g_file_test (sock, G_FILE_TEST_EXISTS));
  g_assert_nonnull (g_subprocess_get_identifier (p)); /* still running */
  g_assert_true (g_file_test (spool, G_FILE_TEST_IS_DIR));
  g_subprocess_send_signal (p, SIGTERM);
  g_assert_true (g_subprocess_wait_check (p, NULL, &error));
  g_assert_no_error (error);
  run_free (&check);
  g_unlink (conf);
  g_rmdir (spool);
  g_autofree char *spool_a = g_path_get_dirname (spool);
  g_rmdir (spool_a);
  g_rmdir (spool_top);
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  dir = g_dir_make_tmp ("descatterd-check-XXXXXX", NULL);
  g_test_add_func ("/check/refusals-equal-start", test_check_equals_start);
  g_test_add_func ("/check/accepts-what-starts", test_check_accepts_what_starts);
  int status = g_test_run ();
  g_rmdir (dir);
  g_free (dir);
  return status;
}
