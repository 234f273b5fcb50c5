/* Error domain of the operating model (daemon/operating/): the scene probe, the pilot checks, the
 * error model and the choice of the operating point. Codes are stable; the daemon maps them to
 * wire codes in one table (daemon/service/wire_error.c), so nothing here knows the protocol. */
#pragma once
#include <glib.h>

G_BEGIN_DECLS

#define DS_OPERATING_ERROR (ds_operating_error_quark ())
GQuark ds_operating_error_quark (void);

typedef enum {
  DS_OPERATING_ERROR_PILOT_FRAMES = 1,       /* a pilot frame is missing, or differs in size or type */
  DS_OPERATING_ERROR_NO_MODULATION = 2,      /* no stripe modulation above the noise: no direct light */
  DS_OPERATING_ERROR_CLIPPED = 3,            /* the pilot's pixels clip: most of them, or the brightest
                                                whatever the exposure */
  DS_OPERATING_ERROR_NO_STRIPES = 4,         /* the pilot check sees no stripes at the period */
  DS_OPERATING_ERROR_CONFIGURATION = 5,      /* the error model has no such configuration, or it leaves
                                                no valid pixel */
  DS_OPERATING_ERROR_UNREACHABLE = 6,        /* no operating point meets the target within the budget */
} DsOperatingError;

G_END_DECLS
