/* What the sequencer tests' scripted labs (test_sequencer.c, test_sequencer_transfer.c) share:
 * the closed-form scene (tests/common/stripe_scene.h) at SCRIPTED_PERIOD, the devices' common
 * set-up and the fault counters. Each test keeps its own camera and illuminator: they script
 * different things.
 *
 * A rig of its own, not drivers/simdev or labsim: the sequencer's tests drive DsSequencer
 * in-process through device ops they script call by call (exact frames, a fault on the n-th
 * grab, a phase moved during a transfer), which a physics rig rendering scenes cannot promise. */
#pragma once
#include "daemon/acquire/devices.h"
#include "daemon/acquire/result.h"
#include "tests/common/stripe_scene.h"

G_BEGIN_DECLS

#define SCRIPTED_PERIOD 8.0

/* A scripted fault counted down: TRUE on the call that brings *counter to zero, once (0: never). */
gboolean scripted_fault_now (guint *counter);

/* 1 where column x is lit by phase `phase` of n_phases, else 0: stripe_scene_lit () at
 * SCRIPTED_PERIOD, so exactly half of each period's 8 pixels are lit. */
double scripted_stripe_lit (guint x, int phase, guint n_phases);

/* The scene's closed form recovered at every pixel: max - min = STRIPE_SCENE_DIRECT_DN and
 * 2 min = STRIPE_SCENE_SCATTERED_DN. A frame folded into a wrong phase (lit one step off) breaks
 * it at the pixels where the two phases differ. */
void scripted_assert_scene_recovered (const DsResult *r);

/* Devices for ds_sequencer_new's open function: `camera` and `illuminator` ops on `backend`, a
 * software trigger, square stripes of SCRIPTED_PERIOD and duty 1/2 in 8 phases, 100 ms to grab
 * and to settle. */
DsDevices *scripted_devices_new (const DsCameraOps *camera, const DsIlluminatorOps *illuminator, gpointer backend,
                                 const char *description);

G_END_DECLS
