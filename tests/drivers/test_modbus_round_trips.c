/* How many Modbus requests a set_phase costs, and that the ones it saves never make it take an
 * apply that is not its own for its own (drivers/modbus/modbus_illuminator.c, apply_and_wait;
 * docs/registers.md). Right after an apply it confirmed, the backend skips the STATUS read
 * before the write: 2 requests instead of 3 when the controller applies at once. Whenever the
 * count may have moved without it (another master wrote, the controller restarted, an apply
 * failed, set_pattern's own apply, a lost connection) it must fall back to reading the count
 * afresh. Against labsim's controller over TCP and over RTU on a pty; what is lit and how many
 * requests and applies the controller saw come from the controller's own model
 * (ds_modbus_server_get_state), never from the backend. */
#include <glib/gstdio.h>
#include <modbus.h>

#include "modbus_fixture.h"
#include "drivers/modbus/registers.h"

static void
fixture_setup (Fixture *f, gconstpointer data)
{
  ds_modbus_server_config_init (&f->cfg);
  /* Applied at once: every request then counts (no poll waits for a settle time). */
  f->cfg.settle_us = 0;
  modbus_fixture_open (f, GPOINTER_TO_INT (data));
  g_autoptr (GError) error = NULL;
  g_assert_true (f->ill->ops->set_pattern (f->ill->backend, &modbus_fixture_four_phases, &error));
  g_assert_no_error (error);
}

static void
fixture_teardown (Fixture *f, gconstpointer data)
{
  (void) data;
  modbus_fixture_close (f);
}

static DsModbusServerState
state (Fixture *f)
{
  DsModbusServerState st;
  ds_modbus_server_get_state (f->server, &st);
  return st;
}

/* set_phase(k) succeeds, phase k is lit, and it took `requests` requests and `applies` applies
 * of the controller. (Reading the controller's state applies a write whose settle time is
 * over, as its own clock would: an earlier write is applied before `before`.) */
static void
assert_set_phase (Fixture *f, guint k, guint requests, guint applies)
{
  g_autoptr (GError) error = NULL;
  DsModbusServerState before = state (f);
  g_assert_true (f->ill->ops->set_phase (f->ill->backend, k, DEADLINE_MS, &error));
  g_assert_no_error (error);
  DsModbusServerState after = state (f);
  g_assert_true (after.enabled && after.ready);
  g_assert_cmpuint (after.phase, ==, k);
  g_assert_cmpuint (after.requests - before.requests, ==, requests);
  g_assert_cmpuint ((guint16) (after.apply_count - before.apply_count), ==, applies);
}

/* Our own applies, one after the other: the first after set_pattern reads the count (STATUS,
 * write, poll), every later one is a write and a poll. off () the same. */
static void
test_own_applies (Fixture *f, gconstpointer data)
{
  (void) data;
  /* After set_pattern's own write, not waited for: the count is read afresh. */
  assert_set_phase (f, 0, 3, 1);
  for (guint k = 1; k < 8; k++)
    assert_set_phase (f, k % 4, 2, 1);
  g_autoptr (GError) error = NULL;
  DsModbusServerState before = state (f);
  g_assert_true (f->ill->ops->off (f->ill->backend, DEADLINE_MS, &error));
  DsModbusServerState after = state (f);
  g_assert_false (after.enabled);
  g_assert_cmpuint (after.requests - before.requests, ==, 2);
  assert_set_phase (f, 2, 2, 1);
  /* set_pattern writes, and its apply moves the count: the next set_phase reads it again. */
  g_assert_true (f->ill->ops->set_pattern (f->ill->backend, &modbus_fixture_four_phases, &error));
  assert_set_phase (f, 3, 3, 1);
}

/* An apply that failed leaves the count unknown: the controller lit another phase (INVALID),
 * then the next set_phase reads the count before writing. */
static void
test_after_failure (Fixture *f, gconstpointer data)
{
  (void) data;
  assert_set_phase (f, 0, 3, 1);
  assert_set_phase (f, 1, 2, 1);
  f->cfg.wrong_phase = TRUE;
  ds_modbus_server_set_config (f->server, &f->cfg);
  g_autoptr (GError) error = NULL;
  g_assert_false (f->ill->ops->set_phase (f->ill->backend, 2, DEADLINE_MS, &error));
  g_assert_error (error, DS_ILLUMINATOR_ERROR, DS_DEVICE_ERROR_INVALID);
  f->cfg.wrong_phase = FALSE;
  ds_modbus_server_set_config (f->server, &f->cfg);
  assert_set_phase (f, 2, 3, 1);
  assert_set_phase (f, 3, 2, 1);
  /* A fault since the last apply shows at the first poll (after the write), as FAULT. */
  f->cfg.fault = TRUE;
  ds_modbus_server_set_config (f->server, &f->cfg);
  g_clear_error (&error);
  g_assert_false (f->ill->ops->set_phase (f->ill->backend, 0, DEADLINE_MS, &error));
  g_assert_error (error, DS_ILLUMINATOR_ERROR, DS_DEVICE_ERROR_FAULT);
  f->cfg.fault = FALSE;
  ds_modbus_server_set_config (f->server, &f->cfg);
  /* The write the faulted controller held applied once the fault cleared; then the count is
   * read afresh. */
  assert_set_phase (f, 1, 3, 1);
}

