#include "daemon/output/phase_folder_write.h"

#include <errno.h>
#include <glib/gstdio.h>
#include <math.h>
#include <string.h>

#include "daemon/output/atomic_file.h"
#include "daemon/output/output_error.h"
#include "daemon/output/result_meta.h"

char *
ds_phase_folder_frame_name (const DsRawFrames *raw, guint i)
{
  const DsRawFrame *f = raw->frames->pdata[i];
  guint m = 0;
  for (guint j = 0; j < i; j++)
    if (((const DsRawFrame *) raw->frames->pdata[j])->phase == f->phase)
      m++;
  return g_strdup_printf ("phase-%02u-%u.png", f->phase, m);
}

static void
copy_member (JsonBuilder *b, JsonNode *meta, const char *path, const char *key)
{
  JsonNode *n = ds_json_path (meta, path);
  if (!n)
    return;
  json_builder_set_member_name (b, key);
  json_builder_add_value (b, json_node_copy (n));
}

JsonNode *
ds_phase_folder_sidecar (const DsRawFrames *raw, JsonNode *meta)
{
  const DsImage *ref = raw->frames->len ? ((const DsRawFrame *) raw->frames->pdata[0])->image : raw->black;
  guint bit_depth = ref ? ref->bit_depth : 16;
  g_autoptr (JsonBuilder) b = json_builder_new ();
  json_builder_begin_object (b);
  json_builder_set_member_name (b, "format");
  json_builder_add_string_value (b, "descatter-phase-folder");
  json_builder_set_member_name (b, "version");
  json_builder_add_int_value (b, 1);

  json_builder_set_member_name (b, "producer");
  json_builder_begin_object (b);
  json_builder_set_member_name (b, "program");
  json_builder_add_string_value (b, ds_json_path_string (meta, "producer.program", "descatterd"));
  copy_member (b, meta, "producer.version", "version");
  copy_member (b, meta, "producer.git", "git");
  copy_member (b, meta, "producer.host", "host");
  copy_member (b, meta, "camera.backend", "backend");
  json_builder_set_member_name (b, "camera");
  json_builder_begin_object (b);
  copy_member (b, meta, "camera.vendor", "vendor");
  copy_member (b, meta, "camera.model", "model");
  copy_member (b, meta, "camera.serial", "serial");
  json_builder_end_object (b);
  json_builder_end_object (b);

  copy_member (b, meta, "time_utc", "time_utc");
  copy_member (b, meta, "set_id", "set_id");
  json_builder_set_member_name (b, "width");
  json_builder_add_int_value (b, ref ? ref->width : 0);
  json_builder_set_member_name (b, "height");
  json_builder_add_int_value (b, ref ? ref->height : 0);
  json_builder_set_member_name (b, "bit_depth");
  json_builder_add_int_value (b, bit_depth);
  /* The level the daemon flagged as saturated; without one, the ADC's maximum. */
  double sat = ds_json_path_double (meta, "separation.saturation_level", NAN);
  json_builder_set_member_name (b, "saturation_dn");
  json_builder_add_double_value (b, isfinite (sat) ? sat : (double) ((1u << MIN (bit_depth, 16u)) - 1u));
  copy_member (b, meta, "camera.pixel_format", "pixel_format");
  copy_member (b, meta, "settings.exposure_us", "exposure_us");
  copy_member (b, meta, "settings.gain_db", "gain_db");

  json_builder_set_member_name (b, "pattern");
  json_builder_begin_object (b);
  json_builder_set_member_name (b, "kind");
  json_builder_add_string_value (b, ds_json_path_string (meta, "pattern.kind",
                                                         ds_json_path_string (meta, "settings.pattern", "square")));
  ds_json_add_double_or_null (b, "period_px", ds_json_path_double (meta, "pattern.period_px",
                                                                  ds_json_path_double (meta, "settings.period_px", NAN)));
  ds_json_add_double_or_null (b, "duty", ds_json_path_double (meta, "pattern.duty",
                                                             ds_json_path_double (meta, "separation.duty", 0.5)));
  ds_json_add_double_or_null (b, "black_level", ds_json_path_double (meta, "pattern.black_level",
                                                                    ds_json_path_double (meta, "separation.black_level", 0.0)));
  copy_member (b, meta, "pattern.phase_offset_cycles", "phase_offset_cycles");
  /* The blur the acquisition knew enters the sampling check and the motion bit's pattern
   * allowance: a reprocessing without it flags other pixels. */
  copy_member (b, meta, "settings.edge_blur_px", "edge_blur_px");
  copy_member (b, meta, "settings.harmonic_gain", "harmonic_gain");
  json_builder_end_object (b);

  json_builder_set_member_name (b, "n_phases");
  json_builder_add_int_value (b, raw->n_phases);
  json_builder_set_member_name (b, "frames");
  json_builder_begin_array (b);
  for (guint i = 0; i < raw->frames->len; i++) {
    const DsRawFrame *f = raw->frames->pdata[i];
    g_autofree char *name = ds_phase_folder_frame_name (raw, i);
    json_builder_begin_object (b);
    json_builder_set_member_name (b, "file");
    json_builder_add_string_value (b, name);
    json_builder_set_member_name (b, "phase");
    json_builder_add_int_value (b, f->phase);
    json_builder_set_member_name (b, "frame_id");
    json_builder_add_int_value (b, (gint64) f->frame_id);
    json_builder_set_member_name (b, "timestamp_ns");
    json_builder_add_int_value (b, (gint64) f->timestamp_ns);
    json_builder_end_object (b);
  }
  json_builder_end_array (b);
  if (raw->black) {
    json_builder_set_member_name (b, "black");
    json_builder_begin_object (b);
    json_builder_set_member_name (b, "files");
    json_builder_begin_array (b);
    json_builder_add_string_value (b, "black.png");
    json_builder_end_array (b);
    json_builder_set_member_name (b, "frame_ids");
    json_builder_begin_array (b);
    for (guint i = 0; i < raw->black_ids->len; i++)
      json_builder_add_int_value (b, (gint64) g_array_index (raw->black_ids, guint64, i));
    json_builder_end_array (b);
    /* One file holding the average the daemon subtracted, not the frames themselves: the
     * offline result then subtracts exactly the same values. */
    json_builder_set_member_name (b, "averaged");
    json_builder_add_boolean_value (b, TRUE);
    json_builder_end_object (b);
  }
  copy_member (b, meta, "settings", "settings");
  json_builder_end_object (b);
  return json_builder_get_root (b);
}

