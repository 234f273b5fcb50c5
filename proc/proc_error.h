/* Error domain of everything in proc/. Codes are stable: clients and tests match them. */
#pragma once
#include <glib.h>

G_BEGIN_DECLS

#define DS_PROC_ERROR (ds_proc_error_quark ())
GQuark ds_proc_error_quark (void);

typedef enum {
  DS_PROC_ERROR_INVALID_ARGUMENT = 1, /* a parameter outside its documented range */
  DS_PROC_ERROR_SIZE_MISMATCH = 2,    /* frames of a set differ in size, type or depth */
  DS_PROC_ERROR_FORMAT = 3,           /* unknown or inconsistent pixel format / image type */
  DS_PROC_ERROR_IO = 4,               /* a file could not be read or written */
  DS_PROC_ERROR_ILL_CONDITIONED = 5,  /* the estimator's inversion is too unstable (e.g. b near 1) */
  DS_PROC_ERROR_NOT_ENOUGH_PHASES = 6,/* fewer phases than the estimator needs */
  DS_PROC_ERROR_TOO_LARGE = 7,        /* a size whose byte count would overflow or exceed limits */
  DS_PROC_ERROR_EMPTY = 8,            /* no input at all (empty folder, empty set) */
  DS_PROC_ERROR_PRECONDITION = 9,     /* the estimator's assumption fails everywhere (sampling) */
  DS_PROC_ERROR_PHASE_ORDER = 10,     /* frames' measured stripe phases contradict their phase
                                         indices (swapped, missing or duplicated phases) */
} DsProcError;

G_END_DECLS
