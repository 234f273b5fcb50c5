/* Writing a result message (reply to capture, or a streamed result event) to a folder: each
 * payload as a file a tool can read (f32 -> TIFF, u8/u16 -> PNG), an 8-bit PNG preview of
 * each float component for people, and the metadata as JSON. Every file is written atomically;
 * the JSON is written last, so a folder with the JSON is complete. */
#pragma once
#include "daemon/protocol/client.h"

/* prefix: "" or e.g. "set-000042-" (files become PREFIXtransmissive.tiff ...). */
gboolean ds_ctl_write_result (const DsMessage *message, const char *dir, const char *prefix,
                              GError **error);
