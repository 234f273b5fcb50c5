#include "daemon/service/wire_error.h"

#include <gio/gio.h>

#include "daemon/config/config.h"
#include "daemon/acquire/sequencer.h"
#include "daemon/operating/operating_error.h"
#include "drivers/core/device_error.h"

#define ANY_CODE (-1)

typedef struct {
  GQuark (*domain) (void);
  int code;               /* ANY_CODE: every code of the domain */
  DsProtocolError wire;
} WireRule;

/* First match wins; anything not listed is `failed` with its message. */
static const WireRule rules[] = {
  { ds_device_error_quark, ANY_CODE, DS_PROTOCOL_ERROR_DEVICE },
  { ds_sequencer_error_quark, DS_SEQUENCER_ERROR_NOT_READY, DS_PROTOCOL_ERROR_DEVICE },
  { ds_sequencer_error_quark, DS_SEQUENCER_ERROR_FRAME_REJECTED, DS_PROTOCOL_ERROR_FAILED },
  { ds_config_error_quark, ANY_CODE, DS_PROTOCOL_ERROR_FAILED },
  { ds_operating_error_quark, DS_OPERATING_ERROR_PILOT_FRAMES, DS_PROTOCOL_ERROR_BAD_ARGUMENT },
  { ds_operating_error_quark, DS_OPERATING_ERROR_NO_MODULATION, DS_PROTOCOL_ERROR_DEVICE },
  { ds_operating_error_quark, DS_OPERATING_ERROR_CLIPPED, DS_PROTOCOL_ERROR_DEVICE },
  { ds_operating_error_quark, DS_OPERATING_ERROR_NO_STRIPES, DS_PROTOCOL_ERROR_FAILED },
  { ds_operating_error_quark, DS_OPERATING_ERROR_CONFIGURATION, DS_PROTOCOL_ERROR_BAD_ARGUMENT },
  { ds_operating_error_quark, DS_OPERATING_ERROR_UNREACHABLE, DS_PROTOCOL_ERROR_BAD_ARGUMENT },
  { g_io_error_quark, G_IO_ERROR_CANCELLED, DS_PROTOCOL_ERROR_CANCELLED },
};

DsProtocolError
ds_wire_error_code (const GError *error)
{
  if (!error)
    return DS_PROTOCOL_ERROR_FAILED;
  if (error->domain == DS_PROTOCOL_ERROR)
    return (DsProtocolError) error->code;
  for (guint i = 0; i < G_N_ELEMENTS (rules); i++)
    if (error->domain == rules[i].domain () && (rules[i].code == ANY_CODE || rules[i].code == error->code))
      return rules[i].wire;
  return DS_PROTOCOL_ERROR_FAILED;
}

GError *
ds_wire_error_new (const GError *error)
{
  return g_error_new_literal (DS_PROTOCOL_ERROR, ds_wire_error_code (error),
                              error ? error->message : "unknown error");
}
