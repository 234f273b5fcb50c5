/* Error domain of daemon/output (result files). Codes are stable: add at the end. */
#pragma once
#include <glib.h>

G_BEGIN_DECLS

#define DS_OUTPUT_ERROR (ds_output_error_quark ())
GQuark ds_output_error_quark (void);

typedef enum {
  DS_OUTPUT_ERROR_IO = 1,       /* a file or folder could not be written (the message names it) */
  DS_OUTPUT_ERROR_INVALID = 2,  /* an image or request the format cannot hold */
  DS_OUTPUT_ERROR_HDF5 = 3,     /* the HDF5 library refused an operation (the message says which) */
  DS_OUTPUT_ERROR_BUSY = 4,     /* the writer's queue is full: the job was not taken */
  DS_OUTPUT_ERROR_NO_SPACE = 5, /* the disk has no room for the write: nothing was written */
} DsOutputError;

G_END_DECLS
