/* The projector-sync wiring: the illuminator controller's sync output drives the camera's
 * trigger line, so the camera exposes once each time the controller applies a pattern. There is
 * no separate trigger device: applying *is* triggering.
 *
 * ds_projector_sync_wrap puts this behind the ordinary interfaces, so the sequencer runs
 * unchanged: the returned illuminator records set_phase(k) and off() (each returns at once,
 * nothing is written), and the returned trigger's fire performs the recorded one on the real
 * illuminator, returning once the controller reports it applied (as set_phase does). So every
 * frame the sequencer triggers is exactly one apply, exposed by that apply's sync pulse: one
 * frame per phase, M applies for M averages, and a dark frame per off(). set_pattern,
 * get_status and reconnect pass straight through. Loading a pattern is an apply too: its pulse
 * exposes a frame nobody asked for, which the sequencer flushes as stale.
 *
 * Errors: fire fails with the illuminator's error (DS_ILLUMINATOR_ERROR codes, message
 * prefixed "projector sync: "), so a controller fault fails the frame and the sequencer's
 * retry policy applies. A missed sync pulse shows as a grab TIMEOUT; a double pulse as a
 * surplus frame, flushed (stale) or refused by phase verification.
 *
 * Threads: as the interfaces (the acquisition thread only). */
#pragma once
#include "drivers/core/illuminator.h"
#include "drivers/core/trigger.h"

G_BEGIN_DECLS

/* Takes ownership of `illuminator`; returns the wrapper (close it to close both) and, in
 * *trigger, the trigger, which borrows the wrapper: close the trigger first. */
DsIlluminator *ds_projector_sync_wrap (DsIlluminator *illuminator, DsTrigger **trigger);

G_END_DECLS
