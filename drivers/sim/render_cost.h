/* What rendering a scene will cost, estimated from the scene alone before anything is built,
 * so that a scene within every key's range (photons up to 1e10, a 16384 x 16384 sensor) but
 * beyond the machine is refused in milliseconds instead of running for hours.
 *
 * The model: the Monte Carlo kernels follow photons x interactions per photon, which is the
 * smaller of the absorption bound (the weight falls by the albedo mu_s/mu_t per interaction
 * until the roulette threshold 1e-4) and the escape bound (a random walk of transport mean
 * free paths leaves a slab of optical thickness tau after about tau + tau x tau' steps); a
 * frame follows the pixels rendered (the sensor, and for scattering the kernel's core at full
 * resolution and its margin in 8 x 8 blocks) times the stages' work per pixel. Seconds are these counts at rates measured on the reference
 * machine (docs/scene-format.md, "Render cost"); `descatter-sim describe` prints the estimate
 * beside the measured cost. Pure functions, any thread. */
#pragma once
#include <glib.h>

#include "drivers/sim/scene.h"

G_BEGIN_DECLS

typedef struct {
  double interactions_per_photon; /* 0 without Monte Carlo kernels */
  double kernel_s;                /* computing the kernels (0 when none; counted even if cached) */
  guint64 frame_pixels;           /* sensor plus margin */
  double frame_s;                 /* one frame */
  double total_s;                 /* kernels and one frame: what `describe` and a first frame wait */
} DsRenderCost;

void ds_render_cost_estimate (const DsSceneSpec *spec, DsRenderCost *cost);

/* Refuses (DS_SIM_ERROR_TOO_COSTLY) a scene whose estimate exceeds its [scene] max-render-s,
 * naming the estimate, its parts and what lowers it. */
gboolean ds_render_cost_check (const DsScene *scene, GError **error);

G_END_DECLS
