#include "daemon/output/hdf5_run.h"

#include <glib/gstdio.h>
#include <string.h>

#include "daemon/output/atomic_file.h"
#include "daemon/output/disk_room.h"
#include "daemon/output/hdf5_set.h"
#include "daemon/output/hdf5_util.h"
#include "daemon/output/nxdata_image.h"
#include "daemon/output/output_error.h"
#include "daemon/output/result_meta.h"

#define TIME_CHARS 32
#define REASON_CHARS 160
/* Room kept free beyond a set's own bytes: HDF5's metadata (chunk indexes, object headers)
 * grows with each append by far less. */
#define APPEND_SLACK_BYTES (256 * 1024)

enum { D_TRANS, D_SCAT, D_MASK, D_PHASES, D_PHASE, D_FRAME_ID, D_SET_INDEX, D_BLACK, D_HAS_BLACK,
       D_TIME, D_META, D_META_END, D_SET_ID, D_FRAMES_END, D_MISSING_ID, D_MISSING_REASON, D_N };

/* What counts a dataset's rows: the committed sets, raw frames, metadata bytes or lost sets. */
typedef enum { BY_SET, BY_FRAME, BY_META_BYTE, BY_MISSING } RowUnit;

static const struct {
  const char *path;
  RowUnit unit;
} dataset_info[D_N] = {
  [D_TRANS] = { "entry/transmissive/data", BY_SET },   [D_SCAT] = { "entry/scattered/data", BY_SET },
  [D_MASK] = { "entry/mask/data", BY_SET },            [D_PHASES] = { "entry/phases/data", BY_FRAME },
  [D_PHASE] = { "entry/phases/phase", BY_FRAME },      [D_FRAME_ID] = { "entry/phases/frame_id", BY_FRAME },
  [D_SET_INDEX] = { "entry/phases/set_index", BY_FRAME }, [D_BLACK] = { "entry/phases/black", BY_SET },
  [D_HAS_BLACK] = { "entry/phases/has_black", BY_SET }, [D_TIME] = { "entry/sets/time_utc", BY_SET },
  [D_META] = { "entry/sets/metadata", BY_META_BYTE },  [D_META_END] = { "entry/sets/metadata_end", BY_SET },
  [D_SET_ID] = { "entry/sets/set_id", BY_SET },        [D_FRAMES_END] = { "entry/sets/frames_end", BY_SET },
  [D_MISSING_ID] = { "entry/sets/missing_set_id", BY_MISSING },
  [D_MISSING_REASON] = { "entry/sets/missing_reason", BY_MISSING },
};

