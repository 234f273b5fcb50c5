#include "drivers/core/camera.h"

void
ds_camera_close (DsCamera *camera)
{
  if (!camera)
    return;
  if (camera->ops && camera->ops->close)
    camera->ops->close (camera->backend);
  g_free (camera);
}
