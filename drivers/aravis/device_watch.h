/* The Aravis backend's hold on an open device: its reference to the ArvDevice, how it learns
 * that Aravis lost control of it, and the release of both when the camera closes.
 *
 * Why a file of its own: the device must never be finalized while Aravis's heartbeat thread
 * can still reference it in an emission of "control-lost" (descatterd printing "g_object_ref:
 * assertion '!object_already_finalized' failed" on a reconnect, or aborting in g_thread_join).
 * Read in GLib 2.74 (gobject/gsignal.c, g_signal_emit_valist) and Aravis 0.8.26
 * (src/arvgvdevice.c, arv_gv_device_heartbeat_thread, arv_gv_device_finalize):
 * - the heartbeat thread emits through a plain pointer to the device, holding no reference;
 * - "control-lost" is registered with an explicit g_cclosure_marshal_VOID__VOID, so it has no
 *   va marshaller: with a handler connected GLib takes its slow path, which decides under its
 *   signal lock, releases the lock and only then references the instance; a handler
 *   disconnected in between is not looked at any more, so nothing of ours is held in that
 *   window and no count or handler shows that the emission has begun;
 * - with no handler and no emission hook the emission returns under the lock without touching
 *   the instance (the fast path's early return);
 * - the finalize cancels the heartbeat and joins it (its memory stays valid until then).
 * So on a GigE Vision device no handler is connected at all: the heartbeat sets the device's
 * is_controller to FALSE right after its (then empty) emission, and that is what lost reads
 * (arv_gv_device_is_controller). No emission ever references the device, and a reference count
 * of 1 is ours alone. Other devices (USB3 Vision) keep a handler, whose data GLib holds until
 * the last emission that runs it is over; the window above stays open for them (their
 * emitting threads and finalize were not examined: no USB3 Vision camera here). This holds
 * as long as nothing in the process installs an emission hook on "control-lost" (a hook
 * puts every emission on the slow path: tests/drivers/aravis_inprocess.c removes its own).
 *
 * Threads: new, lost and release are called by the camera's owner thread; the handler (USB3
 * Vision) runs on an Aravis thread and only sets an atomic. */
#pragma once
#include <arv.h>

G_BEGIN_DECLS

typedef struct _DsArvDeviceWatch DsArvDeviceWatch;

/* Takes a reference to device and notes whether we control it now. Never fails. */
DsArvDeviceWatch *ds_arv_device_watch_new (ArvDevice *device);

/* TRUE once Aravis reported the loss of the control it had at ds_arv_device_watch_new (its
 * heartbeat, GigE Vision) or "control-lost" (other devices). Does not block. */
gboolean ds_arv_device_watch_lost (const DsArvDeviceWatch *watch);

/* Drops the reference (watch is gone on return; NULL is accepted). The device is finalized on
 * the calling thread when nothing else holds it (the rule); otherwise (frames lent past the
 * close hold the stream, the stream holds the device) a detached thread of its own waits until
 * ours is the last reference and drops it there: never on an Aravis thread, which the finalize
 * joins. Does not block. */
void ds_arv_device_watch_release (DsArvDeviceWatch *watch);

G_END_DECLS
