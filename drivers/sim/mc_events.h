/* Monte Carlo records of single photons (internal to drivers/sim): what the kernels with object
 * planes are built from (slab_kernels.c). One record per photon that left the far face
 * scattered and inside the acceptance cone, DS_MC_EVENT_FLOATS (n_planes) floats:
 *   exit x, exit y (mm, from the beam's entry point), weight (fraction of one launched photon),
 *   then per plane j, from DS_MC_EVENT_PLANE (j): x, y of phi_j, its first crossing after its last
 *   crossing of plane j - 1 (of plane 1: its first), x, y of its last crossing (mm),
 *   2 min(crossings, 127) + (1 if it had not scattered yet at phi_j).
 * A transmitted photon crossed every plane an odd number of times. */
#pragma once
#include <glib.h>

#include "drivers/sim/transport.h"

G_BEGIN_DECLS

#define DS_MC_EVENT_FLOATS(n_planes) (3u + 5u * (n_planes))
#define DS_MC_EVENT_PLANE(j) (3u + 5u * (j))

/* The records in chunk order (same bits for any thread count) and the run's totals. threads 0:
 * one per processor. NULL on invalid input (DS_SIM_ERROR_INVALID). */
GArray *ds_mc_slab_events (const DsSlab *slab, const DsSlabPlanes *planes, guint64 photons, guint64 seed,
                           double acceptance_half_angle_deg, guint threads, DsSlabTally *out, GError **error);

G_END_DECLS
