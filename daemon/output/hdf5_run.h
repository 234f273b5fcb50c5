/* One growing HDF5 file per continuous run (NeXus layout as hdf5_set.h, each plane with a
 * leading set axis): /entry/{transmissive,scattered,mask}/data [sets, height, width], optional
 * /entry/phases/{data [frames, h, w], phase, frame_id, set_index, black [sets, h, w],
 * has_black}, and /entry/sets/{time_utc, metadata (UTF-8 JSON bytes of every set back to back),
 * metadata_end (end offset of each set's JSON), set_id}.
 *
 * Crash safety: the file is written in HDF5's single-writer/multiple-reader (SWMR) mode under
 * the name PATH.partial, and every set is flushed in two steps: first its planes (and
 * metadata), then its entry in sets/set_id. sets/set_id therefore counts the complete sets: a
 * reader (h5py.File(path, "r", swmr=True), also while the run goes on) takes the first
 * len(sets/set_id) entries of every dataset; planes beyond are a set the writer did not finish.
 * After a kill -9 the .partial file stays readable that way (HDF5 marks it "open for writing":
 * open it with swmr=True, or clear the mark with `h5clear -s`). A run closed normally gets
 * end_time, is fsynced and renamed to PATH: only a whole run has the final name.
 *
 * One thread uses a run (the spool's writer thread, or descatterctl). */
#pragma once
#include "daemon/output/output_result.h"

G_BEGIN_DECLS

typedef struct DsHdf5Run DsHdf5Run;

/* Creates PATH.partial laid out for results shaped like `first` (raw phases kept when first
 * has them), without appending it. */
DsHdf5Run *ds_hdf5_run_open (const char *path, const DsOutputResult *first, GError **error);
/* Appends one set and flushes. Fails INVALID (and appends nothing) when the planes' size
 * differs from the run's: the caller closes the run and starts another. */
gboolean ds_hdf5_run_append (DsHdf5Run *run, const DsOutputResult *result, GError **error);
guint64 ds_hdf5_run_sets (const DsHdf5Run *run);
/* The final name (PATH) and the name while open (PATH.partial). */
const char *ds_hdf5_run_path (const DsHdf5Run *run);
const char *ds_hdf5_run_partial_path (const DsHdf5Run *run);
/* Bytes on disk now. */
guint64 ds_hdf5_run_bytes (const DsHdf5Run *run);
/* Writes end_time, closes, fsyncs, renames PATH.partial to PATH, and frees the run. */
gboolean ds_hdf5_run_close (DsHdf5Run *run, GError **error);
/* Frees without the final rename (the .partial stays, readable as after a crash). */
void ds_hdf5_run_abandon (DsHdf5Run *run);

G_END_DECLS