struct DsHdf5Run {
  char *path, *partial, *reserve;
  hid_t file;       /* -1 while retired and closed */
  hid_t d[D_N];     /* -1 when absent or retired */
  guint width, height;
  gboolean phases;
  /* The committed rows: what len(sets/set_id) counts. Every append writes at these offsets, so
   * whatever a failed append left beyond them is overwritten by the next set: the rollback. */
  guint64 sets, frames, meta_bytes, missing;
  /* Sets lost since the last commit and why; written with the next set, or at close. */
  GArray *lost_ids;
  GPtrArray *lost_reasons;
  /* An HDF5 write failed: the library's state of this file is not trusted any more, so the
   * handle was closed; the next append reopens the file from what is on disk. */
  gboolean retired;
  /* Closing failed: the file cannot be used again in this process (see close_file). */
  gboolean broken;
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
fixed_string_type (gsize chars)
{
  hid_t t = H5Tcopy (H5T_C_S1);
  H5Tset_size (t, chars);
  H5Tset_strpad (t, H5T_STR_NULLPAD);
  return t;
}

/* An NXdata group whose signal "data" grows by one image per set (or frame): along the lead
 * axis, the image's y and x. The sets have no axis dataset of their own ("."): entry/sets/set_id
 * is written last and may be shorter than the planes while a set is being appended. */
static hid_t
time_type (void)
{
  return fixed_string_type (TIME_CHARS);
}

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
    run->d[D_FRAMES_END] = extendible (sets, "frames_end", H5T_STD_U64LE, 1, 0, 0);
    run->d[D_MISSING_ID] = extendible (sets, "missing_set_id", H5T_STD_U64LE, 1, 0, 0);
    hid_t rt = fixed_string_type (REASON_CHARS);
    run->d[D_MISSING_REASON] = extendible (sets, "missing_reason", rt, 1, 0, 0);
    H5Tclose (rt);
    ok = run->d[D_TIME] >= 0 && run->d[D_META] >= 0 && run->d[D_META_END] >= 0 && run->d[D_SET_ID] >= 0 &&
         run->d[D_FRAMES_END] >= 0 && run->d[D_MISSING_ID] >= 0 && run->d[D_MISSING_REASON] >= 0 &&
         ds_h5_attr_string (sets, "note",
                            "set_id is written last: its length counts the complete sets; rows of other "
                            "datasets beyond it belong to no set. missing_set_id: sets the run lost, "
                            "missing_reason: why");
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

/* Closes the file. A close that fails (its last flush refused) leaves HDF5's state of the file
 * half torn down: the handle is never used again, not even to close it (that crashes inside
 * HDF5), and the run is broken. The .partial file stays as after a crash: readable up to its
 * committed sets. HDF5 does not close it at exit either (ds_h5_quiet turns that off). */
static gboolean
close_file (DsHdf5Run *run)
{
  close_datasets (run);
  if (run->file >= 0 && H5Fclose (run->file) < 0)
    run->broken = TRUE;
  run->file = -1;
  return !run->broken;
}

static void
run_free (DsHdf5Run *run)
{
  close_file (run);
  ds_disk_reserve_release (run->reserve);
  g_free (run->path);
  g_free (run->partial);
  g_free (run->reserve);
  g_free (run->last_time);
  g_array_unref (run->lost_ids);
  g_ptr_array_unref (run->lost_reasons);
  g_free (run);
}

static gboolean
present (const DsHdf5Run *run, guint i)
{
  return run->phases || i < D_PHASES || i > D_HAS_BLACK;
}

static hid_t
latest_format (void)
{
  /* SWMR needs the newest file format. */
  hid_t fapl = H5Pcreate (H5P_FILE_ACCESS);
  H5Pset_libver_bounds (fapl, H5F_LIBVER_LATEST, H5F_LIBVER_LATEST);
  return fapl;
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
  run->reserve = ds_disk_reserve_path (run->partial);
  run->lost_ids = g_array_new (FALSE, FALSE, sizeof (guint64));
  run->lost_reasons = g_ptr_array_new_with_free_func (g_free);
  run->width = first->transmissive->width;
  run->height = first->transmissive->height;
  run->phases = first->raw && first->raw->frames->len > 0;
  hid_t fapl = latest_format ();
  gboolean existed = g_file_test (run->partial, G_FILE_TEST_EXISTS);
  run->file = H5Fcreate (run->partial, H5F_ACC_EXCL, H5P_DEFAULT, fapl);
  H5Pclose (fapl);
  if (run->file < 0) {
    g_autofree char *what = g_strdup_printf ("%s: cannot create", run->partial);
    ds_h5_fail (error, what);
    g_autofree char *partial = g_strdup (run->partial);
    run_free (run);
    /* A file HDF5 began (a full disk) is no run; one that was there before is not ours. */
    if (!existed)
      g_unlink (partial);
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
  /* Without room for the reserve the run still starts; a failed write may then leave the file
   * open until the disk has room again. */
  ds_disk_reserve_take (run->reserve);
  return run;
}

/* Writes `count` elements (1-D) or one image (3-D) at row `at`, growing the dataset if it is
 * shorter. Rows are never appended at the dataset's end: that end may hold a failed set. */
static gboolean
write_at (hid_t d, hid_t mem_type, const void *data, guint64 at, guint64 count, const DsImage *img)
{
  hid_t fs = H5Dget_space (d);
  int rank = H5Sget_simple_extent_ndims (fs);
  hsize_t dims[3] = { 0, 0, 0 };
  H5Sget_simple_extent_dims (fs, dims, NULL);
  H5Sclose (fs);
  if (dims[0] < at + count) {
    dims[0] = at + count;
    if (H5Dset_extent (d, dims) < 0)
      return FALSE;
  }
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

/* The raw frames of the set at rows run->frames.., its black plane at row run->sets. */
static gboolean
write_phases (DsHdf5Run *run, const DsRawFrames *raw)
{
  gboolean ok = TRUE;
  for (guint i = 0; ok && raw && i < raw->frames->len; i++) {
    const DsRawFrame *f = raw->frames->pdata[i];
    g_autoptr (DsImage) wide = f->image->type == DS_SAMPLE_U16 ? NULL : widened (f->image);
    gint32 phase = (gint32) f->phase;
    guint64 set_index = run->sets, row = run->frames + i;
    ok = write_at (run->d[D_PHASES], H5T_NATIVE_UINT16, NULL, row, 1, wide ? wide : f->image) &&
         write_at (run->d[D_PHASE], H5T_NATIVE_INT32, &phase, row, 1, NULL) &&
         write_at (run->d[D_FRAME_ID], H5T_NATIVE_UINT64, &f->frame_id, row, 1, NULL) &&
         write_at (run->d[D_SET_INDEX], H5T_NATIVE_UINT64, &set_index, row, 1, NULL);
  }
  /* One black plane per set, zero when the set had none (has_black says which). */
  g_autoptr (DsImage) zero = NULL;
  const DsImage *black = raw ? raw->black : NULL;
  g_autoptr (DsImage) wide = black && black->type != DS_SAMPLE_U16 ? widened (black) : NULL;
  if (!black)
    black = zero = ds_image_new (DS_SAMPLE_U16, run->width, run->height, NULL);
  guint8 has = raw && raw->black ? 1 : 0;
  return ok && black && write_at (run->d[D_BLACK], H5T_NATIVE_UINT16, NULL, run->sets, 1, wide ? wide : black) &&
         write_at (run->d[D_HAS_BLACK], H5T_NATIVE_UINT8, &has, run->sets, 1, NULL);
}

/* The sets lost since the last commit, at rows run->missing.. of missing_set_id/_reason. */
static gboolean
write_lost (DsHdf5Run *run)
{
  hid_t rt = fixed_string_type (REASON_CHARS);
  gboolean ok = TRUE;
  for (guint i = 0; ok && i < run->lost_ids->len; i++) {
    char reason[REASON_CHARS] = { 0 };
    g_strlcpy (reason, run->lost_reasons->pdata[i], sizeof reason);
    ok = write_at (run->d[D_MISSING_REASON], rt, reason, run->missing + i, 1, NULL) &&
         write_at (run->d[D_MISSING_ID], H5T_NATIVE_UINT64, &g_array_index (run->lost_ids, guint64, i),
                   run->missing + i, 1, NULL);
  }
  H5Tclose (rt);
  return ok;
}

static void
lose (DsHdf5Run *run, guint64 set_id, const char *reason)
{
  /* The file's own name says nothing inside the file. */
  gsize n = strlen (run->partial);
  if (strncmp (reason, run->partial, n) == 0 && reason[n] == ':')
    for (reason += n + 1; *reason == ' ';)
      reason++;
  g_array_append_val (run->lost_ids, set_id);
  g_ptr_array_add (run->lost_reasons, g_strdelimit (g_strdup (reason), "\n", ' '));
}

/* After a failed write: the reserve goes first, so that closing (HDF5 flushes its metadata)
 * has room even on a full disk. What the failed append wrote lies beyond the committed rows. */
static void
retire (DsHdf5Run *run)
{
  ds_disk_reserve_release (run->reserve);
  run->retired = TRUE;
  if (!close_file (run))
    g_warning ("%s: HDF5 could not close the file after a failed write: the run ends there", run->partial);
}

/* A retired run opens its file again, from the disk, and takes back its reserve. */
static gboolean
reopen (DsHdf5Run *run, GError **error)
{
  if (run->broken) {
    g_set_error (error, DS_OUTPUT_ERROR, DS_OUTPUT_ERROR_HDF5, "%s: the file could not be closed after a failed write",
                 run->partial);
    return FALSE;
  }
  hid_t fapl = latest_format ();
  run->file = H5Fopen (run->partial, H5F_ACC_RDWR | H5F_ACC_SWMR_WRITE, fapl);
  H5Pclose (fapl);
  gboolean ok = run->file >= 0;
  for (guint i = 0; ok && i < D_N; i++)
    if (present (run, i))
      ok = (run->d[i] = H5Dopen2 (run->file, dataset_info[i].path, H5P_DEFAULT)) >= 0;
  if (!ok) {
    g_autofree char *what = g_strdup_printf ("%s: reopening after a failed write", run->partial);
    ds_h5_fail (error, what);
    close_file (run);
    return FALSE;
  }
  run->retired = FALSE;
  ds_disk_reserve_take (run->reserve);
  return TRUE;
}

static gboolean
fits (const DsHdf5Run *run, const DsOutputResult *r, GError **error)
{
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
  return TRUE;
}

/* The bytes one set adds to the file, chunk rounding of the 1-D columns included. */
static guint64
set_bytes (const DsHdf5Run *run, const DsOutputResult *r, gsize json_len)
{
  guint64 plane = (guint64) run->width * run->height;
  guint64 frames = run->phases && r->raw ? r->raw->frames->len : 0;
  return plane * (4 + 4 + 1) + (run->phases ? (frames + 1) * plane * 2 : 0) + json_len + 16 * 4096;
}

/* Everything of the set at the committed rows, then its set_id: a set counts only once all of
 * it is on disk. */
static gboolean
write_set (DsHdf5Run *run, const DsOutputResult *r, const char *json, const char *stamp, guint64 set_id)
{
  guint64 len = strlen (json);
  guint64 meta_end = run->meta_bytes + len;
  guint64 frames_end = run->frames + (run->phases && r->raw ? r->raw->frames->len : 0);
  hid_t tt = time_type ();
  guint64 k = run->sets;
  gboolean ok = write_at (run->d[D_TRANS], H5T_NATIVE_FLOAT, NULL, k, 1, r->transmissive) &&
                write_at (run->d[D_SCAT], H5T_NATIVE_FLOAT, NULL, k, 1, r->scattered) &&
                write_at (run->d[D_MASK], H5T_NATIVE_UINT8, NULL, k, 1, r->mask) &&
                (!run->phases || write_phases (run, r->raw)) && write_at (run->d[D_TIME], tt, stamp, k, 1, NULL) &&
                write_at (run->d[D_META], H5T_NATIVE_UINT8, json, run->meta_bytes, len, NULL) &&
                write_at (run->d[D_META_END], H5T_NATIVE_UINT64, &meta_end, k, 1, NULL) &&
                write_at (run->d[D_FRAMES_END], H5T_NATIVE_UINT64, &frames_end, k, 1, NULL) && write_lost (run) &&
                H5Fflush (run->file, H5F_SCOPE_LOCAL) >= 0;
  H5Tclose (tt);
  ok = ok && write_at (run->d[D_SET_ID], H5T_NATIVE_UINT64, &set_id, k, 1, NULL) &&
       H5Fflush (run->file, H5F_SCOPE_LOCAL) >= 0;
  if (ok) {
    run->sets++;
    run->frames = frames_end;
    run->meta_bytes = meta_end;
    run->missing += run->lost_ids->len;
    g_array_set_size (run->lost_ids, 0);
    g_ptr_array_set_size (run->lost_reasons, 0);
  }
  return ok;
}

gboolean
ds_hdf5_run_append (DsHdf5Run *run, const DsOutputResult *r, GError **error)
{
  ds_h5_quiet ();
  if (!fits (run, r, error))
    return FALSE;
  guint64 set_id = (guint64) ds_json_path_int (r->meta, "set_id", 0);
  g_autofree char *json = json_to_string (r->meta, FALSE);
  /* A retired run takes its reserve back when it reopens: that room is needed too. */
  guint64 need = set_bytes (run, r, strlen (json)) + APPEND_SLACK_BYTES + (run->retired ? DS_DISK_RESERVE_BYTES : 0);
  guint64 room = ds_disk_free_bytes (run->partial);
  GError *local = NULL;
  /* No append that cannot fit is started: HDF5 is not trusted after a write failed half way. */
  if (room < need) {
    g_autofree char *reason = g_strdup_printf ("no room on the disk: %" G_GUINT64_FORMAT " bytes free, %" G_GUINT64_FORMAT
                                               " needed", room, need);
    lose (run, set_id, reason);
    g_set_error (error, DS_OUTPUT_ERROR, DS_OUTPUT_ERROR_NO_SPACE, "%s: set %" G_GUINT64_FORMAT " not appended: %s",
                 run->partial, set_id, reason);
    return FALSE;
  }
  if (run->retired && !reopen (run, &local)) {
    lose (run, set_id, local->message);
    g_propagate_error (error, local);
    return FALSE;
  }
  char stamp[TIME_CHARS] = { 0 };
  g_strlcpy (stamp, ds_json_path_string (r->meta, "time_utc", ""), sizeof stamp);
  if (!write_set (run, r, json, stamp, set_id)) {
    g_autofree char *what = g_strdup_printf ("%s: appending set %" G_GUINT64_FORMAT, run->partial, set_id);
    ds_h5_fail (&local, what);
    lose (run, set_id, local->message);
    retire (run);
    g_propagate_error (error, local);
    return FALSE;
  }
  g_free (run->last_time);
  run->last_time = g_strdup (stamp);
  return TRUE;
}

gboolean
ds_hdf5_run_broken (const DsHdf5Run *run)
{
  return run->broken;
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

static guint64
committed_rows (const DsHdf5Run *run, guint i)
{
  switch (dataset_info[i].unit) {
  case BY_SET:
    return run->sets;
  case BY_FRAME:
    return run->frames;
  case BY_META_BYTE:
    return run->meta_bytes;
  case BY_MISSING:
  default:
    return run->missing;
  }
}

/* Out of SWMR mode (the file closed and opened again): every dataset cut to its committed rows,
 * so that no rolled-back row remains, the sets lost since the last commit recorded, end_time. */
static gboolean
finish (DsHdf5Run *run)
{
  hid_t fapl = latest_format ();
  run->file = H5Fopen (run->partial, H5F_ACC_RDWR, fapl);
  H5Pclose (fapl);
  gboolean ok = run->file >= 0;
  for (guint i = 0; ok && i < D_N; i++) {
    if (!present (run, i))
      continue;
    ok = (run->d[i] = H5Dopen2 (run->file, dataset_info[i].path, H5P_DEFAULT)) >= 0;
    hid_t fs = ok ? H5Dget_space (run->d[i]) : -1;
    hsize_t dims[3] = { 0, 0, 0 };
    if (fs >= 0) {
      H5Sget_simple_extent_dims (fs, dims, NULL);
      H5Sclose (fs);
    }
    dims[0] = committed_rows (run, i);
    ok = ok && fs >= 0 && H5Dset_extent (run->d[i], dims) >= 0;
  }
  ok = ok && write_lost (run);
  if (ok)
    run->missing += run->lost_ids->len;
  if (ok && run->last_time && *run->last_time) {
    hid_t entry = H5Gopen2 (run->file, "entry", H5P_DEFAULT);
    ok = entry >= 0 && ds_h5_string_dataset (entry, "end_time", run->last_time);
    if (entry >= 0)
      H5Gclose (entry);
  }
  return close_file (run) && ok;
}

gboolean
ds_hdf5_run_close (DsHdf5Run *run, GError **error)
{
  ds_h5_quiet ();
  /* The reserve goes first: room for the last flush on a full disk. */
  ds_disk_reserve_release (run->reserve);
  g_autofree char *partial = g_strdup (run->partial);
  g_autofree char *path = g_strdup (run->path);
  gboolean closed = close_file (run);
  gboolean ok = closed && finish (run);
  run_free (run);
  if (!ok) {
    g_autofree char *what = g_strdup_printf ("%s: %s", partial, closed ? "finishing the run file" : "closing failed");
    return ds_h5_fail (error, what);
  }
  return ds_durable_rename (partial, path, error);
}
