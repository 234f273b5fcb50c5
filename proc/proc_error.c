#include "proc/proc_error.h"

G_DEFINE_QUARK (ds-proc-error-quark, ds_proc_error)
