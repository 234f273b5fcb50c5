/* A fast rig for the daemon's rate benchmarks: Aravis's own GigE Vision fake camera
 * (ArvGvFakeCamera, served from this process on 127.0.0.1) whose fill is a memcpy of a frame
 * prebuilt per stripe phase, its software trigger polled at 1 kHz (its thread sleeping between
 * the polls: fake_rig.c), and the lab's Modbus TCP illuminator controller
 * (drivers/labsim/modbus_server.h) in-process, whose lit phase chooses the frame. The frames
 * are the closed-form scene of the sequencer's tests (tests/common/stripe_scene.h) at period
 * 16 px, 12 bits in Mono16; so maxmin gives transmissive 1000 and scattered 604 exactly (no
 * noise). Nothing here depends on labsim's renderer.
 *
 * A rig of its own, not labsim: the benchmark measures the daemon, so its camera must cost no
 * more than a copy per frame and give frames known exactly, which labsim's rendered scenes with
 * per-frame sensor noise do not. */
#pragma once
#include <glib.h>

#include "drivers/labsim/modbus_server.h"
#include "tests/common/stripe_scene.h"

G_BEGIN_DECLS

#define FAKE_RIG_PERIOD_PX 16.0
#define FAKE_RIG_DIRECT_DN STRIPE_SCENE_DIRECT_DN
#define FAKE_RIG_DARK_DN STRIPE_SCENE_DARK_DN
#define FAKE_RIG_SCATTERED_EXPECTED STRIPE_SCENE_SCATTERED_DN

typedef struct FakeRig FakeRig;

/* Serves a width x height Mono16 camera for n_phases phases; settle_us is the illuminator's
 * settle time. Fails (NULL, message on stderr) when UDP 3956 on 127.0.0.1 is taken. */
FakeRig *fake_rig_new (guint width, guint height, guint n_phases, guint settle_us);
void fake_rig_free (FakeRig *rig);
guint fake_rig_modbus_port (const FakeRig *rig);
void fake_rig_set_settle_us (FakeRig *rig, guint settle_us);
/* Frames the camera filled so far. */
guint64 fake_rig_frames (FakeRig *rig);
/* CPU time (user + system, seconds) the camera's thread used so far; NAN before its first
 * frame. */
double fake_rig_camera_cpu_s (FakeRig *rig);

/* The camera's cycles between from_us and to_us (g_get_monotonic_time, which is
 * CLOCK_MONOTONIC: the same clock in every process): the intervals between consecutive fills,
 * each the poll instant at which the camera took a trigger, rounded to whole trigger-poll
 * periods. A camera that polls its trigger every millisecond starts a frame only on the
 * millisecond: a cycle of 2.0x ms takes 3 ms. Added to counts[i]: the intervals of i periods
 * (i < n_bins - 1), counts[n_bins - 1] those of n_bins - 1 or more; added to by_phase_us[k]
 * and by_phase_n[k] (each as long as the rig's phases): their duration in microseconds and
 * number, by the phase lit at the fill that began them. Intervals longer than
 * FAKE_RIG_CYCLE_MAX_PERIODS periods (no trigger: between slices) are left out. Returns the
 * number of fills in the interval, counted or not. Any thread. */
#define FAKE_RIG_CYCLE_MAX_PERIODS 20
guint64 fake_rig_cycles (FakeRig *rig, gint64 from_us, gint64 to_us, guint64 *counts, guint n_bins,
                         double *by_phase_us, guint64 *by_phase_n);
/* The trigger-poll period in microseconds. */
guint64 fake_rig_trigger_period_us (const FakeRig *rig);

G_END_DECLS
