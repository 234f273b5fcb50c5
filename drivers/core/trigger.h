/* The trigger interface: what makes the camera expose. "software" goes through the camera's
 * own trigger op; "gpio" pulses a line wired to the camera's trigger input.
 *
 * Threads: acquisition thread only. Errors: DS_TRIGGER_ERROR with DsDeviceError codes. */
#pragma once
#include <glib.h>

#include "drivers/core/camera.h"
#include "drivers/core/device_error.h"

G_BEGIN_DECLS

typedef struct DsTriggerOps DsTriggerOps;

typedef struct {
  const DsTriggerOps *ops;
  gpointer backend;
} DsTrigger;

struct DsTriggerOps {
  const char *name;        /* "software", "gpio", "sim" */
  /* Fires one exposure. Blocks for the pulse width (GPIO) or one camera round trip.
   * Fails DISCONNECTED, FAULT (line request lost), INVALID. */
  gboolean (*fire) (gpointer backend, GError **error);
  void (*close) (gpointer backend);
};

/* The software trigger: fires through camera->ops->trigger. The camera is borrowed and must
 * outlive the trigger. */
DsTrigger *ds_software_trigger_new (DsCamera *camera);
void ds_trigger_close (DsTrigger *trigger); /* NULL-safe; frees the struct too */
G_DEFINE_AUTOPTR_CLEANUP_FUNC (DsTrigger, ds_trigger_close)

G_END_DECLS
