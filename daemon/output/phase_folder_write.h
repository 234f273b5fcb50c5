/* Writes the raw frames of a set as a phase folder (docs/phase-folder.md): what
 * `descatterctl separate` reads back. Files: phase-KK-M.png (phase k, its m-th frame), 16-bit
 * PNG whatever the ADC's depth (frames.json says the depth); black.png, the dark frame the
 * daemon subtracted (the average of the dark frames listed in black.frame_ids); frames.json
 * last. The folder is filled under a hidden temporary name beside `dir` and renamed into place
 * at the end, so a folder named `dir` is always whole (and a leftover ".NAME.tmp-..." is not).
 * Any thread; blocks on the disk. */
#pragma once
#include <glib.h>
#include <json-glib/json-glib.h>

#include "daemon/output/raw_frames.h"

G_BEGIN_DECLS

/* `meta`: the result's metadata (daemon/output/result_meta.h keys), from which producer,
 * camera, pattern, exposure and settings are copied into frames.json. `dir` must not exist. */
gboolean ds_phase_folder_write (const DsRawFrames *raw, JsonNode *meta, const char *dir, GError **error);

/* The frames.json object for raw and meta (exposed for tests and for HDF5 attributes). */
JsonNode *ds_phase_folder_sidecar (const DsRawFrames *raw, JsonNode *meta);

/* Name of frame i of raw in the folder ("phase-03-1.png"). */
char *ds_phase_folder_frame_name (const DsRawFrames *raw, guint i);

G_END_DECLS
