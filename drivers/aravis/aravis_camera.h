/* The Aravis camera backend: a GigE Vision (or USB3 Vision) camera through libaravis, behind
 * the DsCamera ops of drivers/core/camera.h.
 *
 * - Opened by IP address ("192.168.1.20", "127.0.0.1") or by Aravis device id
 *   ("Vendor-Model-Serial"). Prefer the address for GigE Vision: it is unambiguous, while an id
 *   may be found on the wrong interface (the loopback fake camera shows up on several).
 * - Triggered acquisition only (TriggerSelector FrameStart, TriggerMode On, TriggerSource
 *   Software or LineN). The buffer pool is allocated once per stream (n_buffers buffers of one
 *   payload); every buffer, good or bad, goes back to the pool before grab returns.
 * - GV streams: socket buffer AUTO, packet resend ALWAYS (cameras that do not resend simply
 *   leave the request unanswered; the frame then comes back INCOMPLETE).
 * - Frame ids are extended across the 16-bit GigE Vision wrap (drivers/core/frame.h); gaps go
 *   to DsFrame.ids_skipped and DsCameraStats.ids_skipped. A grab that timed out and a frame
 *   without its own id (its leader lost: Aravis leaves the buffer's previous id) are noted as
 *   losses, so their missing ids are no gap for the next frame.
 * - Aravis's loss of control (its GigE Vision heartbeat giving up: arv_gv_device_is_controller;
 *   "control-lost" on other devices) marks the backend DISCONNECTED: trigger and grab fail
 *   DISCONNECTED until ops->reconnect reopens the device (by the same address) and reapplies
 *   the last settings. The camera is left stopped after a reconnect. A device is never
 *   finalized on an Aravis thread (device_watch.h).
 *
 * Threads: as drivers/core/camera.h (one caller thread). Aravis runs its own stream and
 * heartbeat threads; the only state of ours they touch is an atomic flag (USB3 Vision). */
#pragma once
#include <glib-object.h>

#include "drivers/core/camera.h"

G_BEGIN_DECLS

/* Connects to the camera (blocks for GVCP round trips, a few seconds at most when nothing
 * answers). n_buffers: size of the buffer pool (>= 2). Fails DS_CAMERA_ERROR DISCONNECTED
 * when no camera answers at address_or_id, INVALID for bad arguments. */
DsCamera *ds_aravis_camera_open (const char *address_or_id, guint n_buffers, GError **error);

/* TRUE when camera is an Aravis backend. */
gboolean ds_aravis_camera_is_aravis (const DsCamera *camera);

/* For tests and diagnostics: buffers the stream holds in its input queue (waiting to be
 * filled) and output queue (filled, not yet grabbed), and the pool size. Buffers that the
 * stream thread is filling right now are in neither queue; after ops->stop every buffer is
 * back in the input queue. All zero when no stream exists. */
void ds_aravis_camera_pool_counts (const DsCamera *camera, guint *n_input, guint *n_output,
                                   guint *n_pool);

/* For tests: the open camera's ArvDevice (borrowed; it goes with the next close or reconnect),
 * NULL when the camera is closed or not an Aravis backend. */
GObject *ds_aravis_camera_device (const DsCamera *camera);

G_END_DECLS
