#include "daemon/output/hdf5_run.h"

#include <glib/gstdio.h>
#include <string.h>

#include "daemon/output/atomic_file.h"
#include "daemon/output/hdf5_set.h"
#include "daemon/output/hdf5_util.h"
#include "daemon/output/nxdata_image.h"
#include "daemon/output/output_error.h"
#include "daemon/output/result_meta.h"

#define TIME_CHARS 32

enum { D_TRANS, D_SCAT, D_MASK, D_PHASES, D_PHASE, D_FRAME_ID, D_SET_INDEX, D_BLACK, D_HAS_BLACK,
       D_TIME, D_META, D_META_END, D_SET_ID, D_N };

struct DsHdf5Run {
  char *path, *partial;
  hid_t file;
  hid_t d[D_N];     /* -1 when absent */
  guint width, height;
  gboolean phases;
  guint64 sets, frames, meta_bytes;
  char *last_time;
};

static hid_t
extendible (hid_t parent, const char *name, hid_t type, guint rank, guint h, guint w)
{
  hsize_t dims[3] = { 0, h, w }, maxdims[3] = { H5S_UNLIMITED, h, w };
  /* One plane per chunk (one set or frame per write); 1-D columns in chunks of 4096 bytes. */
  hsize_t chunk[3] = { rank == 1 ? MAX (1, 4096 / H5Tget_size (type)) : 1, h, w };
  hid_t s = H5Screate_simple ((int) rank, dims, maxdims);
  hid_t p = H5Pcreate (H5P_DATASET_CREATE);
  H5Pset_chunk (p, (int) rank, chunk);
  hid_t d = H5Dcreate2 (parent, name, type, s, H5P_DEFAULT, p, H5P_DEFAULT);
  H5Pclose (p);
  H5Sclose (s);
  return d;
}

static hid_t
time_type (void)
{
  hid_t t = H5Tcopy (H5T_C_S1);
  H5Tset_size (t, TIME_CHARS);
  H5Tset_strpad (t, H5T_STR_NULLPAD);
  return t;
}

/* An NXdata group whose signal "data" grows by one image per set (or frame): along the lead
 * axis, the image's y and x. The sets have no axis dataset of their own ("."): entry/sets/set_id
 * is written last and may be shorter than the planes while a set is being appended. */
static hid_t
image_block (hid_t parent, const char *group, const char *plane, hid_t type, guint h, guint w, double pixel_size_um,
             const char *lead_axis)
{
  hid_t g = ds_h5_group (parent, group, "NXdata");
  if (g < 0)
    return -1;
  hid_t d = ds_h5_attr_string (g, "signal", "data") && ds_nxdata_image_axes (g, w, h, pixel_size_um, lead_axis)
                ? extendible (g, "data", type, 3, h, w)
                : -1;
  if (d >= 0 && (!ds_nxdata_mark_image (d) || !ds_h5_attr_string (d, "units", ds_output_plane_units (plane)) ||
                 !ds_h5_attr_string (d, "long_name", ds_output_plane_long_name (plane)) ||
                 (strcmp (plane, "mask") == 0 && !ds_h5_mask_legend (d)))) {
    H5Dclose (d);
    d = -1;
  }
  H5Gclose (g);
  return d;
}

