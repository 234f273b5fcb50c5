#include "tests/common/daemon_harness.h"
#include "tests/common/config_groups.h"

#include <glib/gstdio.h>
#include <signal.h>
#include <sys/prctl.h>
#include <string.h>
#include <unistd.h>
#include "tests/common/test_tree.h"

static void
die_with_parent (gpointer data)
{
  (void) data;
  prctl (PR_SET_PDEATHSIG, SIGTERM);
}

GSubprocess *
test_spawn (const char *const *argv, GSubprocessFlags flags)
{
  g_autoptr (GError) error = NULL;
  g_autoptr (GSubprocessLauncher) launcher = g_subprocess_launcher_new (flags);
  g_subprocess_launcher_set_child_setup (launcher, die_with_parent, NULL, NULL);
  GSubprocess *p = g_subprocess_launcher_spawnv (launcher, argv, &error);
  g_assert_no_error (error);
  return p;
}

char *
test_wait_line (GDataInputStream *out, const char *what, const char *text)
{
  g_autoptr (GError) error = NULL;
  for (;;) {
    char *line = g_data_input_stream_read_line (out, NULL, NULL, &error);
    g_assert_no_error (error);
    if (!line)
      g_error ("%s exited before it printed \"%s\"", what, text);
    if (strstr (line, text))
      return line;
    g_free (line);
  }
}

TestDaemon *
test_daemon_start (const char *config_text, const char *const *extra_args)
{
  return test_daemon_start_full (config_text, extra_args, NULL, TRUE);
}

/* The daemon process on a fresh folder holding config_text; not waited for. */
static TestDaemon *
daemon_spawn (const char *config_text, const char *const *extra_args, const char *const *env)
{
  TestDaemon *d = g_new0 (TestDaemon, 1);
  g_autoptr (GError) error = NULL;
  d->dir = g_dir_make_tmp ("descatterd-test-XXXXXX", &error);
  g_assert_no_error (error);
  d->socket_path = g_build_filename (d->dir, "descatterd.sock", NULL);
  d->config_path = g_build_filename (d->dir, "descatterd.conf", NULL);
  g_autofree char *grouped = test_config_groups_merge (config_text);
  g_file_set_contents (d->config_path, grouped, -1, &error);
  g_assert_no_error (error);
  g_autoptr (GPtrArray) argv = g_ptr_array_new ();
  g_ptr_array_add (argv, (gpointer) DESCATTERD_PATH);
  g_ptr_array_add (argv, (gpointer) "--config");
  g_ptr_array_add (argv, d->config_path);
  g_ptr_array_add (argv, (gpointer) "--socket");
  g_ptr_array_add (argv, d->socket_path);
  g_ptr_array_add (argv, (gpointer) "--no-socket-activation");
  for (guint i = 0; extra_args && extra_args[i]; i++)
    g_ptr_array_add (argv, (gpointer) extra_args[i]);
  g_ptr_array_add (argv, NULL);
  g_autoptr (GSubprocessLauncher) launcher = g_subprocess_launcher_new (G_SUBPROCESS_FLAGS_NONE);
  for (guint i = 0; env && env[i] && env[i + 1]; i += 2)
    g_subprocess_launcher_setenv (launcher, env[i], env[i + 1], TRUE);
  /* The daemon dies with the test, even when an assertion aborts it. */
  g_subprocess_launcher_set_child_setup (launcher, die_with_parent, NULL, NULL);
  d->proc = g_subprocess_launcher_spawnv (launcher, (const char *const *) argv->pdata, &error);
  g_assert_no_error (error);
  return d;
}

TestDaemon *
test_daemon_start_unready (const char *config_text)
{
  TestDaemon *d = daemon_spawn (config_text, NULL, NULL);
  for (guint i = 0; i < 12000; i++) {
    g_assert_nonnull (g_subprocess_get_identifier (d->proc));
    g_autoptr (DsClient) c = ds_client_connect (d->socket_path, NULL);
    if (c)
      return d;
    g_usleep (10 * 1000);
  }
  g_error ("descatterd did not open its socket within 120 s");
  return NULL;
}

