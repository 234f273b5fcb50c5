#include "daemon_harness.h"

#include <glib/gstdio.h>
#include <signal.h>
#include <sys/prctl.h>
#include <string.h>
#include <unistd.h>
#include "tests/test_tree.h"

static void
die_with_parent (gpointer data)
{
  (void) data;
  prctl (PR_SET_PDEATHSIG, SIGTERM);
}

TestDaemon *
test_daemon_start (const char *config_text, const char *const *extra_args)
{
  return test_daemon_start_full (config_text, extra_args, NULL, TRUE);
}

TestDaemon *
test_daemon_start_full (const char *config_text, const char *const *extra_args, const char *const *env,
                        gboolean wait_ready)
{
  TestDaemon *d = g_new0 (TestDaemon, 1);
  g_autoptr (GError) error = NULL;
  d->dir = g_dir_make_tmp ("descatterd-test-XXXXXX", &error);
  g_assert_no_error (error);
  d->socket_path = g_build_filename (d->dir, "descatterd.sock", NULL);
  d->config_path = g_build_filename (d->dir, "descatterd.conf", NULL);
  g_file_set_contents (d->config_path, config_text, -1, &error);
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

TestLabsim *
test_labsim_start (const char *labsim_path, const char *scene_path, const char *const *fault_args)
{
  TestLabsim *l = g_new0 (TestLabsim, 1);
  l->modbus_port = 20000 + (guint) (getpid () % 20000);
  g_autofree char *modbus = g_strdup_printf ("127.0.0.1:%u", l->modbus_port);
  g_autoptr (GPtrArray) argv = g_ptr_array_new ();
  g_ptr_array_add (argv, (gpointer) labsim_path);
  g_ptr_array_add (argv, (gpointer) "--scene");
  g_ptr_array_add (argv, (gpointer) scene_path);
  g_ptr_array_add (argv, (gpointer) "--camera-address");
  g_ptr_array_add (argv, (gpointer) "127.0.0.1");
  g_ptr_array_add (argv, (gpointer) "--modbus");
  g_ptr_array_add (argv, modbus);
  for (guint i = 0; fault_args && fault_args[i]; i++)
    g_ptr_array_add (argv, (gpointer) fault_args[i]);
  g_ptr_array_add (argv, NULL);
  g_autoptr (GError) error = NULL;
  g_autoptr (GSubprocessLauncher) launcher = g_subprocess_launcher_new (G_SUBPROCESS_FLAGS_STDOUT_PIPE);
  g_subprocess_launcher_set_child_setup (launcher, die_with_parent, NULL, NULL);
  l->proc = g_subprocess_launcher_spawnv (launcher, (const char *const *) argv->pdata, &error);
  g_assert_no_error (error);
  l->out = g_data_input_stream_new (g_subprocess_get_stdout_pipe (l->proc));
  for (;;) {
    g_autofree char *line = g_data_input_stream_read_line (l->out, NULL, NULL, &error);
    g_assert_no_error (error);
    g_assert_nonnull (line); /* labsim exited before it was ready */
    if (strstr (line, "ready"))
      break;
  }
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

