#include "daemon/operating/operating_error.h"

G_DEFINE_QUARK (ds-operating-error-quark, ds_operating_error)