TestDaemon *
test_daemon_start_full (const char *config_text, const char *const *extra_args, const char *const *env,
                        gboolean wait_ready)
{
  TestDaemon *d = daemon_spawn (config_text, extra_args, env);
  /* Ready = `status` answers ready (the simulated lab may take seconds to build); or, when not
   * waiting for that, answers with the devices opened (ready or not, with a reason). */
  for (guint i = 0; i < 1200; i++) {
    /* The identifier goes away once the process has exited (and been reaped). */
    g_assert_nonnull (g_subprocess_get_identifier (d->proc));
    g_autoptr (DsClient) c = ds_client_connect (d->socket_path, NULL);
    if (c) {
      g_autoptr (DsMessage) m = ds_client_call (c, "status", NULL, NULL, NULL, NULL);
      JsonObject *st = m && m->reply->ok ? json_node_get_object (m->reply->body) : NULL;
      if (st && json_object_get_boolean_member_with_default (st, "ready", FALSE))
        return d;
      const char *why = st ? json_object_get_string_member_with_default (st, "not_ready_reason", NULL) : NULL;
      if (st && !wait_ready && why && !strstr (why, "opening"))
        return d;
    }
    g_usleep (100 * 1000);
  }
  g_error ("descatterd did not become ready within 120 s");
  return NULL;
}

int
test_daemon_stop (TestDaemon *d)
{
  if (!d->proc)
    return -1;
  g_subprocess_send_signal (d->proc, SIGTERM);
  g_autoptr (GError) error = NULL;
  g_subprocess_wait (d->proc, NULL, &error);
  g_assert_no_error (error);
  int status = g_subprocess_get_if_exited (d->proc) ? g_subprocess_get_exit_status (d->proc) : 128 + g_subprocess_get_term_sig (d->proc);
  g_clear_object (&d->proc);
  return status;
}

void
test_daemon_stop_clean (TestDaemon *d)
{
  g_assert_cmpint (test_daemon_stop (d), ==, 0);
  test_daemon_free (d);
}

void
test_daemon_free (TestDaemon *d)
{
  if (!d)
    return;
  if (d->proc)
    test_daemon_stop (d);
  test_remove_tree (d->dir);
  g_free (d->dir);
  g_free (d->socket_path);
  g_free (d->config_path);
  g_free (d);
}

DsClient *
test_daemon_connect (TestDaemon *d)
{
  g_autoptr (GError) error = NULL;
  DsClient *c = ds_client_connect (d->socket_path, &error);
  g_assert_no_error (error);
  return c;
}

DsMessage *
test_daemon_call_ok (DsClient *c, const char *cmd, JsonObject *args)
{
  g_autoptr (GError) error = NULL;
  DsMessage *m = ds_client_call (c, cmd, args, NULL, NULL, &error);
  g_assert_no_error (error);
  if (!m->reply->ok)
    g_error ("%s failed: %s: %s", cmd, ds_protocol_error_name (m->reply->error_code), m->reply->error_message);
  return m;
}

guint64
test_daemon_rss_kib (TestDaemon *d)
{
  g_autofree char *path = g_strdup_printf ("/proc/%s/status", g_subprocess_get_identifier (d->proc));
  g_autofree char *text = NULL;
  g_assert_true (g_file_get_contents (path, &text, NULL, NULL));
  const char *p = strstr (text, "VmRSS:");
  g_assert_nonnull (p);
  return g_ascii_strtoull (p + 6, NULL, 10);
}

gint64
test_json_int (JsonNode *node, const char *path)
{
  g_auto (GStrv) parts = g_strsplit (path, ".", -1);
  for (guint i = 0; parts[i]; i++) {
    g_assert_true (JSON_NODE_HOLDS_OBJECT (node));
    node = json_object_get_member (json_node_get_object (node), parts[i]);
    g_assert_nonnull (node);
  }
  return json_node_get_int (node);
}

TestFrames
test_daemon_frames (DsClient *c)
{
  g_autoptr (DsMessage) st = test_daemon_call_ok (c, "status", NULL);
  JsonNode *b = st->reply->body;
  TestFrames f = {
    .acquired = test_json_int (b, "frames.acquired"),
    .folded = test_json_int (b, "frames.folded"),
    .dropped = test_json_int (b, "frames.dropped"),
    .timeouts = test_json_int (b, "frames.timeouts"),
    .device_errors = test_json_int (b, "frames.device_errors"),
    .stale = test_json_int (b, "frames.dropped_by_reason.stale"),
    .wrong_phase = test_json_int (b, "frames.dropped_by_reason.wrong_phase"),
    .aborted = test_json_int (b, "frames.dropped_by_reason.aborted"),
  };
  g_test_message ("frames: acquired %" G_GINT64_FORMAT ", folded %" G_GINT64_FORMAT ", dropped %" G_GINT64_FORMAT
                  " (stale %" G_GINT64_FORMAT ", wrong phase %" G_GINT64_FORMAT ", aborted %" G_GINT64_FORMAT
                  "); timeouts %" G_GINT64_FORMAT ", device errors %" G_GINT64_FORMAT,
                  f.acquired, f.folded, f.dropped, f.stale, f.wrong_phase, f.aborted, f.timeouts, f.device_errors);
  g_assert_cmpint (f.acquired, ==, f.folded + f.dropped);
  return f;
}

