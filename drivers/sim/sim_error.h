/* Error domain of the scene simulator (drivers/sim). Codes are stable: add at the end. */
#pragma once
#include <glib.h>

G_BEGIN_DECLS

#define DS_SIM_ERROR (ds_sim_error_quark ())
GQuark ds_sim_error_quark (void);

typedef enum {
  DS_SIM_ERROR_INVALID = 1, /* a value outside its allowed range, an unknown name */
  DS_SIM_ERROR_PARSE = 2,   /* malformed scene text, unknown or missing group/key */
  DS_SIM_ERROR_IO = 3,      /* a file could not be read or written */
  DS_SIM_ERROR_NUMERIC = 4, /* a computation failed (convolution, transport) */
  DS_SIM_ERROR_TOO_COSTLY = 5, /* the estimated render cost exceeds the scene's ceiling */
} DsSimError;

G_END_DECLS
