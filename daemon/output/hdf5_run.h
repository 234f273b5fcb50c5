/* One growing HDF5 file per continuous run (NeXus layout as hdf5_set.h, each plane with a
 * leading set axis): /entry/{transmissive,scattered,mask}/data [sets, height, width], optional
 * /entry/phases/{data [frames, h, w], phase, frame_id, set_index, black [sets, h, w],
 * has_black}, and /entry/sets/{time_utc, metadata (UTF-8 JSON bytes of every set back to back),
 * metadata_end (end offset of each set's JSON), set_id, frames_end (end row of each set's raw
 * frames in phases/), missing_set_id and missing_reason (fixed-length strings): the sets the
 * run lost, and why}.
 *
 * Crash safety: the file is written in HDF5's single-writer/multiple-reader (SWMR) mode under
 * the name PATH.partial, and every set is flushed in two steps: first its planes (and
 * metadata), then its entry in sets/set_id. sets/set_id therefore counts the complete sets: a
 * reader (h5py.File(path, "r", swmr=True), also while the run goes on) takes the first
 * len(sets/set_id) entries of every dataset; rows beyond belong to no set.
 * After a kill -9 the .partial file stays readable that way (HDF5 marks it "open for writing":
 * open it with swmr=True, or clear the mark with `h5clear -s`). A run closed normally is cut to
 * its committed rows, gets end_time, is fsynced and renamed to PATH: only a whole run has the
 * final name.
 *
 * A failed append rolls back: it is written at the rows after the last committed set, and the
 * next set is written at the same rows, over it. The set is recorded as missing, with the
 * reason, together with the next set that commits (or at close). An append that would not fit
 * on the disk (its bytes and some slack against statvfs) is not started at all: HDF5 is not
 * trusted after a write failed half way. When a write fails anyway, a reserve file next to the
 * run (disk_room.h) is removed so that closing has room, the file is closed, and the next
 * append opens it again from the disk.
 *
 * One thread uses a run (the spool's writer thread, or descatterctl). */
#pragma once
#include "daemon/output/output_result.h"

G_BEGIN_DECLS

typedef struct DsHdf5Run DsHdf5Run;

/* Creates PATH.partial laid out for results shaped like `first` (raw phases kept when first
 * has them), without appending it. */
DsHdf5Run *ds_hdf5_run_open (const char *path, const DsOutputResult *first, GError **error);
/* Appends one set and flushes. Fails INVALID (and appends nothing, records nothing) when the
 * planes' size differs from the run's: the caller closes the run and starts another. Fails
 * NO_SPACE (nothing written) when the disk lacks room, HDF5 when a write failed (rolled back):
 * both record the set as missing. */
gboolean ds_hdf5_run_append (DsHdf5Run *run, const DsOutputResult *result, GError **error);
guint64 ds_hdf5_run_sets (const DsHdf5Run *run);
/* The final name (PATH) and the name while open (PATH.partial). */
const char *ds_hdf5_run_path (const DsHdf5Run *run);
const char *ds_hdf5_run_partial_path (const DsHdf5Run *run);
/* Bytes on disk now. */
guint64 ds_hdf5_run_bytes (const DsHdf5Run *run);
/* Cuts every dataset to its committed rows, records the sets lost since the last commit,
 * writes end_time, closes, fsyncs, renames PATH.partial to PATH, and frees the run. On failure
 * the .partial file stays (readable up to its committed sets). */
gboolean ds_hdf5_run_close (DsHdf5Run *run, GError **error);
/* Frees without the final rename (the .partial stays, readable as after a crash). */
void ds_hdf5_run_abandon (DsHdf5Run *run);
/* TRUE once HDF5 could not close the file after a failed write: nothing more can be appended
 * in this process; the caller abandons the run (its .partial keeps the committed sets) and
 * starts another. */
gboolean ds_hdf5_run_broken (const DsHdf5Run *run);

G_END_DECLS