static gboolean
create_layout (DsHdf5Run *run, const DsOutputResult *first)
{
  g_autofree char *base = g_path_get_basename (run->path);
  if (!ds_hdf5_write_root_attrs (run->file, base))
    return FALSE;
  hid_t entry = ds_h5_group (run->file, "entry", "NXentry");
  if (entry < 0)
    return FALSE;
  g_autofree char *title = g_strdup_printf ("descatter run from set %" G_GINT64_FORMAT,
                                            ds_json_path_int (first->meta, "set_id", 0));
  gboolean ok = ds_hdf5_write_entry_fields (entry, first->meta, title, FALSE) && ds_hdf5_write_instrument (entry, first->meta);
  guint h = run->height, w = run->width;
  /* The first set's pixel size holds for the run: the optics are configured at start. */
  double px = ds_output_pixel_size_um (first->meta);
  if (ok) {
    run->d[D_TRANS] = image_block (entry, "transmissive", "transmissive", H5T_IEEE_F32LE, h, w, px, ".");
    run->d[D_SCAT] = image_block (entry, "scattered", "scattered", H5T_IEEE_F32LE, h, w, px, ".");
    run->d[D_MASK] = image_block (entry, "mask", "mask", H5T_STD_U8LE, h, w, px, ".");
    ok = run->d[D_TRANS] >= 0 && run->d[D_SCAT] >= 0 && run->d[D_MASK] >= 0;
  }
  if (ok && run->phases) {
    /* The frames along the camera's frame ids, appended with each frame. */
    run->d[D_PHASES] = image_block (entry, "phases", "phases", H5T_STD_U16LE, h, w, px, "frame_id");
    hid_t g = H5Gopen2 (entry, "phases", H5P_DEFAULT);
    ok = run->d[D_PHASES] >= 0 && g >= 0;
    if (ok) {
      run->d[D_PHASE] = extendible (g, "phase", H5T_STD_I32LE, 1, 0, 0);
      run->d[D_FRAME_ID] = extendible (g, "frame_id", H5T_STD_U64LE, 1, 0, 0);
      run->d[D_SET_INDEX] = extendible (g, "set_index", H5T_STD_U64LE, 1, 0, 0);
      run->d[D_BLACK] = extendible (g, "black", H5T_STD_U16LE, 3, h, w);
      run->d[D_HAS_BLACK] = extendible (g, "has_black", H5T_STD_U8LE, 1, 0, 0);
      for (guint i = D_PHASE; i <= D_HAS_BLACK; i++)
        ok = ok && run->d[i] >= 0;
      ok = ok && ds_h5_attr_string (run->d[D_PHASE], "long_name", "stripe phase index of the frame") &&
           ds_h5_attr_string (run->d[D_FRAME_ID], "long_name", "camera frame id") &&
           ds_h5_attr_string (run->d[D_SET_INDEX], "long_name", "index of the frame's set in entry/sets") &&
           ds_h5_attr_string (run->d[D_BLACK], "units", ds_output_plane_units ("black")) &&
           ds_h5_attr_string (run->d[D_BLACK], "long_name", ds_output_plane_long_name ("black")) &&
           ds_h5_attr_string (run->d[D_HAS_BLACK], "long_name", "1 when the set had a dark frame");
    }
    if (g >= 0)
      H5Gclose (g);
  }
  hid_t sets = ok ? ds_h5_group (entry, "sets", "NXcollection") : -1;
  if (sets >= 0) {
    hid_t tt = time_type ();
    run->d[D_TIME] = extendible (sets, "time_utc", tt, 1, 0, 0);
    H5Tclose (tt);
    run->d[D_META] = extendible (sets, "metadata", H5T_STD_U8LE, 1, 0, 0);
    run->d[D_META_END] = extendible (sets, "metadata_end", H5T_STD_U64LE, 1, 0, 0);
    run->d[D_SET_ID] = extendible (sets, "set_id", H5T_STD_U64LE, 1, 0, 0);
    ok = run->d[D_TIME] >= 0 && run->d[D_META] >= 0 && run->d[D_META_END] >= 0 && run->d[D_SET_ID] >= 0 &&
         ds_h5_attr_string (sets, "note", "set_id is written last: its length counts the complete sets");
    H5Gclose (sets);
  } else
    ok = FALSE;
  H5Gclose (entry);
  return ok;
}

static void
close_datasets (DsHdf5Run *run)
{
  for (guint i = 0; i < D_N; i++)
    if (run->d[i] >= 0) {
      H5Dclose (run->d[i]);
      run->d[i] = -1;
    }
}

static void
run_free (DsHdf5Run *run)
{
  close_datasets (run);
  if (run->file >= 0)
    H5Fclose (run->file);
  g_free (run->path);
  g_free (run->partial);
  g_free (run->last_time);
  g_free (run);
}

DsHdf5Run *
ds_hdf5_run_open (const char *path, const DsOutputResult *first, GError **error)
{
  ds_h5_quiet ();
  DsHdf5Run *run = g_new0 (DsHdf5Run, 1);
  for (guint i = 0; i < D_N; i++)
    run->d[i] = -1;
  run->path = g_strdup (path);
  run->partial = g_strconcat (path, ".partial", NULL);
  run->width = first->transmissive->width;
  run->height = first->transmissive->height;
  run->phases = first->raw && first->raw->frames->len > 0;
  /* SWMR needs the newest file format. */
  hid_t fapl = H5Pcreate (H5P_FILE_ACCESS);
  H5Pset_libver_bounds (fapl, H5F_LIBVER_LATEST, H5F_LIBVER_LATEST);
  run->file = H5Fcreate (run->partial, H5F_ACC_EXCL, H5P_DEFAULT, fapl);
  H5Pclose (fapl);
  if (run->file < 0) {
    g_autofree char *what = g_strdup_printf ("%s: cannot create", run->partial);
    ds_h5_fail (error, what);
    run_free (run);
    return NULL;
  }
  if (!create_layout (run, first) || H5Fstart_swmr_write (run->file) < 0) {
    g_autofree char *what = g_strdup_printf ("%s: cannot lay out the run file", run->partial);
    ds_h5_fail (error, what);
    g_autofree char *partial = g_strdup (run->partial);
    run_free (run);
    g_unlink (partial);
    return NULL;
  }
  return run;
}

