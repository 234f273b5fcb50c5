/* What the offline commands (separate, calibrate) learn about a phase folder before using it:
 * the stripe period (given, from frames.json, or detected in the frames) and the phase each
 * frame really shows, measured as descatterd verifies its frames (proc/stripe_phase.h,
 * proc/phase_order.h). */
#pragma once
#include <glib.h>

#include "proc/phase_folder.h"
#include "proc/phase_order.h"

G_BEGIN_DECLS

/* frames.json's bounds: a sidecar lists a few lines per frame, so 4 MiB holds tens of
 * thousands of frames; its deepest real nesting is 3 (root, frames, a frame). */
#define DS_SIDECAR_MAX_BYTES (4u << 20)
#define DS_SIDECAR_MAX_DEPTH 16u

/* The sidecar reader the offline commands give ds_phase_folder_open: the protocol's strict
 * JSON reader within the bounds above (daemon/protocol/json_file.h). */
JsonNode *ds_folder_read_sidecar (const char *path, GError **error);

typedef struct {
  double period_px;           /* NAN when unknown */
  const char *period_source;  /* "--period", "frames.json", "detected" or NULL */
  double offset_cycles;       /* where phase 0 falls; NAN when unknown */
  gboolean offset_measured;   /* measured in the frames (not frames.json's) */
  DsPhaseOrderVerdict verdict;
  gboolean checked;           /* the frames' phases were measured */
  guint *fold_phase;          /* per frame: the phase it is folded as */
  DsPhaseOrderFrame *frames;  /* per frame: given, measured, found (when checked) */
  char *notice;               /* what the user should know (reordering, an unverified order) */
} DsFolderPhases;

/* What an offline command may take on before it decodes anything (--max-side, --max-pixels,
 * --max-memory). A PNG of a few megabytes can declare 30000 x 30000 pixels, which the decoder
 * allocates in full: the header is read first and checked against these. */
typedef struct {
  guint64 max_side;    /* pixels per side; default DS_FOLDER_MAX_SIDE */
  guint64 max_pixels;  /* width x height; default DS_FOLDER_MAX_PIXELS */
  guint64 max_memory;  /* bytes the command may need; 0: what the system has available */
} DsFolderLimits;
#define DS_FOLDER_MAX_SIDE 16384u
#define DS_FOLDER_MAX_PIXELS (64u << 20)

void ds_folder_limits_init (DsFolderLimits *limits);
/* The limits from the options (0: the default; max_memory_mib in MiB). Fails
 * DS_PROC_ERROR_INVALID_ARGUMENT on a negative value, naming the option. */
gboolean ds_folder_limits_from_options (DsFolderLimits *limits, gint64 max_side, gint64 max_pixels,
                                        gint64 max_memory_mib, GError **error);
/* The three options' GOptionEntry lines, for separate and calibrate alike. */
#define DS_FOLDER_LIMIT_OPTIONS(side, pixels, mib)                                                              \
  { "max-side", 0, 0, G_OPTION_ARG_INT64, (side), "refuse images wider or taller than this, read from the "   \
    "header before decoding (default 16384)", "PX" },                                                          \
  { "max-pixels", 0, 0, G_OPTION_ARG_INT64, (pixels), "refuse images of more pixels than this (default "       \
    "67108864, 64 Mi)", "N" },                                                                                 \
  { "max-memory", 0, 0, G_OPTION_ARG_INT64, (mib), "refuse when the estimated memory needed exceeds this "     \
    "(default: the memory available)", "MIB" }

/* Reads every phase and black file's width and height from its header (no decoding) and
 * refuses, with DS_PROC_ERROR_TOO_LARGE naming the file and the limit, a side or pixel count
 * above the limits; then refuses when bytes_per_pixel x the largest image exceeds
 * limits->max_memory (or, when 0, the memory available: MemAvailable and the address-space
 * limit), naming the estimate. what: the command, for the message ("a separation"). */
gboolean ds_folder_check_images (DsPhaseFolder *folder, const DsFolderLimits *limits, double bytes_per_pixel,
                                 const char *what, GError **error);

void ds_folder_phases_clear (DsFolderPhases *fp);
G_DEFINE_AUTO_CLEANUP_CLEAR_FUNC (DsFolderPhases, ds_folder_phases_clear)

/* period_px: --period (NAN: frames.json's, else detected). check: measure every frame's phase.
 * strict: a reordering is refused instead of applied. Fails PHASE_ORDER (frames between phases,
 * phases without a frame, or any reordering when strict), naming the files, or when a frame
 * cannot be read. */
gboolean ds_folder_phases_find (DsPhaseFolder *folder, double period_px, gboolean check,
                                gboolean strict, DsFolderPhases *out, GError **error);

G_END_DECLS
