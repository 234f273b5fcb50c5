/* Recording of results to a spool directory, in the file formats of daemon/output (one naming
 * scheme with descatterctl; docs/operations.md, "The spool"): per set the files of the
 * configured kinds and the JSON sidecar last, so a set whose sidecar exists is complete, and
 * with `hdf5-run` one growing HDF5 file per continuous run. When the directory would exceed its
 * byte cap, the oldest sets and closed runs are removed first (whole ones only).
 *
 * Threads: every function is called from the main thread and never blocks on the disk: results
 * are queued to the spool's own writer thread. When the disk falls behind by `max_pending`
 * results, further ones are not recorded (counted as dropped) rather than delaying acquisition
 * or the socket clients. At start-up, files of sets without a sidecar (an interrupted write) are
 * removed; a run left as .partial by a crash is kept (readable, see hdf5_run.h). */
#pragma once
#include <glib.h>

#include "daemon/acquire/result.h"

G_BEGIN_DECLS

typedef struct DsSpool DsSpool;

/* kinds: DsFileKinds (daemon/output/result_files.h). Creates the directory if needed and takes
 * stock of what is already there. */
DsSpool *ds_spool_new (const char *dir, guint64 max_bytes, guint kinds, guint max_pending, GError **error);
/* Writes everything still queued, closes an open run, joins the writer thread. */
void ds_spool_free (DsSpool *spool);
G_DEFINE_AUTOPTR_CLEANUP_FUNC (DsSpool, ds_spool_free)

/* Queues one result; `in_run`: it belongs to continuous acquisition (hdf5-run appends it to the
 * run's file; a result outside a run gets a file of its own). FALSE when the queue is full (the
 * result is not recorded; counted in dropped). */
gboolean ds_spool_record (DsSpool *spool, DsResult *result, gboolean in_run);
/* Closes the current run's HDF5 file (continuous acquisition stopped). */
void ds_spool_end_run (DsSpool *spool);
/* Waits until everything queued before the call is on disk (tests, shutdown). */
void ds_spool_flush (DsSpool *spool);

typedef struct {
  guint64 bytes;           /* on disk now, open run included */
  guint64 sets_written;
  guint64 sets_removed;    /* sets and runs removed to stay under the cap */
  guint64 errors;          /* writes that failed (nothing of them was left) */
  guint64 dropped;         /* results not recorded because the writer was behind */
  guint pending;           /* results queued now */
  gboolean run_open;
  char last_error[256];
} DsSpoolStats;

void ds_spool_get_stats (DsSpool *spool, DsSpoolStats *stats);

G_END_DECLS