/* Appends `count` elements (1-D) or planes (3-D, one image) at the end of a dataset. */
static gboolean
append (hid_t d, hid_t mem_type, const void *data, guint64 count, const DsImage *img)
{
  hid_t fs = H5Dget_space (d);
  int rank = H5Sget_simple_extent_ndims (fs);
  hsize_t dims[3] = { 0, 0, 0 };
  H5Sget_simple_extent_dims (fs, dims, NULL);
  H5Sclose (fs);
  hsize_t at = dims[0];
  dims[0] += count;
  if (H5Dset_extent (d, dims) < 0)
    return FALSE;
  fs = H5Dget_space (d);
  hsize_t start[3] = { at, 0, 0 }, block[3] = { count, dims[1], dims[2] };
  hid_t ms;
  herr_t r = H5Sselect_hyperslab (fs, H5S_SELECT_SET, start, NULL, block, NULL);
  if (rank == 3) {
    /* The image's rows may be padded: a strided memory selection, no copy. */
    gsize ss = ds_sample_size (img->type);
    hsize_t mdims[3] = { 1, img->height, img->stride / ss }, mcount[3] = { 1, img->height, img->width };
    hsize_t mstart[3] = { 0, 0, 0 };
    ms = H5Screate_simple (3, mdims, NULL);
    if (r >= 0)
      r = H5Sselect_hyperslab (ms, H5S_SELECT_SET, mstart, NULL, mcount, NULL);
    data = img->data;
  } else {
    hsize_t mdims[1] = { count };
    ms = H5Screate_simple (1, mdims, NULL);
  }
  if (r >= 0)
    r = H5Dwrite (d, mem_type, ms, fs, H5P_DEFAULT, data);
  H5Sclose (ms);
  H5Sclose (fs);
  return r >= 0;
}

static DsImage *
widened (const DsImage *img)
{
  DsImage *w = ds_image_new (DS_SAMPLE_U16, img->width, img->height, NULL);
  if (!w)
    return NULL;
  for (guint y = 0; y < img->height; y++) {
    const void *in = ds_image_row (img, y);
    guint16 *out = ds_image_row (w, y);
    for (guint x = 0; x < img->width; x++)
      out[x] = img->type == DS_SAMPLE_U8 ? ((const guint8 *) in)[x] : ((const guint16 *) in)[x];
  }
  return w;
}

static gboolean
append_phases (DsHdf5Run *run, const DsRawFrames *raw)
{
  gboolean ok = TRUE;
  for (guint i = 0; ok && raw && i < raw->frames->len; i++) {
    const DsRawFrame *f = raw->frames->pdata[i];
    g_autoptr (DsImage) wide = f->image->type == DS_SAMPLE_U16 ? NULL : widened (f->image);
    gint32 phase = (gint32) f->phase;
    guint64 set_index = run->sets;
    ok = append (run->d[D_PHASES], H5T_NATIVE_UINT16, NULL, 1, wide ? wide : f->image) &&
         append (run->d[D_PHASE], H5T_NATIVE_INT32, &phase, 1, NULL) &&
         append (run->d[D_FRAME_ID], H5T_NATIVE_UINT64, &f->frame_id, 1, NULL) &&
         append (run->d[D_SET_INDEX], H5T_NATIVE_UINT64, &set_index, 1, NULL);
    run->frames += ok ? 1 : 0;
  }
  /* One black plane per set, zero when the set had none (has_black says which). */
  g_autoptr (DsImage) zero = NULL;
  const DsImage *black = raw ? raw->black : NULL;
  g_autoptr (DsImage) wide = black && black->type != DS_SAMPLE_U16 ? widened (black) : NULL;
  if (!black)
    black = zero = ds_image_new (DS_SAMPLE_U16, run->width, run->height, NULL);
  guint8 has = raw && raw->black ? 1 : 0;
  return ok && black && append (run->d[D_BLACK], H5T_NATIVE_UINT16, NULL, 1, wide ? wide : black) &&
         append (run->d[D_HAS_BLACK], H5T_NATIVE_UINT8, &has, 1, NULL);
}