int
test_daemon_check (const char *config_text, gboolean probe, char **out, char **err)
{
  g_autoptr (GError) error = NULL;
  g_autofree char *dir = g_dir_make_tmp ("descatterd-check-XXXXXX", &error);
  g_assert_no_error (error);
  g_autofree char *conf = g_build_filename (dir, "descatterd.conf", NULL);
  g_autofree char *sock = g_build_filename (dir, "descatterd.sock", NULL);
  g_autofree char *joined = g_strdup_printf ("[daemon]\nsocket=%s\n%s", sock, config_text);
  g_autofree char *text = test_config_groups_merge (joined);
  g_file_set_contents (conf, text, -1, &error);
  g_assert_no_error (error);
  const char *argv[] = { DESCATTERD_PATH, "--check", "--config", conf, probe ? "--probe" : NULL, NULL };
  g_autoptr (GSubprocess) p = test_spawn (argv, G_SUBPROCESS_FLAGS_STDOUT_PIPE | G_SUBPROCESS_FLAGS_STDERR_PIPE);
  g_autofree char *o = NULL, *e = NULL;
  g_subprocess_communicate_utf8 (p, NULL, NULL, &o, &e, &error);
  g_assert_no_error (error);
  g_assert_true (g_subprocess_get_if_exited (p));
  int status = g_subprocess_get_exit_status (p);
  g_test_message ("descatterd --check%s: exit %d\n%s%s", probe ? " --probe" : "", status, o, e);
  g_assert_false (g_file_test (sock, G_FILE_TEST_EXISTS));
  g_unlink (conf);
  g_rmdir (dir);
  if (out)
    *out = g_steal_pointer (&o);
  if (err)
    *err = g_steal_pointer (&e);
  return status;
}

TestLabsim *
test_labsim_start (const char *labsim_path, const char *scene_path, const char *const *extra_args)
{
  return test_labsim_start_on_port (labsim_path, scene_path, extra_args, 0);
}

TestLabsim *
test_labsim_start_on_port (const char *labsim_path, const char *scene_path, const char *const *extra_args,
                           guint modbus_port)
{
  TestLabsim *l = g_new0 (TestLabsim, 1);
  g_snprintf (l->serial, sizeof l->serial, "DSLT%05u", (guint) (getpid () % 100000));
  g_autofree char *modbus = g_strdup_printf ("127.0.0.1:%u", modbus_port);
  g_autoptr (GPtrArray) argv = g_ptr_array_new ();
  const char *fixed[] = { labsim_path, "--scene", scene_path, "--camera-address", "127.0.0.1",
                          "--camera-serial", l->serial, "--modbus", modbus };
  for (guint i = 0; i < G_N_ELEMENTS (fixed); i++)
    g_ptr_array_add (argv, (gpointer) fixed[i]);
  for (guint i = 0; extra_args && extra_args[i]; i++)
    g_ptr_array_add (argv, (gpointer) extra_args[i]);
  g_ptr_array_add (argv, NULL);
  l->proc = test_spawn ((const char *const *) argv->pdata, G_SUBPROCESS_FLAGS_STDOUT_PIPE);
  l->out = g_data_input_stream_new (g_subprocess_get_stdout_pipe (l->proc));
  /* The port labsim bound, from its ready line (port 0: the kernel's choice, free by
   * construction; a fixed one could be any other process's). */
  g_autofree char *line = test_wait_line (l->out, "descatter-labsim", "ready camera=");
  const char *modbus_at = strstr (line, " modbus=127.0.0.1:");
  g_assert_nonnull (modbus_at);
  l->modbus_port = (guint) g_ascii_strtoull (modbus_at + strlen (" modbus=127.0.0.1:"), NULL, 10);
  g_assert_cmpuint (l->modbus_port, >, 0);
  if (modbus_port)
    g_assert_cmpuint (l->modbus_port, ==, modbus_port);
  return l;
}

void
test_labsim_stop (TestLabsim *l)
{
  g_subprocess_send_signal (l->proc, SIGTERM);
  g_autoptr (GError) error = NULL;
  g_subprocess_wait (l->proc, NULL, &error);
  g_assert_no_error (error);
  g_assert_true (g_subprocess_get_if_exited (l->proc));
  g_assert_cmpint (g_subprocess_get_exit_status (l->proc), ==, 0);
  g_object_unref (l->out);
  g_object_unref (l->proc);
  g_free (l);
}

