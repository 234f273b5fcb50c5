/* In-process simulated devices: a camera and an illuminator sharing one lab state, so each
 * frame shows the pattern that was applied when it was triggered. Faults can be injected to
 * exercise the sequencer's contract (docs/reliability.md).
 *
 * Threads: the devices follow drivers/core's rules (acquisition thread only); the fault knobs
 * may be changed from any thread (they are read under the lab's lock). */
#pragma once
#include <glib.h>

#include "drivers/core/camera.h"
#include "drivers/core/illuminator.h"
#include "drivers/sim/renderer.h"

G_BEGIN_DECLS

typedef struct {
  double stale;            /* probability: the frame shows the previously applied phase */
  double incomplete;       /* probability: the frame comes back incomplete */
  double timeout;          /* probability: the frame never arrives (no id consumed) */
  double drop;             /* probability: the frame is lost in transit (its id is skipped) */
  double wrong_phase;      /* probability: the illuminator shows k+1 while reporting k */
  double not_ready;        /* probability: set_phase fails BUSY */
  guint disconnect_after;  /* frames; 0 = never. The camera is gone until reconnect. */
  guint faults_after;      /* triggers: the camera's faults (stale, incomplete, timeout, drop,
                              and their counts) spare the first N triggers; 0 = none spared */
  guint drop_every;        /* triggers: every Nth one after faults_after is lost in transit, as
                              drop (a camera that loses frames at a steady rate, with no chance in
                              it); 0 = none */
  /* Counted faults: the next N triggers (camera knobs) or set_phase calls (illuminator knobs)
   * get the fault for sure, before the probabilities above are rolled. Counted down under the
   * lab's lock; 0 = none. */
  guint stale_next, incomplete_next, timeout_next, drop_next, wrong_phase_next, not_ready_next;
  /* Milliseconds the devices take to open (as a camera's discovery or a cold kernel cache
   * would), so that what a daemon does while its devices open can be tried; 0 = none. Read by
   * whoever opens the lab (daemon/acquire/devices.c), not by the lab. */
  guint open_delay_ms;
} DsSimFaults;

/* Parses "name=value,..." (names as in the struct, with '-' for '_': "drop=0.1",
 * "stale-next=2"); the error names the item and the allowed range. NULL or "" gives no
 * faults. */
gboolean ds_sim_faults_parse (const char *text, DsSimFaults *out, GError **error);

typedef struct DsSimLab DsSimLab;

/* Takes ownership of the renderer. */
DsSimLab *ds_sim_lab_new (DsRenderer *renderer, guint64 seed);
DsSimLab *ds_sim_lab_ref (DsSimLab *lab);
void ds_sim_lab_unref (DsSimLab *lab);
G_DEFINE_AUTOPTR_CLEANUP_FUNC (DsSimLab, ds_sim_lab_unref)
void ds_sim_lab_set_faults (DsSimLab *lab, const DsSimFaults *faults);
/* The illuminator projects any stripe period of 2 px or more (a projector with a PERIOD
 * register: DsIlluminatorStatus.period_adjustable), or, when fixed, the scene's only and refuses
 * others (UNSUPPORTED). Adjustable by default; set before the illuminator is used. */
void ds_sim_lab_set_period_fixed (DsSimLab *lab, gboolean fixed);
/* The illuminator takes any pattern kind and duty it is asked for, and still draws the scene's
 * stripes (labsim's controller does the same with its PATTERN_KIND and DUTY registers): for a
 * daemon that assumes the configured pattern ([sim] geometry = config). Refuses otherwise
 * (INVALID). Set before the illuminator is used. */
void ds_sim_lab_set_any_pattern (DsSimLab *lab, gboolean any);
const DsRenderer *ds_sim_lab_renderer (const DsSimLab *lab);

/* The devices hold a reference on the lab. */
DsCamera *ds_sim_camera_new (DsSimLab *lab);
DsIlluminator *ds_sim_illuminator_new (DsSimLab *lab);

G_END_DECLS
