/* Which phase each frame of a set really shows: the stripe phase measured in every frame
 * (ds_stripe_phase_measure, as the daemon verifies its frames) against the phase index the set
 * gives it, so that swapped, missing or duplicated phases of an offline folder are found
 * instead of separated silently (docs/phase-folder.md).
 *
 * Phase k lights stripes at k/N + offset cycles. The offset (where phase 0 falls) is the
 * folder's when known, else the one that puts the most frames on their given phase, so that a
 * single misplaced frame is found whatever its position. Pure functions, any thread. */
#pragma once
#include <glib.h>

#include "proc/image.h"

G_BEGIN_DECLS

typedef struct {
  guint given;          /* the phase index the folder gives (input) */
  gboolean measured;    /* input: a phase could be measured, precisely enough to tell phases apart */
  double phase;         /* input: measured stripe phase, cycles */
  int found;            /* output: the phase index the measurement shows; -1: not measured, or
                           between two phases (residual beyond the tolerance) */
  double residual;      /* output: cycles from phase `found` (or from the nearest phase) */
} DsPhaseOrderFrame;

typedef enum {
  DS_PHASE_ORDER_OK = 0,        /* every measured frame shows its given phase */
  DS_PHASE_ORDER_REORDERED = 1, /* frames show other phases, and every phase keeps as many
                                   frames as it was given: folding by `found` is right */
  DS_PHASE_ORDER_BROKEN = 2,    /* a frame between phases, or a phase without a frame */
  DS_PHASE_ORDER_UNKNOWN = 3,   /* no frame could be measured */
} DsPhaseOrderVerdict;

/* Fills found/residual of every frame and returns the verdict. tolerance: largest residual
 * accepted, in cycles (the daemon's default is a quarter of the phase step, 0.25/N). *offset:
 * input when offset_known, else output (NAN when nothing was measured). */
DsPhaseOrderVerdict ds_phase_order_check (DsPhaseOrderFrame *frames, guint n_frames, guint n_phases,
                                          double tolerance, gboolean offset_known, double *offset);

G_END_DECLS