/* 16-bit PNG for integer frames whatever their depth (docs/phase-folder.md): values unchanged. */
static gboolean
write_frame_png (const DsImage *img, const char *path, GError **error)
{
  if (img->type == DS_SAMPLE_U16)
    return ds_image_write (img, path, error);
  if (img->type != DS_SAMPLE_U8) {
    g_set_error (error, DS_OUTPUT_ERROR, DS_OUTPUT_ERROR_INVALID, "%s: raw frames must be u8 or u16, not %s",
                 path, ds_sample_type_name (img->type));
    return FALSE;
  }
  g_autoptr (DsImage) wide = ds_image_new (DS_SAMPLE_U16, img->width, img->height, error);
  if (!wide)
    return FALSE;
  wide->bit_depth = img->bit_depth;
  for (guint y = 0; y < img->height; y++) {
    const guint8 *in = ds_image_row (img, y);
    guint16 *out = ds_image_row (wide, y);
    for (guint x = 0; x < img->width; x++)
      out[x] = in[x];
  }
  return ds_image_write (wide, path, error);
}

static void
remove_tree (const char *dir)
{
  g_autoptr (GDir) d = g_dir_open (dir, 0, NULL);
  const char *name;
  while (d && (name = g_dir_read_name (d))) {
    g_autofree char *p = g_build_filename (dir, name, NULL);
    if (g_file_test (p, G_FILE_TEST_IS_DIR) && !g_file_test (p, G_FILE_TEST_IS_SYMLINK))
      remove_tree (p);
    else
      g_unlink (p);
  }
  g_rmdir (dir);
}

static gboolean
fill_folder (const DsRawFrames *raw, JsonNode *meta, const char *tmp, GError **error)
{
  for (guint i = 0; i < raw->frames->len; i++) {
    const DsRawFrame *f = raw->frames->pdata[i];
    g_autofree char *name = ds_phase_folder_frame_name (raw, i);
    g_autofree char *path = g_build_filename (tmp, name, NULL);
    if (!write_frame_png (f->image, path, error))
      return FALSE;
  }
  if (raw->black) {
    g_autofree char *path = g_build_filename (tmp, "black.png", NULL);
    if (!write_frame_png (raw->black, path, error))
      return FALSE;
  }
  g_autoptr (JsonNode) sidecar = ds_phase_folder_sidecar (raw, meta);
  g_autofree char *text = json_to_string (sidecar, TRUE);
  g_autofree char *path = g_build_filename (tmp, "frames.json", NULL);
  return ds_atomic_write_bytes (path, text, strlen (text), error);
}

gboolean
ds_phase_folder_write (const DsRawFrames *raw, JsonNode *meta, const char *dir, GError **error)
{
  if (raw->frames->len == 0) {
    g_set_error (error, DS_OUTPUT_ERROR, DS_OUTPUT_ERROR_INVALID, "%s: no raw frames to write", dir);
    return FALSE;
  }
  if (g_file_test (dir, G_FILE_TEST_EXISTS)) {
    g_set_error (error, DS_OUTPUT_ERROR, DS_OUTPUT_ERROR_IO, "%s: already exists; not overwriting a phase folder",
                 dir);
    return FALSE;
  }
  g_autofree char *tmp = ds_atomic_temp_path (dir);
  if (g_mkdir (tmp, 0755) != 0) {
    int e = errno;
    g_set_error (error, DS_OUTPUT_ERROR, DS_OUTPUT_ERROR_IO, "%s: cannot create: %s", tmp, g_strerror (e));
    return FALSE;
  }
  if (!fill_folder (raw, meta, tmp, error) || !ds_fsync_path (tmp, TRUE, error)) {
    remove_tree (tmp);
    g_prefix_error (error, "phase folder %s: ", dir);
    return FALSE;
  }
  if (g_rename (tmp, dir) != 0) {
    int e = errno;
    remove_tree (tmp);
    g_set_error (error, DS_OUTPUT_ERROR, DS_OUTPUT_ERROR_IO, "%s: rename failed: %s", dir, g_strerror (e));
    return FALSE;
  }
  g_autofree char *parent = g_path_get_dirname (dir);
  return ds_fsync_path (parent, TRUE, error);
}
