/* Proof that a frame was lit with the phase the sequencer applied: the stripe phase measured in
 * the frame itself (proc/stripe_phase) is compared with k/N plus the illuminator's own offset
 * (where its phase 0 falls on the sensor), which is learned from the first set whose frames
 * all agree with each other. Acquisition thread only. */
#pragma once
#include <glib.h>

#include "proc/image.h"

G_BEGIN_DECLS

typedef enum {
  DS_PHASE_VERDICT_OK = 0,
  DS_PHASE_VERDICT_WRONG,        /* measured phase is another phase than k */
  DS_PHASE_VERDICT_UNVERIFIABLE, /* no measurable modulation (illuminator off, too much scattering) */
} DsPhaseVerdict;

typedef struct {
  double period_px;
  double tolerance_cycles;   /* |measured - expected| allowed, in periods */
  double min_confidence;     /* below this the measurement is "cannot tell" */
  gboolean offset_known;     /* offset learned from a complete, self-consistent set */
  double offset_cycles;
  /* Provisional offset while the first set is acquired. */
  gboolean provisional;
  double provisional_offset;
} DsPhaseCheck;

void ds_phase_check_init (DsPhaseCheck *check, double period_px, double tolerance_deg);
/* Checks frame (lit with phase k of n), measuring on at least 256 of its rows evenly spread
 * (all rows of a frame with fewer than 512). *measured_cycles receives the measured phase. `why`
 * receives a message when the verdict is not OK. */
DsPhaseVerdict ds_phase_check_frame (DsPhaseCheck *check, const DsImage *frame, guint k, guint n,
                                     double *measured_cycles, char **why);
/* The set the provisional offset came from completed: the offset is now known. */
void ds_phase_check_confirm (DsPhaseCheck *check);
/* The set failed while the offset was provisional: forget it. */
void ds_phase_check_abandon (DsPhaseCheck *check);

G_END_DECLS
