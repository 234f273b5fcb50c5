/* Small helpers over the HDF5 C API for the NeXus writers (hdf5_set.c, hdf5_run.c): groups
 * with an NX_class, string and numeric attributes, whole-image datasets, and the library's
 * error stack turned into a GError. Private to daemon/output. Any thread (Debian's libhdf5 is
 * built thread-safe; its error stack is per thread). */
#pragma once
#include <glib.h>
#include <hdf5.h>

#include "proc/image.h"

G_BEGIN_DECLS

/* Replaces HDF5's automatic printing of errors on this thread by a note of the first failure,
 * and forgets an earlier note: call it at the start of each operation. */
void ds_h5_quiet (void);
/* Sets error from the first HDF5 failure noted since ds_h5_quiet: "what: <HDF5's innermost
 * message> in <function>". */
gboolean ds_h5_fail (GError **error, const char *what);

hid_t ds_h5_group (hid_t parent, const char *name, const char *nx_class);
gboolean ds_h5_attr_string (hid_t obj, const char *name, const char *value);
gboolean ds_h5_attr_strings (hid_t obj, const char *name, const char *const *values, guint n);
gboolean ds_h5_attr_double (hid_t obj, const char *name, double value);
gboolean ds_h5_attr_int (hid_t obj, const char *name, gint64 value);
gboolean ds_h5_attr_ints (hid_t obj, const char *name, const gint32 *values, guint n);
/* A scalar string dataset (NeXus fields such as start_time or title). */
gboolean ds_h5_string_dataset (hid_t parent, const char *name, const char *value);
gboolean ds_h5_double_dataset (hid_t parent, const char *name, double value, const char *units);
/* The HDF5 file and memory types of a sample type. */
hid_t ds_h5_file_type (DsSampleType type);
hid_t ds_h5_mem_type (DsSampleType type);
/* A contiguous 2-D dataset holding img (stride honoured), with units and long_name. */
hid_t ds_h5_image_dataset (hid_t parent, const char *name, const DsImage *img, const char *units,
                           const char *long_name);
/* The mask's legend as CF attributes flag_masks / flag_meanings on a dataset. */
gboolean ds_h5_mask_legend (hid_t dataset);

G_END_DECLS
