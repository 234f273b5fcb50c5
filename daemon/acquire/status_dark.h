/* status's "dark" member: whether the sets take their own dark frame, the last dark frame
 * taken and the stored one (docs/protocol.md). Any thread; CPU only. */
#pragma once
#include <json-glib/json-glib.h>

#include "daemon/acquire/sequencer.h"

G_BEGIN_DECLS

/* The "dark" object of a status snapshot, with ages against now_unix_us (g_get_real_time ()). */
JsonNode *ds_status_dark_to_json (const DsSequencerStatus *status, gint64 now_unix_us);

G_END_DECLS
