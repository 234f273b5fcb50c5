/* The lighting states labsim's camera serves, rendered off the GigE Vision thread.
 *
 * A lighting state is the light reaching the sensor (f32 photons per pixel,
 * ds_renderer_render_photons) for one thing the illuminator can show: dark, every stripe lit,
 * or phase k of N at a stripe period. It is rendered once, at the scene's default exposure, and serves every
 * exposure and gain: the expected DN is linear in both (docs/drivers.md, "descatter-labsim").
 * A generated scene with a wide kernel and several object planes takes seconds per state; the
 * camera thread also answers GVCP, so it must never wait for one (a few seconds there and the
 * client reports "control lost"). So states are rendered
 *   - before the camera appears: the whole set the controller shows at power-up (every phase of
 *     its phase count and period, and dark), ds_lab_states_prepare;
 *   - by a worker thread afterwards: it watches the light (every 20 ms) and renders the whole
 *     set again when the phase count or the period changes; a state asked for by a trigger
 *     (ds_lab_states_get) goes first.
 * Beyond 512 MiB the states of sets other than the current one are dropped.
 *
 * The light is sampled through the DsLabIlluminationFunc, called from one thread at a time
 * (this object's lock): the external controller's Modbus connection is not shared.
 *
 * Threads: new/free/prepare on the main thread; the rest from any thread. */
#pragma once
#include <glib.h>

#include "drivers/labsim/lab_camera.h"

G_BEGIN_DECLS

/* What the illuminator shows, as far as the light is concerned. */
typedef struct {
  gboolean on;
  gboolean all_on;       /* on, every stripe lit (phase then 0) */
  guint phase, n_phases; /* 0, 0 when dark */
  double period_px;      /* 0: the scene's; 0 when dark */
} DsLabLight;

typedef struct {
  DsLabLight light;
  float *photons;        /* width x height, at reference_exposure_us */
  double reference_exposure_us;
  double render_s;       /* how long it took */
} DsLabState;

typedef struct DsLabStates DsLabStates;

DsLabStates *ds_lab_states_new (const DsRenderer *renderer, DsLabIlluminationFunc illumination,
                                gpointer user_data);
/* Renders, on the calling thread, every state of the set lit now, then starts the worker.
 * Blocks for as long as that takes (n states, seconds). Fails (DS_SIM_ERROR) when a render
 * does. */
gboolean ds_lab_states_prepare (DsLabStates *states, guint *n_rendered, double *seconds, GError **error);
/* The light now (the illumination function, serialised). Non-blocking except for an external
 * controller's Modbus read (its response timeout, 200 ms). */
void ds_lab_states_sample (DsLabStates *states, DsLabLight *light);
/* The state of `light` (a new reference), waiting for it until `deadline` (monotonic µs;
 * 0: do not wait). NULL when it is not ready by then: it is then rendered first. */
DsLabState *ds_lab_states_get (DsLabStates *states, const DsLabLight *light, gint64 deadline);
DsLabState *ds_lab_state_ref (DsLabState *state);
void ds_lab_state_unref (DsLabState *state);
/* States rendered so far (prepare and worker), and their total time. */
void ds_lab_states_rendered (DsLabStates *states, guint64 *n, double *seconds);
void ds_lab_states_free (DsLabStates *states);
G_DEFINE_AUTOPTR_CLEANUP_FUNC (DsLabState, ds_lab_state_unref)
G_DEFINE_AUTOPTR_CLEANUP_FUNC (DsLabStates, ds_lab_states_free)

G_END_DECLS
