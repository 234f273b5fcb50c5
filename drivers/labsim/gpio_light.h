/* What a stripe projector driven by GPIO lines lights, read from its lines' levels: the light
 * labsim's camera sees when its illuminator is the GPIO chip's stripe lines (--gpio-stripe-lines)
 * instead of the Modbus controller.
 *
 * Geometry (docs/drivers.md, "Illuminator: which line is lit in which phase"): L stripe groups
 * per period, group j lighting [j/L, (j+1)/L) of it. A square stripe of duty a centred at k/N
 * lights the groups j with j/L in [k/N - a/2, k/N + a/2): when a L is even their light tiles
 * that interval and the lit run's centre is k/N; with an odd number of lit groups the light sits
 * half a group late, as it would on the real projector. Pure functions, any thread. */
#pragma once
#include <glib.h>

G_BEGIN_DECLS

typedef enum {
  DS_GPIO_LIGHT_DARK,      /* no group lit (or the enable line low) */
  DS_GPIO_LIGHT_STRIPE,    /* one run of lit groups: *phase / *n_phases is its centre */
  DS_GPIO_LIGHT_GARBLED,   /* lit groups in more than one run */
  DS_GPIO_LIGHT_ALL,       /* every group lit: the whole field (the illuminator's all_on) */
} DsGpioLight;

/* levels[j] for group j (0 or 1), n_groups 2..64. For a stripe, *n_phases is 2 n_groups (the
 * centre falls on a half group when the run is odd). */
DsGpioLight ds_gpio_light_read (const int *levels, guint n_groups, guint *phase, guint *n_phases);

G_END_DECLS
