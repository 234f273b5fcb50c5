/* Frame counters: the accounting of every frame the camera delivered, as status and each
 * result's metadata report it. Kept apart from the result so that the sequencer counts
 * without entering result.c. Any thread: the functions only touch the struct given. */
#pragma once
#include <glib.h>
#include <json-glib/json-glib.h>

G_BEGIN_DECLS

/* Why an acquired frame was not folded. Stable names: `status` and result metadata report
 * them. A grab that times out produced no frame and is counted in `timeouts` instead. */
typedef enum {
  DS_DROP_INCOMPLETE = 0, /* missing packets / short buffer */
  DS_DROP_FRAME_GAP,      /* frame ids not continuous: a frame in between was lost */
  DS_DROP_WRONG_PHASE,    /* stripe phase measured in the frame disagrees with the applied one */
  DS_DROP_STALE,          /* exposed before the phase was applied (flushed or too early) */
  DS_DROP_UNVERIFIABLE,   /* no stripes at the configured period where the scene shows them, or
                           * another period (frames that only cannot tell are folded: `unverified`) */
  DS_DROP_ABORTED,        /* folded into a set that then failed or was abandoned */
  DS_DROP_PREVIEW,        /* a preview for the automatic operating point, never folded */
  DS_DROP_N_REASONS
} DsDropReason;

const char *ds_drop_reason_name (DsDropReason reason);

/* Frame accounting. Invariant (tested): acquired == folded + dropped, and dropped is the sum
 * of by_reason. `folded` counts only frames of published results. */
typedef struct {
  guint64 acquired;       /* frames that came out of the camera (complete or not) */
  guint64 folded;         /* frames folded into a published result */
  guint64 dropped;        /* frames not folded, = sum of by_reason */
  guint64 by_reason[DS_DROP_N_REASONS];
  guint64 retries;        /* re-acquisitions (a frame or a phase) after a drop or device error */
  guint64 timeouts;       /* grabs that returned no frame in time */
  guint64 device_errors;  /* illuminator/camera/trigger operations that failed */
  guint64 unverified;     /* frames that passed without a phase proof: their stripes could not tell
                           * the phases apart (folded, or aborted with their set) */
} DsFrameCounters;

/* Counts n frames dropped for reason (already counted as acquired). */
void ds_frame_counters_drop (DsFrameCounters *counters, DsDropReason reason, guint64 n);
/* A set (or dark frame) that failed: every frame acquired and not dropped yet goes down with
 * it, as aborted, so that the invariant holds without a frame folded into nothing. */
void ds_frame_counters_abort_rest (DsFrameCounters *counters);
/* A set (or dark frame) that succeeded: every frame acquired and not dropped went into it. */
void ds_frame_counters_fold_rest (DsFrameCounters *counters);
/* Adds part to total, field by field. */
void ds_frame_counters_add (DsFrameCounters *total, const DsFrameCounters *part);
/* {acquired, folded, retries, timeouts, device_errors, unverified, dropped, dropped_by_reason{...}}: the
 * `frames` object of status and of a result's metadata (docs/protocol.md). New node. */
JsonNode *ds_frame_counters_to_json (const DsFrameCounters *counters);

G_END_DECLS
