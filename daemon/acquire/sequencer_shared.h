/* What the main thread and the acquisition thread share: the command queue, the status and
 * defaults under one lock, the atomics that stop the thread, and the way events reach the main
 * context. Everything else the acquisition thread owns alone (acquisition.h).
 *
 * Threads: the main thread pushes commands and reads status (ds_sequencer_get_status); the
 * acquisition thread pops commands and writes status; the fold worker thread adds stage times
 * and reads the frame hook. Every field is either atomic, set before the thread starts and
 * read-only after, or under `lock`, as its comment says. The functions here take the lock
 * briefly and never block on a device. */
#pragma once
#include <glib.h>

#include "daemon/acquire/frame_counters.h"
#include "daemon/acquire/sequencer.h"

G_BEGIN_DECLS

typedef struct {
  /* Set before the thread starts, read-only after. */
  GAsyncQueue *queue;             /* commands, main thread to acquisition thread */
  GMainContext *context;          /* where events are dispatched */
  DsSequencerEventFunc on_event;
  gpointer user_data;

  gint quit;     /* atomic: the daemon is stopping; set by the main thread */
  gint pending;  /* atomic: captures, darks, releases and acquires queued */
  /* Cancellation (ds_sequencer_cancel). cancel_gen counts the cancels: every command is stamped
   * with its value when queued, and work stamped with an older value is cancelled (a running set
   * between two frames, a queued one before its first). Written by the main thread only, which
   * queues the CMD_CANCEL of a new value before publishing it, so the thread always finds that
   * command queued once it sees the new value. cancel_acked: the value of the last CMD_CANCEL the
   * thread took, i.e. every command queued before it was answered; status says `cancelling` while
   * the two differ. */
  gint cancel_gen;
  gint cancel_acked;
  /* Delivery of events after free must not happen: pending events check this first. */
  gint alive;    /* atomic: cleared by ds_sequencer_free once the thread joined */

  GMutex lock;                    /* protects what follows */
  DsSequencerStatus status;       /* written by the acquisition thread, read by the main one */
  DsCaptureSettings defaults;     /* written by the acquisition thread (CMD_DEFAULTS) */
  DsSequencerFrameFunc frame_hook; /* written by the main thread, read by the fold worker */
  gpointer frame_hook_data;
  DsSequencerPreviewFunc preview_hook; /* written by the main thread, read by the acquisition
                                        * thread (preview.c) */
  gpointer preview_hook_data;
} DsSequencerShared;

/* ---- report.c: events and status, from the acquisition thread (and the fold worker's
 * stage times). None blocks beyond the lock. ---- */

/* Posts an event to the main context; events are dispatched in the order they were posted.
 * Takes ownership of result and error. Any thread. */
void ds_seq_emit (DsSequencerShared *shared, DsSequencerEventKind kind, guint64 tag, DsResult *result,
                  GError *error, const char *message);
/* A capture's progress (phase of n done); nothing for tag 0 (continuous sets answer no one). */
void ds_seq_emit_progress (DsSequencerShared *shared, guint64 tag, guint phase, guint n);
void ds_seq_emit_dark (DsSequencerShared *shared, guint64 tag, double dark_mean_dn);

/* The state, with a heartbeat. */
void ds_seq_set_state (DsSequencerShared *shared, DsSequencerState state);
/* A sign of life for the watchdog; ends a ds_seq_blocking declaration. */
void ds_seq_heartbeat (DsSequencerShared *shared);
/* Before a device call that may block: a sign of life, and the call's own bound. The watchdog
 * stays fed while the thread waits that long (a camera timing out is not a wedged thread),
 * and starves beyond it. The next heartbeat ends the declaration. */
void ds_seq_blocking (DsSequencerShared *shared, guint bound_ms);
/* A control round trip with the libraries' own retries (GVCP, Modbus): what a device call
 * without a timeout of its own may take before it fails. */
#define DS_SEQ_CONTROL_BOUND_MS 5000
/* Adds the time since since_us to a stage's total, with a heartbeat. Acquisition thread or
 * fold worker. */
void ds_seq_stage_add (DsSequencerShared *shared, DsStage stage, gint64 since_us);
/* status.last_error. */
void ds_seq_record_error (DsSequencerShared *shared, const GError *error);
/* Adds a set's (or a dark frame's) counters to the totals; ok counts the set as done, else
 * as failed. */
void ds_seq_account (DsSequencerShared *shared, const DsFrameCounters *c, gboolean ok);
/* Adds a failed set's counters to the totals, counts it failed and makes `error` last_error,
 * all at once: no status shows the count without the error. */
void ds_seq_account_failed (DsSequencerShared *shared, const DsFrameCounters *c, const GError *error);
/* Adds frame counters to the totals without counting a set (frames of no set, a dark frame). */
void ds_seq_account_frames (DsSequencerShared *shared, const DsFrameCounters *c);
/* Whether an error ends work because it was cancelled (a cancel, or the daemon stopping):
 * DS_PROTOCOL_ERROR_CANCELLED. */
gboolean ds_seq_error_is_cancel (const GError *error);
/* A set (or dark frame) that did not finish: its frames not dropped already are aborted
 * (counted in c), the totals take them, and the set counts as cancelled when `error` is a
 * cancel (not in last_error: nothing went wrong with the rig), else as failed with `error` as
 * last_error. */
void ds_seq_account_unfinished (DsSequencerShared *shared, DsFrameCounters *c, const GError *error);
/* The frame hook as the main thread set it last (NULL: none). Fold worker or acquisition
 * thread. */
DsSequencerFrameFunc ds_seq_frame_hook (DsSequencerShared *shared, gpointer *user_data);

G_END_DECLS
