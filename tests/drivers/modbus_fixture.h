/* A descatter Modbus controller (labsim's, a thread of the test) and the Modbus backend
 * connected to it over TCP or a serial line, for the tests of drivers/modbus. */
#pragma once

#include "drivers/labsim/modbus_server.h"
#include "drivers/modbus/modbus_illuminator.h"

G_BEGIN_DECLS

typedef struct {
  DsModbusServer *server;
  DsModbusServerConfig cfg;
  DsIlluminator *ill;
  char *uri;
  char *dir; /* RTU: where the line's symlink lives */
} Fixture;

extern const DsStripePattern modbus_fixture_four_phases;

/* The controller is a thread of this process, which a loaded machine schedules late: at load 20
 * on 2 cores it missed a 100 ms response timeout. Where no answer is meant to be late, the
 * backend waits ANSWER_MS for one and a phase is awaited up to DEADLINE_MS. */
#define ANSWER_MS 1000
#define DEADLINE_MS 5000

/* Starts the controller with f->cfg (set it first) on 127.0.0.1 or, with rtu, only on a pty
 * reached through a symlink in a fresh directory (a link that survives the line going away and
 * coming back), and opens the backend on it, waiting ANSWER_MS for answers. */
void modbus_fixture_open (Fixture *f, gboolean rtu);
/* Closes the backend, stops the controller, removes the link's directory. */
void modbus_fixture_close (Fixture *f);

G_END_DECLS
