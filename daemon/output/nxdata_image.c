#include "daemon/output/nxdata_image.h"

#include <math.h>
#include <string.h>

#include "daemon/output/hdf5_util.h"
#include "daemon/output/result_meta.h"

static gboolean
axis_dataset (hid_t group, const char *name, guint n, double pixel_size_um)
{
  gboolean known = isfinite (pixel_size_um);
  g_autofree double *v = g_new (double, MAX (n, 1));
  for (guint i = 0; i < n; i++)
    v[i] = known ? i * pixel_size_um : i;
  hsize_t dims[1] = { n };
  hid_t s = H5Screate_simple (1, dims, NULL);
  hid_t d = H5Dcreate2 (group, name, H5T_IEEE_F64LE, s, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
  H5Sclose (s);
  if (d < 0)
    return FALSE;
  /* NeXus' NX_LENGTH unit "um" (UDUNITS spells it so too); an index has no length, and its
   * long name says why, so that a plot's label never suggests a scale that is not there. */
  g_autofree char *long_name =
      known ? g_strdup_printf ("%s (object plane, %.6g µm per pixel)", name, pixel_size_um)
            : g_strdup_printf ("%s (pixel index; pixel size unknown)", name);
  gboolean ok = (n == 0 || H5Dwrite (d, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, v) >= 0) &&
                ds_h5_attr_string (d, "units", known ? "um" : "pixel") && ds_h5_attr_string (d, "long_name", long_name);
  H5Dclose (d);
  return ok;
}

gboolean
ds_nxdata_image_axes (hid_t group, guint width, guint height, double pixel_size_um, const char *lead_axis)
{
  const char *axes[3];
  guint n = 0;
  if (lead_axis)
    axes[n++] = lead_axis;
  axes[n++] = "y";
  axes[n++] = "x";
  gboolean ok = axis_dataset (group, "y", height, pixel_size_um) && axis_dataset (group, "x", width, pixel_size_um) &&
                ds_h5_attr_strings (group, "axes", axes, n) && ds_h5_attr_int (group, "y_indices", n - 2) &&
                ds_h5_attr_int (group, "x_indices", n - 1);
  if (ok && lead_axis && g_strcmp0 (lead_axis, ".") != 0) {
    g_autofree char *indices = g_strconcat (lead_axis, "_indices", NULL);
    ok = ds_h5_attr_int (group, indices, 0);
  }
  return ok;
}

gboolean
ds_nxdata_mark_image (hid_t dataset)
{
  return ds_h5_attr_string (dataset, "interpretation", "image");
}

gboolean
ds_nxdata_image (hid_t parent, const char *name, const DsImage *img, const char *plane, double pixel_size_um)
{
  hid_t g = ds_h5_group (parent, name, "NXdata");
  if (g < 0)
    return FALSE;
  gboolean ok = ds_h5_attr_string (g, "signal", "data") &&
                ds_nxdata_image_axes (g, img->width, img->height, pixel_size_um, NULL);
  hid_t d = ok ? ds_h5_image_dataset (g, "data", img, ds_output_plane_units (plane), ds_output_plane_long_name (plane))
               : -1;
  ok = d >= 0 && ds_nxdata_mark_image (d) && (strcmp (plane, "mask") != 0 || ds_h5_mask_legend (d));
  if (d >= 0)
    H5Dclose (d);
  H5Gclose (g);
  return ok;
}