gboolean
ds_hdf5_run_append (DsHdf5Run *run, const DsOutputResult *r, GError **error)
{
  ds_h5_quiet ();
  const DsImage *planes[] = { r->transmissive, r->scattered, r->mask };
  for (guint i = 0; i < G_N_ELEMENTS (planes); i++)
    if (planes[i]->width != run->width || planes[i]->height != run->height) {
      g_set_error (error, DS_OUTPUT_ERROR, DS_OUTPUT_ERROR_INVALID, "%s: a %ux%u result does not fit a %ux%u run",
                   run->partial, planes[i]->width, planes[i]->height, run->width, run->height);
      return FALSE;
    }
  if (r->raw)
    for (guint i = 0; i < r->raw->frames->len; i++) {
      const DsImage *img = ((const DsRawFrame *) r->raw->frames->pdata[i])->image;
      if (img->width != run->width || img->height != run->height) {
        g_set_error (error, DS_OUTPUT_ERROR, DS_OUTPUT_ERROR_INVALID, "%s: a raw frame of %ux%u does not fit a %ux%u run",
                     run->partial, img->width, img->height, run->width, run->height);
        return FALSE;
      }
    }
  g_autofree char *json = json_to_string (r->meta, FALSE);
  guint64 len = strlen (json);
  guint64 end = run->meta_bytes + len;
  char stamp[TIME_CHARS] = { 0 };
  g_strlcpy (stamp, ds_json_path_string (r->meta, "time_utc", ""), sizeof stamp);
  hid_t tt = time_type ();
  gboolean ok = append (run->d[D_TRANS], H5T_NATIVE_FLOAT, NULL, 1, r->transmissive) &&
                append (run->d[D_SCAT], H5T_NATIVE_FLOAT, NULL, 1, r->scattered) &&
                append (run->d[D_MASK], H5T_NATIVE_UINT8, NULL, 1, r->mask) &&
                (!run->phases || append_phases (run, r->raw)) && append (run->d[D_TIME], tt, stamp, 1, NULL) &&
                append (run->d[D_META], H5T_NATIVE_UINT8, json, len, NULL) &&
                append (run->d[D_META_END], H5T_NATIVE_UINT64, &end, 1, NULL) &&
                H5Fflush (run->file, H5F_SCOPE_LOCAL) >= 0;
  H5Tclose (tt);
  /* Last: the set counts only once everything above is on disk. */
  guint64 set_id = (guint64) ds_json_path_int (r->meta, "set_id", 0);
  ok = ok && append (run->d[D_SET_ID], H5T_NATIVE_UINT64, &set_id, 1, NULL) &&
       H5Fflush (run->file, H5F_SCOPE_LOCAL) >= 0;
  if (!ok) {
    g_autofree char *what = g_strdup_printf ("%s: appending set %" G_GUINT64_FORMAT, run->partial, set_id);
    return ds_h5_fail (error, what);
  }
  run->meta_bytes = end;
  run->sets++;
  g_free (run->last_time);
  run->last_time = g_strdup (stamp);
  return TRUE;
}

guint64
ds_hdf5_run_sets (const DsHdf5Run *run)
{
  return run->sets;
}

const char *
ds_hdf5_run_path (const DsHdf5Run *run)
{
  return run->path;
}

const char *
ds_hdf5_run_partial_path (const DsHdf5Run *run)
{
  return run->partial;
}

guint64
ds_hdf5_run_bytes (const DsHdf5Run *run)
{
  GStatBuf st;
  return g_stat (run->partial, &st) == 0 ? (guint64) st.st_size : 0;
}

void
ds_hdf5_run_abandon (DsHdf5Run *run)
{
  if (run)
    run_free (run);
}

gboolean
ds_hdf5_run_close (DsHdf5Run *run, GError **error)
{
  ds_h5_quiet ();
  g_autofree char *partial = g_strdup (run->partial);
  g_autofree char *path = g_strdup (run->path);
  g_autofree char *end_time = g_strdup (run->last_time);
  close_datasets (run);
  herr_t r = H5Fclose (run->file);
  run->file = -1;
  run_free (run);
  if (r < 0) {
    g_autofree char *what = g_strdup_printf ("%s: closing failed", partial);
    return ds_h5_fail (error, what);
  }
  /* Out of SWMR mode now: objects may be added again. */
  if (end_time && *end_time) {
    hid_t file = H5Fopen (partial, H5F_ACC_RDWR, H5P_DEFAULT);
    hid_t entry = file >= 0 ? H5Gopen2 (file, "entry", H5P_DEFAULT) : -1;
    gboolean ok = entry >= 0 && ds_h5_string_dataset (entry, "end_time", end_time);
    if (entry >= 0)
      H5Gclose (entry);
    if ((file >= 0 && H5Fclose (file) < 0) || !ok) {
      g_autofree char *what = g_strdup_printf ("%s: writing end_time", partial);
      return ds_h5_fail (error, what);
    }
  }
  return ds_durable_rename (partial, path, error);
}
