#include "drivers/core/illuminator.h"

void
ds_illuminator_close (DsIlluminator *illuminator)
{
  if (!illuminator)
    return;
  if (illuminator->ops && illuminator->ops->close)
    illuminator->ops->close (illuminator->backend);
  g_free (illuminator);
}

gboolean
ds_illuminator_all_on (DsIlluminator *illuminator, guint timeout_ms, GError **error)
{
  if (!illuminator->ops->all_on) {
    g_set_error (error, DS_ILLUMINATOR_ERROR, DS_DEVICE_ERROR_UNSUPPORTED,
                 "%s illuminator: cannot light all stripes at once (light a phase instead)", illuminator->ops->name);
    return FALSE;
  }
  return illuminator->ops->all_on (illuminator->backend, timeout_ms, error);
}
