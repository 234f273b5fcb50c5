/* `descatterd --check --probe`: after the configuration checks (preflight.h), the devices are
 * opened and given the configured settings by the acquisition thread itself (sequencer.h),
 * exactly as the running daemon does at start, reconnect and reload; what the devices are and
 * what they allow is printed, and any refusal fails with the devices' reason (the setting and
 * the values the device allows).
 * Main thread; blocks while the devices open (device discovery: seconds). */
#pragma once
#include <stdio.h>

#include <glib.h>

#include "daemon/service/preflight.h"

G_BEGIN_DECLS

/* Prints the camera's and illuminator's identity and limits to out. Fails with the reason the
 * devices did not open, refused a configured setting, or report a fault. */
gboolean ds_probe_run (const DsPreflight *preflight, FILE *out, GError **error);

G_END_DECLS
