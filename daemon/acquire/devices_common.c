/* What every user of DsDevices needs whatever backends it holds (closing goes through the ops;
 * camera settings come from the stored [camera] ones), apart from the configuration-to-backend
 * mapping in devices.c: the sequencer and its tests need only this. */
#include "daemon/acquire/devices.h"

void
ds_devices_close (DsDevices *dev)
{
  if (!dev)
    return;
  /* Trigger first: the software trigger borrows the camera. */
  ds_trigger_close (dev->trigger);
  ds_illuminator_close (dev->illuminator);
  ds_camera_close (dev->camera);
  if (dev->owner && dev->free_owner)
    dev->free_owner (dev->owner);
  g_free (dev->description);
  g_free (dev);
}

void
ds_devices_camera_settings (const DsDevices *devices, double exposure_us, double gain_db,
                            DsCameraSettings *out)
{
  *out = devices->camera_settings;
  out->exposure_us = exposure_us;
  out->gain_db = gain_db;
}
