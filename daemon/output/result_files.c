#include "daemon/output/result_files.h"

#include <errno.h>
#include <glib/gstdio.h>
#include <math.h>
#include <string.h>

#include "daemon/output/atomic_file.h"
#include "daemon/output/hdf5_set.h"
#include "daemon/output/output_error.h"
#include "daemon/output/phase_folder_write.h"
#include "daemon/output/png_file.h"
#include "daemon/output/result_meta.h"
#include "daemon/output/tiff_file.h"
#include "build_info.h"
#include "proc/preview.h"

static const struct {
  const char *name;
  DsFileKinds kind;
} kind_names[] = {
  { "tiff", DS_FILES_TIFF },       { "png16", DS_FILES_PNG16 }, { "preview", DS_FILES_PREVIEW },
  { "hdf5", DS_FILES_HDF5 },       { "hdf5-run", DS_FILES_HDF5_RUN },
};

gboolean
ds_file_kinds_parse (const char *list, guint *kinds, GError **error)
{
  *kinds = 0;
  g_auto (GStrv) parts = g_strsplit (list ? list : "", ",", -1);
  for (guint i = 0; parts[i]; i++) {
    const char *p = g_strstrip (parts[i]);
    if (!*p)
      continue;
    guint j = 0;
    while (j < G_N_ELEMENTS (kind_names) && strcmp (p, kind_names[j].name) != 0)
      j++;
    if (j == G_N_ELEMENTS (kind_names)) {
      g_set_error (error, DS_OUTPUT_ERROR, DS_OUTPUT_ERROR_INVALID, "unknown file kind \"%s\" (known: %s)", p,
                   DS_FILES_ALL_NAMES);
      return FALSE;
    }
    *kinds |= kind_names[j].kind;
  }
  return TRUE;
}

char *
ds_file_kinds_to_string (guint kinds)
{
  GString *s = g_string_new (NULL);
  for (guint j = 0; j < G_N_ELEMENTS (kind_names); j++)
    if (kinds & kind_names[j].kind)
      g_string_append_printf (s, "%s%s", s->len ? "," : "", kind_names[j].name);
  return g_string_free (s, FALSE);
}

char *
ds_result_stem (JsonNode *meta)
{
  const char *t = ds_json_path_string (meta, "time_utc", NULL);
  g_autoptr (GDateTime) when = t ? g_date_time_new_from_iso8601 (t, NULL) : NULL;
  if (!when)
    when = g_date_time_new_now_utc ();
  g_autoptr (GDateTime) utc = g_date_time_to_utc (when);
  g_autofree char *stamp = g_date_time_format (utc, "%Y%m%dT%H%M%SZ");
  return g_strdup_printf ("set-%s-%06" G_GINT64_FORMAT, stamp, ds_json_path_int (meta, "set_id", 0));
}

char *
ds_result_file_name (const char *stem, const char *part, const char *ext)
{
  return stem && *stem ? g_strdup_printf ("%s-%s.%s", stem, part, ext) : g_strdup_printf ("%s.%s", part, ext);
}

DsImage *
ds_png16_scaled (const DsImage *plane, double *scale, GError **error)
{
  if (plane->type != DS_SAMPLE_F32) {
    g_set_error (error, DS_OUTPUT_ERROR, DS_OUTPUT_ERROR_INVALID, "16-bit PNG: expected a float plane, got %s",
                 ds_sample_type_name (plane->type));
    return NULL;
  }
  float top = 0.0f;
  for (guint y = 0; y < plane->height; y++) {
    const float *row = ds_image_row (plane, y);
    for (guint x = 0; x < plane->width; x++)
      if (isfinite (row[x]) && row[x] > top)
        top = row[x];
  }
  int k = 0;
  if (top > 0) {
    /* top * 2^k <= 65535 < top * 2^(k+1), with rounding to the nearest integer in mind. */
    k = (int) floor (log2 (65535.0 / top));
    while (k > -16 && ldexp (top, k) + 0.5 > 65535.5)
      k--;
    k = CLAMP (k, -16, 16);
  }
  *scale = ldexp (1.0, k);
  DsImage *out = ds_image_new (DS_SAMPLE_U16, plane->width, plane->height, error);
  if (!out)
    return NULL;
  for (guint y = 0; y < plane->height; y++) {
    const float *in = ds_image_row (plane, y);
    guint16 *o = ds_image_row (out, y);
    for (guint x = 0; x < plane->width; x++) {
      double v = isfinite (in[x]) && in[x] > 0 ? ldexp (in[x], k) : 0.0;
      o[x] = (guint16) (v < 65535.0 ? floor (v + 0.5) : 65535.0);
    }
  }
  return out;
}

