#include "daemon/output/hdf5_set.h"

#include <glib/gstdio.h>
#include <math.h>
#include <string.h>

#include "build_info.h"
#include "daemon/output/atomic_file.h"
#include "daemon/output/hdf5_util.h"
#include "daemon/output/nxdata_image.h"
#include "daemon/output/output_error.h"
#include "daemon/output/result_meta.h"

guint
ds_output_result_optional (const DsOutputResult *r, const char **names, const DsImage **images)
{
  const char *all_names[] = { "max", "min", "mean", "sigma_transmissive", "sigma_scattered" };
  const DsImage *all[] = { r->max, r->min, r->mean, r->sigma_transmissive, r->sigma_scattered };
  guint n = 0;
  for (guint i = 0; i < G_N_ELEMENTS (all); i++)
    if (all[i]) {
      names[n] = all_names[i];
      images[n++] = all[i];
    }
  return n;
}

gboolean
ds_hdf5_write_root_attrs (hid_t file, const char *file_name)
{
  g_autoptr (GDateTime) now = g_date_time_new_now_utc ();
  g_autofree char *stamp = ds_output_time_string (now);
  hid_t root = H5Gopen2 (file, "/", H5P_DEFAULT);
  gboolean ok = root >= 0 && ds_h5_attr_string (root, "NX_class", "NXroot") &&
                ds_h5_attr_string (root, "default", "entry") && ds_h5_attr_string (root, "file_name", file_name) &&
                ds_h5_attr_string (root, "file_time", stamp) &&
                ds_h5_attr_string (root, "creator", "descatter " DS_VERSION " (" DS_GIT_DESCRIBE ")");
  if (root >= 0)
    H5Gclose (root);
  return ok;
}

gboolean
ds_hdf5_write_entry_fields (hid_t entry, JsonNode *meta, const char *title, gboolean with_end)
{
  const char *start = ds_json_path_string (meta, "time_utc", NULL);
  const char *end = with_end ? ds_json_path_string (meta, "time_utc_end", NULL) : NULL;
  g_autofree char *json = json_to_string (meta, TRUE);
  gboolean ok = ds_h5_attr_string (entry, "default", "transmissive") && ds_h5_string_dataset (entry, "title", title) &&
                (!start || ds_h5_string_dataset (entry, "start_time", start)) &&
                (!end || ds_h5_string_dataset (entry, "end_time", end)) &&
                ds_h5_string_dataset (entry, "program_name", ds_json_path_string (meta, "producer.program", "descatter"));
  if (ok) {
    hid_t d = H5Dopen2 (entry, "program_name", H5P_DEFAULT);
    ok = d >= 0 && ds_h5_attr_string (d, "version", ds_json_path_string (meta, "producer.version", DS_VERSION)) &&
         ds_h5_attr_string (d, "git", ds_json_path_string (meta, "producer.git", DS_GIT_DESCRIBE));
    if (d >= 0)
      H5Dclose (d);
  }
  if (!ok)
    return FALSE;
  /* The whole metadata, as the JSON sidecar and the TIFF description hold it. */
  hid_t note = ds_h5_group (entry, "metadata", "NXnote");
  if (note < 0)
    return FALSE;
  ok = ds_h5_string_dataset (note, "type", "application/json") && ds_h5_string_dataset (note, "data", json);
  H5Gclose (note);
  return ok;
}

static gboolean
string_field (hid_t g, JsonNode *meta, const char *path, const char *name)
{
  const char *v = ds_json_path_string (meta, path, NULL);
  return !v || ds_h5_string_dataset (g, name, v);
}

/* Integers stay integers: NeXus' NX_INT fields (bit depth, saturation value) are not floats. A
 * whole number the JSON holds as a double (4095.0) is written as the integer it is; a fraction
 * (a configured clip level of 3900.5) stays a float rather than be rounded. */
