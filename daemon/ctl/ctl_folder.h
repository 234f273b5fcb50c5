/* What the offline commands (separate, calibrate) learn about a phase folder before using it:
 * the stripe period (given, from frames.json, or detected in the frames) and the phase each
 * frame really shows, measured as descatterd verifies its frames (proc/stripe_phase.h,
 * proc/phase_order.h). */
#pragma once
#include <glib.h>

#include "proc/phase_folder.h"
#include "proc/phase_order.h"

G_BEGIN_DECLS

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

void ds_folder_phases_clear (DsFolderPhases *fp);
G_DEFINE_AUTO_CLEANUP_CLEAR_FUNC (DsFolderPhases, ds_folder_phases_clear)

/* period_px: --period (NAN: frames.json's, else detected). check: measure every frame's phase.
 * strict: a reordering is refused instead of applied. Fails PHASE_ORDER (frames between phases,
 * phases without a frame, or any reordering when strict), naming the files, or when a frame
 * cannot be read. */
gboolean ds_folder_phases_find (DsPhaseFolder *folder, double period_px, gboolean check,
                                gboolean strict, DsFolderPhases *out, GError **error);

G_END_DECLS
