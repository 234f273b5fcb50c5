#include "daemon/ctl/ctl_output.h"

#include <string.h>

#include "daemon/output/output_error.h"
#include "daemon/output/result_meta.h"

struct DsCtlResult {
  DsOutputResult planes;
  GPtrArray *images;   /* owned DsImage */
  DsRawFrames *raw;
};

void
ds_ctl_result_free (DsCtlResult *r)
{
  if (!r)
    return;
  g_ptr_array_unref (r->images);
  ds_raw_frames_free (r->raw);
  if (r->planes.meta)
    json_node_unref (r->planes.meta);
  g_free (r);
}

const DsOutputResult *
ds_ctl_result_planes (const DsCtlResult *r)
{
  return &r->planes;
}

static int
find_payload (const DsMessage *m, const char *name)
{
  for (guint i = 0; i < m->reply->n_payloads; i++)
    if (strcmp (m->reply->payloads[i].name, name) == 0)
      return (int) i;
  return -1;
}

/* A payload as an image; u16 planes of a float result are widened (exactly) to f32. */
static DsImage *
payload_image (const DsMessage *m, int i, gboolean want_float, GError **error)
{
  const DsPayloadInfo *info = &m->reply->payloads[i];
  DsSampleType type = strcmp (info->dtype, "f32") == 0   ? DS_SAMPLE_F32
                      : strcmp (info->dtype, "u16") == 0 ? DS_SAMPLE_U16
                                                         : DS_SAMPLE_U8;
  DsSampleType out = want_float ? DS_SAMPLE_F32 : type;
  g_autoptr (DsImage) img = ds_image_new (out, info->width, info->height, error);
  if (!img)
    return NULL;
  const guint8 *src = g_bytes_get_data (m->payloads[i], NULL);
  gsize row = (gsize) info->width * ds_sample_size (type);
  for (guint y = 0; y < info->height; y++) {
    const guint8 *in = src + (gsize) y * row;
    if (out == type)
      memcpy (ds_image_row (img, y), in, row);
    else
      for (guint x = 0; x < info->width; x++)
        ((float *) ds_image_row (img, y))[x] = type == DS_SAMPLE_U16 ? (float) ((const guint16 *) in)[x]
                                                                      : (float) in[x];
  }
  return g_steal_pointer (&img);
}

static const DsImage *
plane (DsCtlResult *r, const DsMessage *m, const char *name, gboolean required, gboolean want_float,
       GError **error)
{
  int i = find_payload (m, name);
  if (i < 0) {
    if (required)
      g_set_error (error, DS_OUTPUT_ERROR, DS_OUTPUT_ERROR_INVALID, "the result has no %s payload", name);
    return NULL;
  }
  DsImage *img = payload_image (m, i, want_float, error);
  if (img)
    g_ptr_array_add (r->images, img);
  return img;
}

static gboolean
raw_from_payloads (DsCtlResult *r, const DsMessage *m, GError **error)
{
  JsonNode *node = ds_json_path (m->reply->body, "raw_frames.frames");
  if (!node || !JSON_NODE_HOLDS_ARRAY (node))
    return TRUE;
  JsonArray *frames = json_node_get_array (node);
  /* A streamed result lists the frames the daemon kept for its spool but does not send them:
   * then this copy of the result has none. */
  gboolean any = find_payload (m, "black") >= 0;
  for (guint i = 0; !any && i < json_array_get_length (frames); i++)
    any = find_payload (m, ds_json_path_string (json_array_get_element (frames, i), "payload", "")) >= 0;
  if (!any) {
    json_object_remove_member (json_node_get_object (r->planes.meta), "raw_frames");
    return TRUE;
  }
  r->raw = ds_raw_frames_new ((guint) ds_json_path_int (m->reply->body, "raw_frames.n_phases", 0));
  for (guint i = 0; i < json_array_get_length (frames); i++) {
    JsonNode *f = json_array_get_element (frames, i);
    const char *name = ds_json_path_string (f, "payload", "");
    int p = find_payload (m, name);
    if (p < 0) {
      g_set_error (error, DS_OUTPUT_ERROR, DS_OUTPUT_ERROR_INVALID, "raw frame %u: no payload \"%s\"", i, name);
      return FALSE;
    }
    DsImage *img = payload_image (m, p, FALSE, error);
    if (!img)
      return FALSE;
    img->bit_depth = (guint) ds_json_path_int (f, "bit_depth", img->bit_depth);
    ds_raw_frames_add_owned (r->raw, (guint) ds_json_path_int (f, "phase", 0),
                             (guint64) ds_json_path_int (f, "frame_id", 0),
                             (guint64) ds_json_path_int (f, "timestamp_ns", 0), img);
  }
  int b = find_payload (m, "black");
  if (b >= 0) {
    g_autoptr (DsImage) black = payload_image (m, b, FALSE, error);
    if (!black)
      return FALSE;
    black->bit_depth = (guint) ds_json_path_int (m->reply->body, "raw_frames.black_bit_depth", black->bit_depth);
    g_autoptr (GArray) ids = g_array_new (FALSE, FALSE, sizeof (guint64));
    JsonNode *idn = ds_json_path (m->reply->body, "raw_frames.black_frame_ids");
    for (guint i = 0; idn && JSON_NODE_HOLDS_ARRAY (idn) && i < json_array_get_length (json_node_get_array (idn)); i++) {
      guint64 id = (guint64) json_array_get_int_element (json_node_get_array (idn), i);
      g_array_append_val (ids, id);
    }
    if (!ds_raw_frames_set_black (r->raw, black, (const guint64 *) ids->data, ids->len, error))
      return FALSE;
  }
  r->planes.raw = r->raw;
  return TRUE;
}

DsCtlResult *
ds_ctl_result_new (const DsMessage *m, GError **error)
{
  if (!m->reply->body || !JSON_NODE_HOLDS_OBJECT (m->reply->body)) {
    g_set_error (error, DS_OUTPUT_ERROR, DS_OUTPUT_ERROR_INVALID, "the result carries no metadata");
    return NULL;
  }
  g_autoptr (DsCtlResult) r = g_new0 (DsCtlResult, 1);
  r->images = g_ptr_array_new_with_free_func ((GDestroyNotify) ds_image_free);
  r->planes.meta = ds_json_deep_copy (m->reply->body);
  GError *local = NULL;
  r->planes.transmissive = plane (r, m, "transmissive", TRUE, TRUE, &local);
  if (!local)
    r->planes.scattered = plane (r, m, "scattered", TRUE, TRUE, &local);
  if (!local)
    r->planes.mask = plane (r, m, "mask", TRUE, FALSE, &local);
  if (!local)
    r->planes.max = plane (r, m, "max", FALSE, TRUE, &local);
  if (!local)
    r->planes.min = plane (r, m, "min", FALSE, TRUE, &local);
  if (!local)
    r->planes.mean = plane (r, m, "mean", FALSE, TRUE, &local);
  if (local || !raw_from_payloads (r, m, &local)) {
    g_propagate_error (error, local);
    return NULL;
  }
  return g_steal_pointer (&r);
}

gboolean
ds_ctl_write_result (const DsMessage *m, const char *dir, guint kinds, GPtrArray *written, GError **error)
{
  g_autoptr (DsCtlResult) r = ds_ctl_result_new (m, error);
  if (!r)
    return FALSE;
  g_autofree char *stem = ds_result_stem (r->planes.meta);
  return ds_result_write_files (&r->planes, dir, stem, kinds & ~DS_FILES_HDF5_RUN, written, error);
}
