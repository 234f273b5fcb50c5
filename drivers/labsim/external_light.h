/* The light a third-party illuminator controller shows, as labsim's camera sees it: the
 * controller's registers (docs/registers.md) read over Modbus TCP at each frame, standing in
 * for the optics between a projector labsim does not simulate and its camera. With it,
 * descatterd can drive a controller written elsewhere (tests/drivers/pymodbus_controller.py)
 * while labsim's camera still shows the phase that controller lit.
 *
 * Threads: read on the camera thread only; new/free on the main thread. */
#pragma once
#include <glib.h>

#include "drivers/sim/renderer.h"

G_BEGIN_DECLS

typedef struct DsExternalLight DsExternalLight;

/* uri: "tcp://HOST:PORT". Connects lazily; fails INVALID-style (G_IO_ERROR) on a bad URI only. */
DsExternalLight *ds_external_light_new (const char *uri, GError **error);
/* Fills req->illuminator_on, req->phase, req->n_phases from APPLIED_PHASE and NUM_PHASES, and
 * req->period_px from PERIOD_CENTIPX where CAPABILITIES says the period is adjustable (else 0:
 * the scene's); dark (with a warning, once per outage) when the controller cannot be read. */
void ds_external_light_read (DsExternalLight *light, DsRenderRequest *req);
void ds_external_light_free (DsExternalLight *light);

G_END_DECLS
