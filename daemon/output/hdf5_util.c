#include "daemon/output/hdf5_util.h"

#include <string.h>

#include "daemon/output/output_error.h"
#include "daemon/output/result_meta.h"
#include "proc/separation.h"

typedef struct {
  char func[64];
  char desc[192];
} H5Message;

/* The innermost message of the last failed HDF5 call on this thread. HDF5 clears its error stack
 * at the start of every call, so the stack must be read when the failing call returns: HDF5
 * calls the "automatic" error function right then. */
static _Thread_local H5Message last_error;

static herr_t
innermost (unsigned n, const H5E_error2_t *err, void *data)
{
  H5Message *m = data;
  /* Downward: the API function first, the deepest cause (with errno, if any) last. */
  if (n == 0)
    g_strlcpy (m->func, err->func_name ? err->func_name : "", sizeof m->func);
  g_strlcpy (m->desc, err->desc ? err->desc : "", sizeof m->desc);
  return 0;
}

static herr_t
note_error (hid_t stack, void *data)
{
  (void) data;
  H5Message m = { { 0 }, { 0 } };
  H5Ewalk2 (stack, H5E_WALK_DOWNWARD, innermost, &m);
  /* The first failure is the cause; calls failing after it (cleanup) would hide it. */
  if (!last_error.desc[0])
    last_error = m;
  return 0;
}

void
ds_h5_quiet (void)
{
  /* No closing of files by HDF5 at exit: every file is closed by its writer, and one whose close
   * failed (a full disk) must not be touched again, which HDF5's teardown would do and crash.
   * Effective only before HDF5's first use in the process; later it changes nothing. */
  static gsize once = 0;
  if (g_once_init_enter (&once)) {
    H5dont_atexit ();
    g_once_init_leave (&once, 1);
  }
  H5Eset_auto2 (H5E_DEFAULT, note_error, NULL);
  memset (&last_error, 0, sizeof last_error);
}

gboolean
ds_h5_fail (GError **error, const char *what)
{
  H5Message m = last_error;
  memset (&last_error, 0, sizeof last_error);
  g_set_error (error, DS_OUTPUT_ERROR, DS_OUTPUT_ERROR_HDF5, "%s: %s%s%s", what, m.desc[0] ? m.desc : "HDF5 error",
               m.func[0] ? " in " : "", m.func);
  return FALSE;
}

