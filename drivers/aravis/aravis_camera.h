/* The Aravis camera backend: a GigE Vision (or USB3 Vision) camera through libaravis, behind
 * the DsCamera ops of drivers/core/camera.h.
 *
 * - Opened by IP address ("192.168.1.20", "127.0.0.1") or by Aravis device id
 *   ("Vendor-Model-Serial"). Prefer the address for GigE Vision: it is unambiguous, while an id
 *   may be found on the wrong interface (the loopback fake camera shows up on several).
 * - Triggered acquisition only (TriggerSelector FrameStart, TriggerMode On, TriggerSource
 *   Software or LineN). The buffer pool is allocated once per stream (n_buffers buffers of one
 *   payload); every buffer, good or bad, goes back to the pool before grab returns.
 * - GV streams: a receive buffer of several payloads and a frame retention the caller chooses
 *   (DsAravisStreamOptions), packet resend ALWAYS (cameras that do not resend simply leave the
 *   request unanswered; the frame then comes back INCOMPLETE).
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

/* How the stream receives frames. The GigE Vision ones apply to GV streams only, from the next
 * stream on (configure makes a new one). */
typedef struct {
  guint n_buffers;             /* the buffer pool: 2..1024 */
  /* GigE Vision: the UDP receive buffer asked for, in payloads (1..64). Packets that arrive
   * while the stream's thread waits for a CPU wait there; when it is full they are lost, and
   * their frame comes back INCOMPLETE after frame_retention_ms. Aravis's own choice (AUTO) is
   * one payload, which the kernel's per-packet accounting fills before a whole frame is in.
   * The kernel caps the buffer at net.core.rmem_max: the backend says so (g_message) when
   * that leaves less than asked. */
  guint receive_buffer_frames;
  /* GigE Vision: how long a frame missing packets waits after its last packet, for resent or
   * late ones, before it comes back INCOMPLETE (1..10000 ms; Aravis's default is 100). A
   * camera that resends needs Aravis's packet timeouts (20 ms) and a resend round trip. */
  guint frame_retention_ms;
} DsAravisStreamOptions;

/* The defaults descatterd.conf documents: 8 buffers, 4 payloads of receive buffer, 100 ms. */
#define DS_ARAVIS_STREAM_OPTIONS_DEFAULT ((DsAravisStreamOptions) { 8, 4, 100 })

/* Connects to the camera (blocks for GVCP round trips, a few seconds at most when nothing
 * answers). Fails DS_CAMERA_ERROR DISCONNECTED when no camera answers at address_or_id,
 * INVALID for bad arguments (options out of their ranges). */
DsCamera *ds_aravis_camera_open_with (const char *address_or_id, const DsAravisStreamOptions *options,
                                      GError **error);

/* ds_aravis_camera_open_with () with the default options and a pool of n_buffers. */
DsCamera *ds_aravis_camera_open (const char *address_or_id, guint n_buffers, GError **error);

/* TRUE when camera is an Aravis backend. */
gboolean ds_aravis_camera_is_aravis (const DsCamera *camera);

/* For tests and diagnostics: buffers the stream holds in its input queue (waiting to be
 * filled) and output queue (filled, not yet grabbed), and the pool size. Buffers that the
 * stream thread is filling right now are in neither queue; after ops->stop every buffer is
 * back in the input queue. All zero when no stream exists. */
void ds_aravis_camera_pool_counts (const DsCamera *camera, guint *n_input, guint *n_output,
                                   guint *n_pool);

/* For tests: the receive buffer size (bytes) the kernel granted the GV stream's socket, as
 * getsockopt (SO_RCVBUF) reads it (twice what was asked, within net.core.rmem_max: socket(7));
 * 0 when there is no GV stream or its socket is not found. Aravis sets it when a frame's first
 * packet arrives, so read it after a frame. */
gsize ds_aravis_camera_receive_buffer (const DsCamera *camera);

/* For tests: the open camera's ArvDevice (borrowed; it goes with the next close or reconnect),
 * NULL when the camera is closed or not an Aravis backend. */
GObject *ds_aravis_camera_device (const DsCamera *camera);

G_END_DECLS
