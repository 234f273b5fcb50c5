#include "drivers/core/trigger.h"

/* The software trigger borrows the camera: it fires through the camera's own op, so the
 * sequencer drives "software" and "gpio" triggers the same way. */
static gboolean
software_fire (gpointer backend, GError **error)
{
  DsCamera *camera = backend;
  return camera->ops->trigger (camera->backend, error);
}

static void
software_close (gpointer backend)
{
  (void) backend; /* borrowed */
}

static const DsTriggerOps software_ops = {
  .name = "software",
  .fire = software_fire,
  .close = software_close,
};

DsTrigger *
ds_software_trigger_new (DsCamera *camera)
{
  DsTrigger *t = g_new0 (DsTrigger, 1);
  t->ops = &software_ops;
  t->backend = camera;
  return t;
}

void
ds_trigger_close (DsTrigger *trigger)
{
  if (!trigger)
    return;
  if (trigger->ops && trigger->ops->close)
    trigger->ops->close (trigger->backend);
  g_free (trigger);
}
