#include "drivers/labsim/external_light.h"

#include <errno.h>
#include <gio/gio.h>
#include <modbus.h>

#include "drivers/modbus/modbus_illuminator.h"
#include "drivers/modbus/registers.h"

struct DsExternalLight {
  char *uri;
  modbus_t *ctx;
  gboolean connected;
  gboolean warned;         /* one warning per outage */
};

DsExternalLight *
ds_external_light_new (const char *uri, GError **error)
{
  DsModbusUri u;
  GError *e = NULL;
  if (!ds_modbus_uri_parse (uri, &u, &e) || u.transport != DS_MODBUS_TCP) {
    g_set_error (error, G_IO_ERROR, G_IO_ERROR_INVALID_ARGUMENT, "--light-from \"%s\": %s", uri,
                 e ? e->message : "expected tcp://HOST:PORT");
    g_clear_error (&e);
    return NULL;
  }
  DsExternalLight *l = g_new0 (DsExternalLight, 1);
  l->uri = g_strdup (uri);
  char port[16];
  g_snprintf (port, sizeof port, "%u", u.port);
  l->ctx = modbus_new_tcp_pi (u.host, port);
  /* Optics answer at once; the controller standing in for them is a peer process on this
   * machine, which on a loaded one (load 10 and more, tests/drivers/daemon-rtu's pymodbus
   * controller in Python) answered later than the 200 ms this waited: the frame was then drawn
   * dark and failed the phase and period checks as if the illuminator had lit nothing. A
   * controller that is away refuses or resets the connection at once, so waiting long costs
   * nothing but on a slow answer, which the camera's frame must wait for. */
  modbus_set_response_timeout (l->ctx, 5, 0);
  return l;
}

void
ds_external_light_read (DsExternalLight *l, DsRenderRequest *req)
{
  guint16 applied = DS_MB_PHASE_OFF, hold[3] = { 0, 0, 0 }, caps = 0;
  gboolean ok = (l->connected || modbus_connect (l->ctx) == 0);
  l->connected = ok;
  /* NUM_PHASES, PATTERN_KIND, PERIOD_CENTIPX */
  ok = ok && modbus_read_input_registers (l->ctx, DS_MB_INPUT_APPLIED_PHASE, 1, &applied) == 1 &&
       modbus_read_registers (l->ctx, DS_MB_HOLD_NUM_PHASES, 3, hold) == 3;
  /* A controller of map revision 1 has no CAPABILITIES (exception 02): its period is fixed. */
  if (ok && modbus_read_input_registers (l->ctx, DS_MB_INPUT_CAPABILITIES, 1, &caps) != 1)
    ok = errno == EMBXILADD;
  if (!ok) {
    if (!l->warned)
      g_warning ("light from %s: cannot read the controller (%s): frames are dark", l->uri,
                 modbus_strerror (errno));
    l->warned = TRUE;
    if (l->connected)
      modbus_close (l->ctx);
    l->connected = FALSE;
    req->illuminator_on = FALSE;
    return;
  }
  l->warned = FALSE;
  guint n_phases = hold[0];
  req->illuminator_on = applied != DS_MB_PHASE_OFF && n_phases >= 1 && applied < n_phases;
  req->phase = req->illuminator_on ? applied : 0;
  req->n_phases = MAX (n_phases, 1u);
  req->period_px = (caps & DS_MB_CAP_PERIOD_ADJUSTABLE) && hold[2] >= DS_MB_CENTIPX_MIN ? hold[2] / 100.0 : 0;
}

void
ds_external_light_free (DsExternalLight *l)
{
  if (!l)
    return;
  if (l->connected)
    modbus_close (l->ctx);
  modbus_free (l->ctx);
  g_free (l->uri);
  g_free (l);
}
