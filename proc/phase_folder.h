/* A folder of phase images (docs/phase-folder.md): the layout of the ICCP 2013 authors' public
 * scripts, optionally with a frames.json sidecar that says what the images cannot.
 *
 * Without frames.json:
 *   - every image file (.png .tif .tiff .bmp .jpg .jpeg .pgm) is one phase, in natural sort
 *     order of the names ("img2" before "img10");
 *   - black.<ext> is the frame with the illuminator off (subtracted as the dark frame);
 *   - white.<ext> (all stripes on) is not a phase and is not used;
 *   - earlier outputs are skipped: direct, global, max, min, mean, transmissive, scattered,
 *     mask, sigma_transmissive, sigma_scattered, any name starting with "truth" and any
 *     ending in "-preview";
 *   - hidden files (".name", e.g. half-written temporaries) are ignored.
 *   Names are matched without extension, case-insensitively.
 * With frames.json, its "frames" list (acquisition order, a phase index each, several frames
 * per phase averaged) and "black" files are the set; images it does not list are not phases.
 * Its bit_depth is given to the integer images (a 12-bit camera's 16-bit PNGs saturate at
 * 4095, not 65535) and checked against their samples; saturation_dn, the pattern and the
 * estimator are there for the separation to use. A sidecar that does not parse, names a
 * missing file or disagrees with the images is refused, naming the key and the file.
 *
 * Images are read one at a time (ds_phase_folder_read), so a set of many large frames never
 * has to fit in memory at once; every image read is checked against the first one read
 * (size, sample type, bit depth) and a mismatch names both files. Not thread-safe: one user. */
#pragma once
#include <glib.h>
/* json-glib's own type, declared here so that proc/ users need not include json-glib */
typedef struct _JsonNode JsonNode;

#include "proc/image.h"
#include "proc/separation.h"

G_BEGIN_DECLS

typedef struct {
  char *file;             /* basename */
  guint phase;            /* k */
  gboolean has_frame_id;
  guint64 frame_id;
} DsPhaseFolderFrame;

/* What frames.json says (present = FALSE without one). NAN / NULL for absent optional keys. */
typedef struct {
  gboolean present;
  char *producer;         /* producer.program */
  guint width, height;
  guint bit_depth;        /* 1..16, or 32 for float frames */
  double saturation_dn;
  char *pixel_format;
  gboolean has_pattern_kind;
  DsPatternKind pattern_kind;
  double period_px, duty, black_level;
  double edge_blur_px;    /* pattern.edge_blur_px: the stripe edges' blur the acquisition knew */
  double harmonic_gain;   /* pattern.harmonic_gain: sine's h the acquisition knew (calibrated) */
  gboolean has_phase_offset;
  double phase_offset_cycles;
  char *estimator;        /* settings.estimator */
  gboolean has_detect_motion;
  gboolean detect_motion; /* settings.detect_motion: the acquisition judged the motion bit */
} DsPhaseFolderSidecar;

typedef struct {
  char *dir;
  GArray *frames;          /* DsPhaseFolderFrame, in acquisition order */
  guint n_phases;
  GPtrArray *phase_files;  /* the frames' basenames, in the same order */
  char *black_file;        /* the first black file or NULL */
  GPtrArray *black_files;  /* basenames, averaged into the dark frame; may be empty */
  char *white_file;        /* basename or NULL (reported, never used) */
  GPtrArray *skipped;      /* basenames of earlier outputs that were skipped */
  DsPhaseFolderSidecar sidecar;
  /* Significant bits given to integer images as they are read (and checked against their
   * samples): frames.json's, or ds_phase_folder_set_bit_depth's; 0 = the file's. */
  guint bit_depth;
  /* The shape every image must have, fixed by the first image read. */
  gboolean have_reference;
  guint width, height, ref_bit_depth;
  DsSampleType type;
  char *reference_file;
} DsPhaseFolder;

/* Reads frames.json at path into a JSON tree, or fails with a message that does not repeat
 * the path. proc/ has no JSON reader of its own: the caller gives the strict, bounded one
 * (daemon/protocol/json_file.h), so that a hostile sidecar (a FIFO, /dev/zero, nesting that
 * would overflow a recursive parser, duplicate keys) is refused the way the wire refuses it. */
typedef JsonNode *(*DsSidecarReader) (const char *path, GError **error);

/* Lists the folder and reads frames.json if there is one (with read_sidecar). Fails IO (not a
 * readable folder), EMPTY (no phase image; the message says what was skipped),
 * NOT_ENOUGH_PHASES (one phase image only: a separation needs >= 2), FORMAT (frames.json:
 * unreadable, or the message names the key). */
DsPhaseFolder *ds_phase_folder_open (const char *dir, DsSidecarReader read_sidecar, GError **error);
void ds_phase_folder_free (DsPhaseFolder *folder);
G_DEFINE_AUTOPTR_CLEANUP_FUNC (DsPhaseFolder, ds_phase_folder_free)

guint ds_phase_folder_n_phases (const DsPhaseFolder *folder);
guint ds_phase_folder_n_frames (const DsPhaseFolder *folder);
const DsPhaseFolderFrame *ds_phase_folder_frame (const DsPhaseFolder *folder, guint i);

/* The ADC's significant bits for integer images (--bit-depth): 1..16. Fails INVALID_ARGUMENT
 * out of range. Images read later get it as their bit_depth, and a sample above 2^bits - 1
 * fails FORMAT naming the file and pixel. */
gboolean ds_phase_folder_set_bit_depth (DsPhaseFolder *folder, guint bits, GError **error);

/* Reads frame i (0-based, ds_phase_folder_frame (i) says its phase). Fails IO/FORMAT
 * (unreadable, or samples beyond the bit depth: names the file) or SIZE_MISMATCH (names this
 * file and the reference file with both shapes, or frames.json's width/height). */
DsImage *ds_phase_folder_read (DsPhaseFolder *folder, guint i, GError **error);
/* The dark frame: the black files averaged (integer frames rounded to the nearest DN, as
 * descatterd averages its dark frames); folder->black_file must be set. Same checks. */
DsImage *ds_phase_folder_read_black (DsPhaseFolder *folder, GError **error);

/* Natural order: runs of digits compare by value, other characters case-insensitively. */
int ds_natural_compare (const char *a, const char *b);

/* Private to proc/phase_folder*.c: parses dir/frames.json into folder (frames, black files,
 * sidecar). */
gboolean ds_phase_folder_read_sidecar (DsPhaseFolder *folder, const char *path, DsSidecarReader read,
                                       GError **error);

G_END_DECLS
