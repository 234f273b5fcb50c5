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
/* The same, returning as soon as the daemon's socket accepts a connection, before its devices
 * are open (status `opening`): for what a client sent right away gets. */
TestDaemon *test_daemon_start_unready (const char *config_text);
/* SIGTERM and wait; returns the exit status. */
int test_daemon_stop (TestDaemon *d);
void test_daemon_free (TestDaemon *d);
/* test_daemon_stop asserting a clean exit (status 0), then test_daemon_free. */
void test_daemon_stop_clean (TestDaemon *d);
DsClient *test_daemon_connect (TestDaemon *d);
/* Calls cmd and asserts ok; returns the message. */
DsMessage *test_daemon_call_ok (DsClient *c, const char *cmd, JsonObject *args);
/* The daemon's resident set size (VmRSS of /proc/PID/status), KiB. */
guint64 test_daemon_rss_kib (TestDaemon *d);
/* The integer at a dotted path in a JSON object ("frames.acquired"). */
gint64 test_json_int (JsonNode *node, const char *path);

/* The frame counters of `status`, logged; asserts the accounting every test relies on: each
 * acquired frame was folded or dropped (acquired = folded + dropped). */
typedef struct {
  gint64 acquired, folded, dropped, timeouts, device_errors;
  gint64 stale, wrong_phase, aborted; /* frames.dropped_by_reason */
} TestFrames;
TestFrames test_daemon_frames (DsClient *c);

/* descatterd --check, with --probe when `probe`, on config_text (a [daemon] socket in a fresh
 * temporary folder is added). Returns the exit status; *out and *err (each may be NULL) get
 * what it printed. Asserts that the check bound no socket. */
int test_daemon_check (const char *config_text, gboolean probe, char **out, char **err);

/* A helper process that dies with the test, even when an assertion aborts it (so that none
 * outlives it holding UDP 3956 or a pty). */
GSubprocess *test_spawn (const char *const *argv, GSubprocessFlags flags);
/* Reads a helper's stdout until a line contains `text`; returns that line. Fails the test,
 * naming `what`, when the helper exits first. */
char *test_wait_line (GDataInputStream *out, const char *what, const char *text);

/* descatter-labsim as a process: started with the scene and extra (fault) arguments, ready
 * once it prints its ready line, which names its Modbus TCP port. Its camera's serial number
 * is unique to the test process, so that a test can tell labsim's camera from another one on
 * the port. */
typedef struct {
  GSubprocess *proc;
  GDataInputStream *out;
  guint modbus_port;
  char serial[32];
} TestLabsim;

/* On a free Modbus port. */
TestLabsim *test_labsim_start (const char *labsim_path, const char *scene_path,
                               const char *const *extra_args);
/* On a given Modbus port: labsim back where a running daemon's configuration points. */
TestLabsim *test_labsim_start_on_port (const char *labsim_path, const char *scene_path,
                                       const char *const *extra_args, guint modbus_port);
/* SIGTERM; asserts a clean exit. */
void test_labsim_stop (TestLabsim *labsim);
