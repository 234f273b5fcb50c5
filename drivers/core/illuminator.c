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