static gboolean
int_field (hid_t g, JsonNode *meta, const char *path, const char *name, const char *units)
{
  double x = ds_json_path_double (meta, path, NAN);
  if (!isfinite (x))
    return TRUE;
  if (fabs (x) > 9e15 || x != floor (x))
    return ds_h5_double_dataset (g, name, x, units);
  gint64 v = (gint64) x;
  hid_t s = H5Screate (H5S_SCALAR);
  hid_t d = H5Dcreate2 (g, name, H5T_STD_I64LE, s, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
  H5Sclose (s);
  if (d < 0)
    return FALSE;
  gboolean ok = H5Dwrite (d, H5T_NATIVE_INT64, H5S_ALL, H5S_ALL, H5P_DEFAULT, &v) >= 0 &&
                (!units || ds_h5_attr_string (d, "units", units));
  H5Dclose (d);
  return ok;
}

static gboolean
number_field (hid_t g, JsonNode *meta, const char *path, const char *name, const char *units)
{
  double v = ds_json_path_double (meta, path, NAN);
  return !isfinite (v) || ds_h5_double_dataset (g, name, v, units);
}

gboolean
ds_hdf5_write_instrument (hid_t entry, JsonNode *meta)
{
  hid_t inst = ds_h5_group (entry, "instrument", "NXinstrument");
  if (inst < 0)
    return FALSE;
  hid_t cam = ds_h5_group (inst, "camera", "NXdetector");
  g_autofree char *description = g_strdup_printf ("%s %s", ds_json_path_string (meta, "camera.vendor", "?"),
                                                  ds_json_path_string (meta, "camera.model", "?"));
  gboolean ok = cam >= 0 && ds_h5_string_dataset (cam, "description", description) &&
                string_field (cam, meta, "camera.serial", "serial_number") &&
                string_field (cam, meta, "camera.backend", "backend") &&
                string_field (cam, meta, "camera.pixel_format", "pixel_format") &&
                int_field (cam, meta, "camera.bit_depth", "bit_depth_readout", NULL) &&
                int_field (cam, meta, "separation.saturation_level", "saturation_value", "counts") &&
                number_field (cam, meta, "settings.exposure_us", "count_time", "us") &&
                number_field (cam, meta, "settings.gain_db", "gain", "dB") &&
                number_field (cam, meta, "optics.sensor_pixel_pitch_um", "x_pixel_size", "um") &&
                number_field (cam, meta, "optics.sensor_pixel_pitch_um", "y_pixel_size", "um");
  if (cam >= 0)
    H5Gclose (cam);
  hid_t ill = ok ? ds_h5_group (inst, "illuminator", "NXcollection") : -1;
  ok = ill >= 0 && string_field (ill, meta, "pattern.kind", "pattern") &&
       number_field (ill, meta, "pattern.period_px", "period", "pixels") &&
       number_field (ill, meta, "pattern.duty", "duty", NULL) &&
       number_field (ill, meta, "pattern.black_level", "black_level", NULL) &&
       number_field (ill, meta, "pattern.phase_offset_cycles", "phase_offset", "cycles") &&
       string_field (ill, meta, "illuminator.backend", "backend") &&
       number_field (ill, meta, "illuminator.temperature_c", "temperature", "degC");
  if (ill >= 0)
    H5Gclose (ill);
  H5Gclose (inst);
  return ok;
}

static gboolean
write_array_1d (hid_t g, const char *name, hid_t file_type, hid_t mem_type, const void *data, guint n,
                const char *units, const char *long_name)
{
  hsize_t dims[1] = { n };
  hid_t s = H5Screate_simple (1, dims, NULL);
  hid_t d = H5Dcreate2 (g, name, file_type, s, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
  herr_t r = d >= 0 && n > 0 ? H5Dwrite (d, mem_type, H5S_ALL, H5S_ALL, H5P_DEFAULT, data) : d >= 0 ? 0 : -1;
  gboolean ok = r >= 0 && (!units || ds_h5_attr_string (d, "units", units)) &&
                ds_h5_attr_string (d, "long_name", long_name);
  if (d >= 0)
    H5Dclose (d);
  H5Sclose (s);
  return ok;
}

/* The raw frames as one [frames, height, width] uint16 dataset (u8 frames widened). */
static gboolean
write_phases (hid_t entry, const DsRawFrames *raw, double pixel_size_um)
{
  const DsImage *first = ((const DsRawFrame *) raw->frames->pdata[0])->image;
  guint n = raw->frames->len, w = first->width, h = first->height;
  hid_t g = ds_h5_group (entry, "phases", "NXdata");
  if (g < 0)
    return FALSE;
  /* The frames in the order taken, along the camera's frame ids. */
  gboolean ok = ds_h5_attr_string (g, "signal", "data") && ds_nxdata_image_axes (g, w, h, pixel_size_um, "frame_id") &&
                ds_h5_attr_int (g, "n_phases", raw->n_phases);
  hsize_t dims[3] = { n, h, w };
  hid_t fs = H5Screate_simple (3, dims, NULL);
  hid_t d = ok ? H5Dcreate2 (g, "data", H5T_STD_U16LE, fs, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT) : -1;
  g_autofree guint16 *plane = g_new (guint16, (gsize) w * h);
  g_autofree gint32 *phase = g_new (gint32, n);
  g_autofree guint64 *ids = g_new (guint64, n);
  g_autofree guint64 *stamps = g_new (guint64, n);
  hsize_t one[3] = { 1, h, w };
  hid_t ms = H5Screate_simple (3, one, NULL);
  ok = d >= 0;
  for (guint i = 0; ok && i < n; i++) {
    const DsRawFrame *f = raw->frames->pdata[i];
    if (f->image->width != w || f->image->height != h) {
      ok = FALSE;
      break;
    }
    for (guint y = 0; y < h; y++) {
      const void *row = ds_image_row (f->image, y);
      for (guint x = 0; x < w; x++)
        plane[(gsize) y * w + x] = f->image->type == DS_SAMPLE_U8 ? ((const guint8 *) row)[x] : ((const guint16 *) row)[x];
    }
    hsize_t start[3] = { i, 0, 0 };
    ok = H5Sselect_hyperslab (fs, H5S_SELECT_SET, start, NULL, one, NULL) >= 0 &&
         H5Dwrite (d, H5T_NATIVE_UINT16, ms, fs, H5P_DEFAULT, plane) >= 0;
    phase[i] = (gint32) f->phase;
    ids[i] = f->frame_id;
    stamps[i] = f->timestamp_ns;
  }
  H5Sclose (ms);
  H5Sclose (fs);
  if (d >= 0) {
    ok = ok && ds_h5_attr_string (d, "units", ds_output_plane_units ("phases")) &&
         ds_h5_attr_string (d, "long_name", ds_output_plane_long_name ("phases")) &&
         ds_h5_attr_int (d, "bit_depth", first->bit_depth) && ds_nxdata_mark_image (d);
    H5Dclose (d);
  }
  ok = ok && write_array_1d (g, "phase", H5T_STD_I32LE, H5T_NATIVE_INT32, phase, n, NULL, "stripe phase index of the frame") &&
       write_array_1d (g, "frame_id", H5T_STD_U64LE, H5T_NATIVE_UINT64, ids, n, NULL, "camera frame id") &&
       write_array_1d (g, "timestamp_ns", H5T_STD_U64LE, H5T_NATIVE_UINT64, stamps, n, "ns", "camera timestamp");
  if (ok && raw->black) {
    hid_t b = ds_h5_image_dataset (g, "black", raw->black, ds_output_plane_units ("black"),
                                   ds_output_plane_long_name ("black"));
    ok = b >= 0;
    if (b >= 0)
      H5Dclose (b);
    ok = ok && write_array_1d (g, "black_frame_ids", H5T_STD_U64LE, H5T_NATIVE_UINT64, raw->black_ids->data,
                               raw->black_ids->len, NULL, "camera frame ids of the dark frames");
  }
  H5Gclose (g);
  return ok;
}

static gboolean
fill_file (hid_t file, const DsOutputResult *r, const char *path)
{
  g_autofree char *base = g_path_get_basename (path);
  if (!ds_hdf5_write_root_attrs (file, base))
    return FALSE;
  hid_t entry = ds_h5_group (file, "entry", "NXentry");
  if (entry < 0)
    return FALSE;
  g_autofree char *title = g_strdup_printf ("descatter set %" G_GINT64_FORMAT, ds_json_path_int (r->meta, "set_id", 0));
  double px = ds_output_pixel_size_um (r->meta);
  const char *names[5];
  const DsImage *images[5];
  guint n = ds_output_result_optional (r, names, images);
  gboolean ok = ds_hdf5_write_entry_fields (entry, r->meta, title, TRUE) && ds_hdf5_write_instrument (entry, r->meta) &&
                ds_nxdata_image (entry, "transmissive", r->transmissive, "transmissive", px) &&
                ds_nxdata_image (entry, "scattered", r->scattered, "scattered", px) &&
                ds_nxdata_image (entry, "mask", r->mask, "mask", px);
  for (guint i = 0; ok && i < n; i++)
    ok = ds_nxdata_image (entry, names[i], images[i], names[i], px);
  if (ok && r->raw && r->raw->frames->len > 0)
    ok = write_phases (entry, r->raw, px);
  H5Gclose (entry);
  return ok;
}

gboolean
ds_hdf5_write_set (const DsOutputResult *r, const char *path, GError **error)
{
  ds_h5_quiet ();
  g_autofree char *tmp = ds_atomic_temp_path (path);
  hid_t file = H5Fcreate (tmp, H5F_ACC_EXCL, H5P_DEFAULT, H5P_DEFAULT);
  if (file < 0) {
    g_autofree char *what = g_strdup_printf ("%s: cannot create", path);
    return ds_h5_fail (error, what);
  }
  gboolean ok = fill_file (file, r, path);
  if (!ok) {
    g_autofree char *what = g_strdup_printf ("%s: writing failed", path);
    ds_h5_fail (error, what);
  }
  if (H5Fclose (file) < 0 && ok) {
    g_autofree char *what = g_strdup_printf ("%s: closing failed", path);
    ok = ds_h5_fail (error, what);
  }
  if (!ok) {
    g_unlink (tmp);
    return FALSE;
  }
  return ds_atomic_commit (tmp, path, error);
}