hid_t
ds_h5_group (hid_t parent, const char *name, const char *nx_class)
{
  hid_t g = H5Gcreate2 (parent, name, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
  if (g < 0)
    return g;
  if (nx_class && !ds_h5_attr_string (g, "NX_class", nx_class)) {
    H5Gclose (g);
    return -1;
  }
  return g;
}

static hid_t
utf8_vlen_type (void)
{
  hid_t t = H5Tcopy (H5T_C_S1);
  H5Tset_size (t, H5T_VARIABLE);
  H5Tset_cset (t, H5T_CSET_UTF8);
  return t;
}

gboolean
ds_h5_attr_string (hid_t obj, const char *name, const char *value)
{
  hid_t t = utf8_vlen_type ();
  hid_t s = H5Screate (H5S_SCALAR);
  hid_t a = H5Acreate2 (obj, name, t, s, H5P_DEFAULT, H5P_DEFAULT);
  herr_t r = a >= 0 ? H5Awrite (a, t, &value) : -1;
  if (a >= 0)
    H5Aclose (a);
  H5Sclose (s);
  H5Tclose (t);
  return r >= 0;
}

gboolean
ds_h5_attr_strings (hid_t obj, const char *name, const char *const *values, guint n)
{
  hid_t t = utf8_vlen_type ();
  hsize_t dims[1] = { n };
  hid_t s = H5Screate_simple (1, dims, NULL);
  hid_t a = H5Acreate2 (obj, name, t, s, H5P_DEFAULT, H5P_DEFAULT);
  herr_t r = a >= 0 ? H5Awrite (a, t, values) : -1;
  if (a >= 0)
    H5Aclose (a);
  H5Sclose (s);
  H5Tclose (t);
  return r >= 0;
}

static gboolean
attr_scalar (hid_t obj, const char *name, hid_t file_type, hid_t mem_type, const void *value)
{
  hid_t s = H5Screate (H5S_SCALAR);
  hid_t a = H5Acreate2 (obj, name, file_type, s, H5P_DEFAULT, H5P_DEFAULT);
  herr_t r = a >= 0 ? H5Awrite (a, mem_type, value) : -1;
  if (a >= 0)
    H5Aclose (a);
  H5Sclose (s);
  return r >= 0;
}

gboolean
ds_h5_attr_double (hid_t obj, const char *name, double value)
{
  return attr_scalar (obj, name, H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, &value);
}

gboolean
ds_h5_attr_int (hid_t obj, const char *name, gint64 value)
{
  return attr_scalar (obj, name, H5T_STD_I64LE, H5T_NATIVE_INT64, &value);
}

gboolean
ds_h5_attr_ints (hid_t obj, const char *name, const gint32 *values, guint n)
{
  hsize_t dims[1] = { n };
  hid_t s = H5Screate_simple (1, dims, NULL);
  hid_t a = H5Acreate2 (obj, name, H5T_STD_I32LE, s, H5P_DEFAULT, H5P_DEFAULT);
  herr_t r = a >= 0 ? H5Awrite (a, H5T_NATIVE_INT32, values) : -1;
  if (a >= 0)
    H5Aclose (a);
  H5Sclose (s);
  return r >= 0;
}

gboolean
ds_h5_string_dataset (hid_t parent, const char *name, const char *value)
{
  hid_t t = utf8_vlen_type ();
  hid_t s = H5Screate (H5S_SCALAR);
  hid_t d = H5Dcreate2 (parent, name, t, s, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
  herr_t r = d >= 0 ? H5Dwrite (d, t, H5S_ALL, H5S_ALL, H5P_DEFAULT, &value) : -1;
  if (d >= 0)
    H5Dclose (d);
  H5Sclose (s);
  H5Tclose (t);
  return r >= 0;
}

gboolean
ds_h5_double_dataset (hid_t parent, const char *name, double value, const char *units)
{
  hid_t s = H5Screate (H5S_SCALAR);
  hid_t d = H5Dcreate2 (parent, name, H5T_IEEE_F64LE, s, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
  herr_t r = d >= 0 ? H5Dwrite (d, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, &value) : -1;
  gboolean ok = r >= 0 && (!units || ds_h5_attr_string (d, "units", units));
  if (d >= 0)
    H5Dclose (d);
  H5Sclose (s);
  return ok;
}

hid_t
ds_h5_file_type (DsSampleType type)
{
  return type == DS_SAMPLE_F32 ? H5T_IEEE_F32LE : type == DS_SAMPLE_U16 ? H5T_STD_U16LE : H5T_STD_U8LE;
}

hid_t
ds_h5_mem_type (DsSampleType type)
{
  return type == DS_SAMPLE_F32 ? H5T_NATIVE_FLOAT : type == DS_SAMPLE_U16 ? H5T_NATIVE_UINT16 : H5T_NATIVE_UINT8;
}

hid_t
ds_h5_image_dataset (hid_t parent, const char *name, const DsImage *img, const char *units, const char *long_name)
{
  hsize_t dims[2] = { img->height, img->width };
  hid_t fs = H5Screate_simple (2, dims, NULL);
  hid_t d = H5Dcreate2 (parent, name, ds_h5_file_type (img->type), fs, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
  H5Sclose (fs);
  if (d < 0)
    return d;
  /* The image's rows may be padded: describe its memory as a strided block, no copy. */
  gsize ss = ds_sample_size (img->type);
  hsize_t mdims[2] = { img->height, img->stride / ss };
  hid_t ms = H5Screate_simple (2, mdims, NULL);
  hsize_t start[2] = { 0, 0 }, count[2] = { img->height, img->width };
  herr_t r = img->stride % ss == 0 ? H5Sselect_hyperslab (ms, H5S_SELECT_SET, start, NULL, count, NULL) : -1;
  if (r >= 0)
    r = H5Dwrite (d, ds_h5_mem_type (img->type), ms, H5S_ALL, H5P_DEFAULT, img->data);
  H5Sclose (ms);
  if (r < 0 || (units && !ds_h5_attr_string (d, "units", units)) ||
      (long_name && !ds_h5_attr_string (d, "long_name", long_name))) {
    H5Dclose (d);
    return -1;
  }
  return d;
}

gboolean
ds_h5_mask_legend (hid_t dataset)
{
  gint32 masks[DS_MASK_N_BITS];
  for (guint i = 0; i < DS_MASK_N_BITS; i++)
    masks[i] = 1 << i;
  g_autofree char *meanings = ds_output_mask_flag_meanings ();
  return ds_h5_attr_ints (dataset, "flag_masks", masks, DS_MASK_N_BITS) &&
         ds_h5_attr_string (dataset, "flag_meanings", meanings);
}
