#include "drivers/labsim/gpio_light.h"

DsGpioLight
ds_gpio_light_read (const int *levels, guint n, guint *phase, guint *n_phases)
{
  guint lit = 0, starts = 0, start = 0;
  for (guint j = 0; j < n; j++) {
    if (!levels[j])
      continue;
    lit++;
    if (!levels[(j + n - 1) % n]) { /* a run begins here (circularly) */
      starts++;
      start = j;
    }
  }
  if (lit == 0)
    return DS_GPIO_LIGHT_DARK;
  if (lit == n) {
    *n_phases = 2 * n;
    *phase = 0;
    return DS_GPIO_LIGHT_ALL;
  }
  if (starts != 1)
    return DS_GPIO_LIGHT_GARBLED;
  /* Centre of [start/n, (start + lit)/n) in units of 1/(2n). */
  *n_phases = 2 * n;
  *phase = (2 * start + lit) % (2 * n);
  return DS_GPIO_LIGHT_STRIPE;
}
