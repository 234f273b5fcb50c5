/* The one writer of result files, used by descatterctl (capture, stream) and descatterd's spool
 * (docs/operations.md, "Result files"). One naming scheme everywhere:
 *   <stem>-transmissive.tiff, <stem>-scattered.tiff   float32 TIFF with tags (tiff_file.h)
 *   <stem>-max.tiff, -min.tiff, -mean.tiff, -sigma_*.tiff   when the result has them
 *   <stem>-mask.png                                  u8 quality flags (legend: mask_bits)
 *   <stem>-direct.png, <stem>-global.png             16-bit, scaled to be visible (png16)
 *   <stem>-transmissive-preview.png, -scattered-preview.png   8-bit pictures (preview)
 *   <stem>.h5                                        NeXus HDF5 (hdf5)
 *   <stem>-phases/                                   the raw frames as a phase folder (phases)
 *   <stem>.json                                      metadata + the list of files: written LAST,
 *                                                    so a set whose .json exists is complete
 * with stem "set-<UTC start, YYYYMMDDTHHMMSSZ>-<set id, 6 digits>", the same for a set in the
 * spool and in a client's folder. Every file is written atomically; on failure the files of
 * the set written so far are removed. Any thread; blocks on the disk. */
#pragma once
#include <glib.h>

#include "daemon/output/output_result.h"

G_BEGIN_DECLS

typedef enum {
  DS_FILES_TIFF = 1 << 0,     /* float32 TIFFs with tags, mask PNG */
  DS_FILES_PNG16 = 1 << 1,    /* direct.png, global.png */
  DS_FILES_PREVIEW = 1 << 2,  /* 8-bit previews */
  DS_FILES_HDF5 = 1 << 3,     /* one NeXus file per set */
  DS_FILES_PHASES = 1 << 4,   /* the phase folder (when the result has raw frames) */
  DS_FILES_HDF5_RUN = 1 << 5, /* one growing NeXus file per run (hdf5_run.h; the caller's) */
} DsFileKinds;

#define DS_FILES_ALL_NAMES "tiff, png16, preview, hdf5, hdf5-run"

/* "tiff,png16,preview": kinds by name (phases is not named: it follows save_phases); the error
 * names an unknown one and lists the rest. */
gboolean ds_file_kinds_parse (const char *list, guint *kinds, GError **error);
char *ds_file_kinds_to_string (guint kinds);

/* "set-20261125T160211Z-000042" from the metadata's time_utc and set_id (now and 0 when
 * absent). */
char *ds_result_stem (JsonNode *meta);
/* "<stem>-<part>.<ext>" ("<part>.<ext>" for an empty stem). */
char *ds_result_file_name (const char *stem, const char *part, const char *ext);

/* Writes the files of `kinds` (DS_FILES_HDF5_RUN is ignored here) and the JSON sidecar last.
 * `written` (may be NULL) receives the basenames, sidecar included. */
gboolean ds_result_write_files (const DsOutputResult *result, const char *dir, const char *stem, guint kinds,
                                GPtrArray *written, GError **error);

/* 16-bit copy of a float plane, scaled by the largest power of two (2^-16..2^16) that keeps
 * the largest finite value within 65535, so that it fills at least half the range and every
 * value is recovered as file / scale within 0.5 / scale. Negative and non-finite values
 * become 0 (the mask flags them). */
DsImage *ds_png16_scaled (const DsImage *plane, double *scale, GError **error);

G_END_DECLS