/* Another master lights a phase between two of ours (TCP: a second connection). The count then
 * moved by two when ours is applied: that cannot be told from "another apply, ours not yet",
 * so the backend writes again from the count it read then (4 requests, 2 applies of ours). */
static void
test_other_master (Fixture *f, gconstpointer data)
{
  (void) data;
  assert_set_phase (f, 0, 3, 1);
  assert_set_phase (f, 1, 2, 1);
  modbus_t *other = modbus_new_tcp ("127.0.0.1", (int) ds_modbus_server_port (f->server));
  modbus_set_response_timeout (other, ANSWER_MS / 1000, (ANSWER_MS % 1000) * 1000);
  g_assert_cmpint (modbus_connect (other), ==, 0);
  guint16 lit3[2] = { 3, 1 };
  g_assert_cmpint (modbus_write_registers (other, DS_MB_HOLD_PHASE, 2, lit3), ==, 2);
  /* Its apply came first (before `before`); then ours, and ours again. */
  assert_set_phase (f, 2, 4, 2);
  assert_set_phase (f, 3, 2, 1);
  modbus_close (other);
  modbus_free (other);
}

/* The controller restarts between two of ours (TCP: a new controller on the same port; its
 * count starts from 0), and another master lights a phase on it first, so that when ours is
 * applied the count equals the one we last confirmed. Taken for "not applied yet" the backend
 * would wait for the deadline; it sees the count moved by other than one and writes again. */
static void
test_restart (Fixture *f, gconstpointer data)
{
  (void) data;
  assert_set_phase (f, 0, 3, 1); /* count 2: set_pattern's apply and ours */
  g_assert_cmpuint (state (f).apply_count, ==, 2);
  guint port = ds_modbus_server_port (f->server);
  ds_modbus_server_free (f->server);
  g_autoptr (GError) error = NULL;
  f->server = ds_modbus_server_new ("127.0.0.1", port, &f->cfg, &error);
  g_assert_no_error (error);
  /* Power-up: 4 phases of square stripes at 6 px, as modbus_fixture_four_phases. */
  modbus_t *other = modbus_new_tcp ("127.0.0.1", (int) port);
  modbus_set_response_timeout (other, ANSWER_MS / 1000, (ANSWER_MS % 1000) * 1000);
  g_assert_cmpint (modbus_connect (other), ==, 0);
  guint16 lit1[2] = { 1, 1 };
  g_assert_cmpint (modbus_write_registers (other, DS_MB_HOLD_PHASE, 2, lit1), ==, 2);
  modbus_close (other);
  modbus_free (other);
  gint64 t0 = g_get_monotonic_time ();
  g_assert_true (f->ill->ops->set_phase (f->ill->backend, 2, DEADLINE_MS, &error));
  g_assert_no_error (error);
  /* Not by the deadline: once the count was seen moved. */
  g_assert_cmpint (g_get_monotonic_time () - t0, <, DEADLINE_MS * 1000 / 2);
  DsModbusServerState st = state (f);
  g_assert_true (st.enabled);
  g_assert_cmpuint (st.phase, ==, 2);
  g_assert_cmpuint (st.apply_count, ==, 3); /* the other master's, ours, ours again */
}

/* A lost connection leaves the count unknown (the controller may have restarted meanwhile):
 * after it the count is read before the write. */
static void
test_lost_connection (Fixture *f, gconstpointer data)
{
  (void) data;
  assert_set_phase (f, 0, 3, 1);
  assert_set_phase (f, 1, 2, 1);
  g_autoptr (GError) error = NULL;
  g_assert_true (f->ill->ops->reconnect (f->ill->backend, &error));
  g_assert_no_error (error);
  assert_set_phase (f, 2, 3, 1);
  assert_set_phase (f, 3, 2, 1);
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
#define ADD(path, fn, rtu)                                                                        \
  g_test_add ("/modbus-round-trips/" path, Fixture, GINT_TO_POINTER (rtu), fixture_setup, fn, fixture_teardown)
  ADD ("own-applies", test_own_applies, FALSE);
  ADD ("after-failure", test_after_failure, FALSE);
  ADD ("other-master", test_other_master, FALSE);
  ADD ("restart", test_restart, FALSE);
  ADD ("lost-connection", test_lost_connection, FALSE);
  ADD ("rtu/own-applies", test_own_applies, TRUE);
  ADD ("rtu/after-failure", test_after_failure, TRUE);
  ADD ("rtu/lost-connection", test_lost_connection, TRUE);
  return g_test_run ();
}
