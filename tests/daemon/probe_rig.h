/* What the probe tests against the simulator (test_probe_sim.c, test_probe_objects.c) share:
 * pilot frames rendered from a scene text as `descatterctl validate` takes them, probed as
 * descatterd probes, and the renderer's own truth to compare the probe with.
 *
 * Not a rig of its own: the calibrated simulated rig of `descatterctl validate`
 * (daemon/ctl/sim_rig.h), so that the tests probe exactly the frames the validation probes. */
#pragma once
#include "daemon/ctl/sim_rig.h"
#include "daemon/ctl/validate.h"

G_BEGIN_DECLS

/* The calibrated simulated rig of the scene `text` (named `name` in messages), seed 1, its pilot
 * probed into *vs; aborts the test on any error. */
DsSimRig *probe_rig_new_probed (const char *text, const char *name, DsValidateScene *vs);

/* Probes the scene `text` (named `name` in messages) on the calibrated simulated rig, seed 1, into
 * *vs; aborts the test on any error. *leak_truth is the renderer's share of the direct light that
 * its scattered light adds to the stripes' first harmonic (its kernel's MTF at 1/period times the
 * scattered light in the cone over the direct light; 0 without direct light). If gain_truth is not
 * NULL it gets the sensor's system gain in DN^2 per DN, which is a frame's shot noise at the
 * pilot's 0 dB gain. */
void probe_rig_probe_scene (const char *text, const char *name, DsValidateScene *vs, double *leak_truth,
                            double *gain_truth);

G_END_DECLS
