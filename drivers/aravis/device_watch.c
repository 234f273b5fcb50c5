#include "drivers/aravis/device_watch.h"

struct _DsArvDeviceWatch {
  ArvDevice *device;  /* the backend's reference */
  gboolean had_control; /* GigE Vision: Aravis took control at open (another host may hold it) */
  gulong handler_id;  /* other devices: "control-lost" */
  gint refs;          /* atomic: the owner's, and the handler's (released by GLib) */
  gint lost;          /* atomic: set by the handler */
};

static void
watch_unref (DsArvDeviceWatch *w)
{
  if (g_atomic_int_dec_and_test (&w->refs))
    g_free (w);
}

/* GLib drops the handler's data once the handler is disconnected and no emission runs it. */
static void
handler_data_released (gpointer data, GClosure *closure)
{
  (void) closure;
  watch_unref (data);
}

static void
on_control_lost (ArvDevice *device, gpointer data)
{
  (void) device;
  DsArvDeviceWatch *w = data;
  g_atomic_int_set (&w->lost, 1);
}

DsArvDeviceWatch *
ds_arv_device_watch_new (ArvDevice *device)
{
  DsArvDeviceWatch *w = g_new0 (DsArvDeviceWatch, 1);
  w->device = g_object_ref (device);
  w->refs = 1;
  if (ARV_IS_GV_DEVICE (device)) {
    w->had_control = arv_gv_device_is_controller (ARV_GV_DEVICE (device));
    return w;
  }
  g_atomic_int_inc (&w->refs);
  w->handler_id = g_signal_connect_data (device, "control-lost", G_CALLBACK (on_control_lost), w,
                                         handler_data_released, 0);
  return w;
}

gboolean
ds_arv_device_watch_lost (const DsArvDeviceWatch *w)
{
  if (ARV_IS_GV_DEVICE (w->device))
    return w->had_control && !arv_gv_device_is_controller (ARV_GV_DEVICE (w->device));
  return g_atomic_int_get ((gint *) &w->lost) != 0;
}

/* The handler's data first: an emission that runs the handler holds the device meanwhile. */
static gboolean
last_holder (DsArvDeviceWatch *w)
{
  return g_atomic_int_get (&w->refs) == 1 &&
         g_atomic_int_get ((gint *) &G_OBJECT (w->device)->ref_count) == 1;
}

static void
drop (DsArvDeviceWatch *w)
{
  g_object_unref (w->device); /* the last: finalized here, the heartbeat thread joined from here */
  watch_unref (w);
}

/* No notification of the count's fall runs on a thread of ours (a toggle reference notifies on
 * the thread that drops it), hence the poll: it waits for a condition, not for a time. */
static gpointer
release_thread (gpointer data)
{
  DsArvDeviceWatch *w = data;
  gulong wait_us = 100;
  while (!last_holder (w)) {
    g_usleep (wait_us);
    wait_us = MIN (wait_us * 2, 20000ul);
  }
  drop (w);
  return NULL;
}

void
ds_arv_device_watch_release (DsArvDeviceWatch *w)
{
  if (!w)
    return;
  if (w->handler_id)
    g_signal_handler_disconnect (w->device, w->handler_id);
  if (last_holder (w)) {
    drop (w);
    return;
  }
  /* Detached: the lent frames it may wait for are freed by the very thread that would join it. */
  g_thread_unref (g_thread_new ("arv-device-release", release_thread, w));
}
