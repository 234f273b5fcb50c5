#include "drivers/sim/sim_error.h"

G_DEFINE_QUARK (ds-sim-error-quark, ds_sim_error)
