/* The pixels of results, allocated once and shared without copies: "one copy of the pixels"
 * (docs/design.md). A DsPlanePool keeps the planes of results nobody holds any more, so that a
 * new set writes into memory that is already mapped; DsResultPlanes is one result's separation,
 * reference-counted by the result and by every payload sent from it (GBytes over the planes),
 * and goes back to its pool when the last of them lets go.
 *
 * Threads: the pool and the planes may be used from any thread (the acquisition thread takes,
 * the main thread releases); one mutex guards the pool's free list. */
#pragma once
#include <glib.h>

#include "proc/separation.h"

G_BEGIN_DECLS

typedef struct DsPlanePool DsPlanePool;

/* Keeps at most max_free released separations; more are freed. */
DsPlanePool *ds_plane_pool_new (guint max_free);
DsPlanePool *ds_plane_pool_ref (DsPlanePool *pool);
void ds_plane_pool_unref (DsPlanePool *pool);
G_DEFINE_AUTOPTR_CLEANUP_FUNC (DsPlanePool, ds_plane_pool_unref)

/* Planes for a width x height result, to pass to ds_phase_set_finalize_reusing: a released
 * separation of that size, else new transmissive, scattered (f32) and mask (u8) planes with
 * packed rows (so payloads need no copy), written once here so that their first-touch page
 * faults happen now rather than after the last frame of a set. NULL only when allocation fails. */
DsSeparation *ds_plane_pool_take (DsPlanePool *pool, guint width, guint height, GError **error);
/* Takes sep back (NULL-safe): kept for a later take, or freed. */
void ds_plane_pool_give (DsPlanePool *pool, DsSeparation *sep);
/* Separations kept for reuse now. */
guint ds_plane_pool_n_free (DsPlanePool *pool);

typedef struct DsResultPlanes DsResultPlanes;

/* Takes ownership of sep; pool (may be NULL: sep is then freed at the end) gets it back when
 * the last reference goes. */
DsResultPlanes *ds_result_planes_new (DsSeparation *sep, DsPlanePool *pool);
DsResultPlanes *ds_result_planes_ref (DsResultPlanes *planes);
void ds_result_planes_unref (DsResultPlanes *planes);
const DsSeparation *ds_result_planes_separation (const DsResultPlanes *planes);
/* The pixels of `image` (one of the separation's planes), rows packed, as bytes: without a copy
 * when its rows are already packed (the bytes then hold a reference on the planes), else a
 * packed copy. */
GBytes *ds_result_planes_bytes (DsResultPlanes *planes, const DsImage *image);

G_END_DECLS
