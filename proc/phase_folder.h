/* A folder of phase images in the layout of the ICCP 2013 authors' public scripts:
 *   - every image file (.png .tif .tiff .bmp .jpg .jpeg .pgm) is one phase, in natural sort
 *     order of the names ("img2" before "img10");
 *   - black.<ext> is the frame with the illuminator off (subtracted as the dark frame);
 *   - white.<ext> (all stripes on) is not a phase and is not used;
 *   - earlier outputs are skipped: direct, global, max, min, mean, transmissive, scattered,
 *     mask, sigma_transmissive, sigma_scattered, any name starting with "truth" and any
 *     ending in "-preview";
 *   - hidden files (".name", e.g. half-written temporaries) are ignored.
 * Names are matched without extension, case-insensitively.
 *
 * Images are read one at a time (ds_phase_folder_read), so a set of many large frames never
 * has to fit in memory at once; every image read is checked against the first one read
 * (size, sample type, bit depth) and a mismatch names both files. Not thread-safe: one user. */
#pragma once
#include <glib.h>

#include "proc/image.h"

G_BEGIN_DECLS

typedef struct {
  char *dir;
  GPtrArray *phase_files;  /* basenames (char *), in phase order */
  char *black_file;        /* basename or NULL */
  char *white_file;        /* basename or NULL (reported, never used) */
  GPtrArray *skipped;      /* basenames of earlier outputs that were skipped */
  /* The shape every image must have, fixed by the first image read. */
  gboolean have_reference;
  guint width, height, bit_depth;
  DsSampleType type;
  char *reference_file;
} DsPhaseFolder;

/* Lists the folder. Fails IO (not a readable folder), EMPTY (no phase image; the message says
 * what was skipped), NOT_ENOUGH_PHASES (one phase image only: a separation needs >= 2). */
DsPhaseFolder *ds_phase_folder_open (const char *dir, GError **error);
void ds_phase_folder_free (DsPhaseFolder *folder);
G_DEFINE_AUTOPTR_CLEANUP_FUNC (DsPhaseFolder, ds_phase_folder_free)

guint ds_phase_folder_n_phases (const DsPhaseFolder *folder);

/* Reads phase k (0-based). Fails IO/FORMAT (unreadable: names the file) or SIZE_MISMATCH
 * (names this file and the reference file with both shapes). */
DsImage *ds_phase_folder_read (DsPhaseFolder *folder, guint k, GError **error);
/* Reads the black frame; folder->black_file must be set. Same checks as a phase. */
DsImage *ds_phase_folder_read_black (DsPhaseFolder *folder, GError **error);

/* Natural order: runs of digits compare by value, other characters case-insensitively. */
int ds_natural_compare (const char *a, const char *b);

G_END_DECLS