/* The list of files of one set and what each holds, for the sidecar. */
typedef struct {
  const char *dir;
  GPtrArray *names;   /* basenames written so far (removed on failure) */
  JsonBuilder *files; /* inside an object */
} Written;

static void
record (Written *w, const char *name, const char *kind, const char *plane, double scale)
{
  g_ptr_array_add (w->names, g_strdup (name));
  json_builder_set_member_name (w->files, name);
  json_builder_begin_object (w->files);
  json_builder_set_member_name (w->files, "kind");
  json_builder_add_string_value (w->files, kind);
  if (plane) {
    json_builder_set_member_name (w->files, "plane");
    json_builder_add_string_value (w->files, plane);
  }
  if (!isnan (scale)) {
    json_builder_set_member_name (w->files, "scale");
    json_builder_add_double_value (w->files, scale);
    json_builder_set_member_name (w->files, "meaning");
    json_builder_add_string_value (w->files, "value in counts = file value / scale");
  }
  json_builder_end_object (w->files);
}

static gboolean
write_tiff_plane (Written *w, const DsOutputResult *r, const char *stem, const char *plane, const DsImage *img,
                  GDateTime *when, GError **error)
{
  g_autofree char *name = ds_result_file_name (stem, plane, "tiff");
  g_autofree char *path = g_build_filename (w->dir, name, NULL);
  /* The metadata of the whole result, plus which plane this file is. */
  g_autoptr (JsonNode) desc = ds_json_deep_copy (r->meta);
  json_object_set_string_member (json_node_get_object (desc), "plane", plane);
  g_autofree char *text = json_to_string (desc, FALSE);
  DsTiffTags tags = { .description = text, .time = when, .document_name = plane,
                      .pixel_size_um = ds_output_pixel_size_um (r->meta) };
  if (!ds_tiff_write (img, path, &tags, error))
    return FALSE;
  record (w, name, "tiff", plane, NAN);
  return TRUE;
}

static gboolean
write_png (Written *w, const char *stem, const char *part, const char *kind, const char *plane, const DsImage *img,
           double scale, GError **error)
{
  g_autofree char *name = ds_result_file_name (stem, part, "png");
  g_autofree char *path = g_build_filename (w->dir, name, NULL);
  if (!ds_image_write (img, path, error))
    return FALSE;
  record (w, name, kind, plane, scale);
  return TRUE;
}

/* A scaled plane (ds_png16_scaled, scale = 2^k) says in the file what its values are: the scale
 * and units as text, and sBIT = 16 - k significant bits, the bits at and above one count, so
 * that a reader shifting right by 16 - sBIT gets whole counts (the bits below are fractions of
 * a count, not noise of the file). */
static gboolean
write_png16 (Written *w, const char *stem, const char *part, const char *plane, const DsImage *img, double scale,
             GError **error)
{
  g_autofree char *name = ds_result_file_name (stem, part, "png");
  g_autofree char *path = g_build_filename (w->dir, name, NULL);
  int k = (int) lround (log2 (scale));
  guint sbit = (guint) CLAMP (16 - MAX (k, 0), 1, 16);
  char scale_text[32];
  g_ascii_formatd (scale_text, sizeof scale_text, "%.17g", scale);
  const DsPngText texts[] = {
    { "Software", "descatter " DS_VERSION " (" DS_GIT_DESCRIBE ")" },
    { "Title", plane },
    { "Description", ds_output_plane_long_name (plane) },
    { "descatter:scale", scale_text },
    { "descatter:units", ds_output_plane_units (plane) },
    { "descatter:meaning", "value in counts = file value / descatter:scale" },
  };
  if (!ds_png16_write (img, path, sbit, texts, G_N_ELEMENTS (texts), error))
    return FALSE;
  record (w, name, "png16", plane, scale);
  return TRUE;
}

