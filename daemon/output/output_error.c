#include "daemon/output/output_error.h"

G_DEFINE_QUARK (ds-output-error-quark, ds_output_error)
