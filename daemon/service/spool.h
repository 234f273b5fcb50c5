/* Recording of results to a spool directory: per set, transmissive and scattered as float32
 * TIFF, the mask as PNG and a JSON sidecar, each written atomically (temporary name, fsync,
 * rename). The sidecar is written last, so a set whose sidecar exists is complete; a reader
 * ignores files without one. When the directory would exceed its byte cap, the oldest sets
 * are removed first (whole sets only). Main thread (writes are synchronous and bounded by the
 * result size). */
#pragma once
#include <glib.h>

#include "daemon/service/result.h"

G_BEGIN_DECLS

typedef struct DsSpool DsSpool;

/* Creates the directory if needed and takes stock of what is already there. */
DsSpool *ds_spool_new (const char *dir, guint64 max_bytes, GError **error);
void ds_spool_free (DsSpool *spool);
G_DEFINE_AUTOPTR_CLEANUP_FUNC (DsSpool, ds_spool_free)

/* Writes one result; on error nothing that looks whole is left behind. */
gboolean ds_spool_record (DsSpool *spool, DsResult *result, GError **error);
guint64 ds_spool_bytes (const DsSpool *spool);
guint64 ds_spool_sets_removed (const DsSpool *spool);

G_END_DECLS
