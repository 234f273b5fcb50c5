/* What the sequencer tests' scripted labs (test_sequencer.c, test_sequencer_transfer.c) share:
 * the synthetic scene and its closed form, the devices' common set-up and the fault counters.
 * Each test keeps its own camera and illuminator: they script different things. */
#pragma once
#include "daemon/acquire/devices.h"
#include "daemon/acquire/result.h"

G_BEGIN_DECLS

#define SCRIPTED_PERIOD 8.0

/* A scripted fault counted down: TRUE on the call that brings *counter to zero, once (0: never). */
gboolean scripted_fault_now (guint *counter);

/* 1 where column x is lit by phase `phase` of n_phases, else 0: square stripes of duty 1/2 and
 * period SCRIPTED_PERIOD, centred at x = (j + phase/N) P and sampled at pixel centres (the
 * project's convention, docs/estimators.md), so exactly half of each period's 8 pixels are lit. */
double scripted_stripe_lit (guint x, int phase, guint n_phases);

/* The closed form of the scene both labs render: Ld = 1000 DN of stripes over Lg = 600 DN of
 * global light (300 DN in every frame, in the half-lit convention) and a 2 DN offset, so that
 * max - min = 1000 and 2 min = 604 at every pixel. A frame folded into a wrong phase (lit one
 * step off) breaks it at the pixels where the two phases differ. */
void scripted_assert_scene_recovered (const DsResult *r);

/* Devices for ds_sequencer_new's open function: `camera` and `illuminator` ops on `backend`, a
 * software trigger, square stripes of SCRIPTED_PERIOD and duty 1/2 in 8 phases, 100 ms to grab
 * and to settle. */
DsDevices *scripted_devices_new (const DsCameraOps *camera, const DsIlluminatorOps *illuminator, gpointer backend,
                                 const char *description);

G_END_DECLS
