/* Runs a real descatterd process for integration tests: a configuration written to a temporary
 * folder, a UNIX socket there, readiness awaited through `status`. */
#pragma once
#include <gio/gio.h>

#include "daemon/protocol/client.h"

typedef struct {
  char *dir;          /* temporary folder: config, socket, spool, outputs */
  char *socket_path;
  char *config_path;
  GSubprocess *proc;
} TestDaemon;

/* config_text: a complete descatterd.conf body ([daemon] socket is added by the harness).
 * extra_args: NULL-terminated, may be NULL. Fails the test if the daemon is not ready within
 * the timeout. */
TestDaemon *test_daemon_start (const char *config_text, const char *const *extra_args);
/* The same with environment variables (NULL-terminated name, value pairs) and, when wait_ready
 * is FALSE, returning once the devices were opened, ready or not (a refused setting). */
TestDaemon *test_daemon_start_full (const char *config_text, const char *const *extra_args,
                                    const char *const *env, gboolean wait_ready);
/* SIGTERM and wait; returns the exit status. */
int test_daemon_stop (TestDaemon *d);
void test_daemon_free (TestDaemon *d);
DsClient *test_daemon_connect (TestDaemon *d);
/* Calls cmd and asserts ok; returns the message. */
DsMessage *test_daemon_call_ok (DsClient *c, const char *cmd, JsonObject *args);
/* The daemon's resident set size (VmRSS of /proc/PID/status), KiB. */
guint64 test_daemon_rss_kib (TestDaemon *d);
/* The integer at a dotted path in a JSON object ("frames.acquired"). */
gint64 test_json_int (JsonNode *node, const char *path);

/* descatter-labsim as a process: started with the scene and extra (fault) arguments, ready
 * once it prints its ready line. The Modbus port is chosen per test process. */
typedef struct {
  GSubprocess *proc;
  GDataInputStream *out;
  guint modbus_port;
} TestLabsim;

TestLabsim *test_labsim_start (const char *labsim_path, const char *scene_path,
                               const char *const *extra_args);
/* SIGTERM; asserts a clean exit. */
void test_labsim_stop (TestLabsim *labsim);