static gboolean
write_all (Written *w, const DsOutputResult *r, const char *stem, guint kinds, GError **error)
{
  const char *t = ds_json_path_string (r->meta, "time_utc", NULL);
  g_autoptr (GDateTime) when = t ? g_date_time_new_from_iso8601 (t, NULL) : NULL;
  if (kinds & DS_FILES_TIFF) {
    const char *names[5];
    const DsImage *images[5];
    guint n = ds_output_result_optional (r, names, images);
    if (!write_tiff_plane (w, r, stem, "transmissive", r->transmissive, when, error) ||
        !write_tiff_plane (w, r, stem, "scattered", r->scattered, when, error) ||
        !write_png (w, stem, "mask", "png", "mask", r->mask, NAN, error))
      return FALSE;
    for (guint i = 0; i < n; i++)
      if (!write_tiff_plane (w, r, stem, names[i], images[i], when, error))
        return FALSE;
  }
  if (kinds & DS_FILES_PNG16) {
    const char *parts[] = { "direct", "global" };
    const DsImage *planes[] = { r->transmissive, r->scattered };
    for (guint i = 0; i < 2; i++) {
      double scale;
      g_autoptr (DsImage) img = ds_png16_scaled (planes[i], &scale, error);
      if (!img || !write_png16 (w, stem, parts[i], i ? "scattered" : "transmissive", img, scale, error))
        return FALSE;
    }
  }
  if (kinds & DS_FILES_PREVIEW) {
    const char *parts[] = { "transmissive-preview", "scattered-preview" };
    const DsImage *planes[] = { r->transmissive, r->scattered };
    for (guint i = 0; i < 2; i++) {
      /* 0.5th..99.5th percentile: a person sees the structure, not a few hot pixels. */
      g_autoptr (DsImage) img = ds_preview_u8 (planes[i], 0.5, 99.5, error);
      if (!img || !write_png (w, stem, parts[i], "preview", i ? "scattered" : "transmissive", img, NAN, error))
        return FALSE;
    }
  }
  if (kinds & DS_FILES_HDF5) {
    g_autofree char *name = stem && *stem ? g_strconcat (stem, ".h5", NULL) : g_strdup ("result.h5");
    g_autofree char *path = g_build_filename (w->dir, name, NULL);
    if (!ds_hdf5_write_set (r, path, error))
      return FALSE;
    record (w, name, "hdf5", NULL, NAN);
  }
  if ((kinds & DS_FILES_PHASES) && r->raw && r->raw->frames->len > 0) {
    g_autofree char *name = stem && *stem ? g_strconcat (stem, "-phases", NULL) : g_strdup ("phases");
    g_autofree char *path = g_build_filename (w->dir, name, NULL);
    if (!ds_phase_folder_write (r->raw, r->meta, path, error))
      return FALSE;
    record (w, name, "phases", NULL, NAN);
  }
  return TRUE;
}

static void
remove_path (const char *path)
{
  if (!g_file_test (path, G_FILE_TEST_IS_DIR) || g_file_test (path, G_FILE_TEST_IS_SYMLINK)) {
    g_unlink (path);
    return;
  }
  g_autoptr (GDir) d = g_dir_open (path, 0, NULL);
  const char *name;
  while (d && (name = g_dir_read_name (d))) {
    g_autofree char *p = g_build_filename (path, name, NULL);
    remove_path (p);
  }
  g_rmdir (path);
}

gboolean
ds_result_write_files (const DsOutputResult *r, const char *dir, const char *stem, guint kinds, GPtrArray *written,
                       GError **error)
{
  if (g_mkdir_with_parents (dir, 0755) != 0) {
    int e = errno;
    g_set_error (error, DS_OUTPUT_ERROR, DS_OUTPUT_ERROR_IO, "%s: cannot create folder: %s", dir, g_strerror (e));
    return FALSE;
  }
  g_autoptr (GPtrArray) names = g_ptr_array_new_with_free_func (g_free);
  g_autoptr (JsonBuilder) files = json_builder_new ();
  json_builder_begin_object (files);
  Written w = { .dir = dir, .names = names, .files = files };
  gboolean ok = write_all (&w, r, stem, kinds, error);
  g_autofree char *json_name = stem && *stem ? g_strconcat (stem, ".json", NULL) : g_strdup ("result.json");
  if (ok) {
    json_builder_end_object (files);
    g_autoptr (JsonNode) sidecar = ds_json_deep_copy (r->meta);
    json_object_set_member (json_node_get_object (sidecar), "files", json_builder_get_root (files));
    g_autofree char *text = json_to_string (sidecar, TRUE);
    g_autofree char *path = g_build_filename (dir, json_name, NULL);
    ok = ds_atomic_write_bytes (path, text, strlen (text), error);
  }
  if (!ok) {
    /* The images of an incomplete set would look like data: remove them. */
    for (guint i = 0; i < names->len; i++) {
      g_autofree char *p = g_build_filename (dir, (const char *) names->pdata[i], NULL);
      remove_path (p);
    }
    g_prefix_error (error, "set %s: ", stem && *stem ? stem : dir);
    return FALSE;
  }
  if (written) {
    for (guint i = 0; i < names->len; i++)
      g_ptr_array_add (written, g_strdup (names->pdata[i]));
    g_ptr_array_add (written, g_strdup (json_name));
  }
  return TRUE;
}
