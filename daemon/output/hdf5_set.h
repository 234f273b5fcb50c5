/* One phase set in one HDF5 file following NeXus conventions (docs/operations.md, "HDF5"):
 *   /entry (NXentry)            title, start_time, end_time, program_name, default
 *     transmissive, scattered, mask [, max, min, mean, sigma_*] (NXdata, signal "data",
 *                               float32/uint8 [height, width], units and long_name attributes;
 *                               the mask carries CF flag_masks/flag_meanings)
 *     phases (NXdata, optional) data uint16 [frames, height, width], phase, frame_id,
 *                               timestamp_ns; black [height, width] and black_frame_ids
 *     instrument (NXinstrument) camera (NXdetector), illuminator (NXcollection)
 *     metadata (NXnote)         type "application/json", data: the whole result metadata
 * Written to a temporary name, closed, fsynced and renamed: a file with the final name is
 * whole. Any thread; blocks on the disk. */
#pragma once
#include <hdf5.h>

#include "daemon/output/output_result.h"

G_BEGIN_DECLS

gboolean ds_hdf5_write_set (const DsOutputResult *result, const char *path, GError **error);

/* Shared with the growing run file: entry-level NeXus fields and the instrument group built
 * from the metadata (result_meta.h keys); end_time only with_end (a run writes its own). */
gboolean ds_hdf5_write_entry_fields (hid_t entry, JsonNode *meta, const char *title, gboolean with_end);
gboolean ds_hdf5_write_instrument (hid_t entry, JsonNode *meta);
/* The root group's NeXus attributes. */
gboolean ds_hdf5_write_root_attrs (hid_t file, const char *file_name);

G_END_DECLS
