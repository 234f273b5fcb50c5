/* How a failure reaches a client: the one table from the daemon's internal error domains to
 * the stable codes of the wire (docs/protocol.md, "Error codes"). A device failure is
 * `device_error` whatever device and whatever code (drivers/core/device_error.h), a frame the
 * sequencer rejected is `failed`, a stop is `cancelled`; errors already in DS_PROTOCOL_ERROR
 * keep their code. Pure; any thread. */
#pragma once
#include <glib.h>

#include "daemon/protocol/protocol.h"

G_BEGIN_DECLS

DsProtocolError ds_wire_error_code (const GError *error);
/* A copy in DS_PROTOCOL_ERROR with that code and the same message. */
GError *ds_wire_error_new (const GError *error);

G_END_DECLS
