#include "daemon/output/raw_frames.h"

#include <string.h>

static void
raw_frame_free (gpointer data)
{
  DsRawFrame *f = data;
  ds_image_free (f->image);
  g_free (f);
}

DsRawFrames *
ds_raw_frames_new (guint n_phases)
{
  DsRawFrames *raw = g_new0 (DsRawFrames, 1);
  raw->n_phases = n_phases;
  raw->frames = g_ptr_array_new_with_free_func (raw_frame_free);
  raw->black_ids = g_array_new (FALSE, FALSE, sizeof (guint64));
  raw->spare = g_ptr_array_new_with_free_func ((GDestroyNotify) ds_image_free);
  return raw;
}

void
ds_raw_frames_free (DsRawFrames *raw)
{
  if (!raw)
    return;
  g_ptr_array_unref (raw->frames);
  g_array_unref (raw->black_ids);
  g_ptr_array_unref (raw->spare);
  ds_image_free (raw->black);
  g_free (raw);
}

void
ds_raw_frames_add_owned (DsRawFrames *raw, guint phase, guint64 frame_id, guint64 timestamp_ns, DsImage *image)
{
  DsRawFrame *f = g_new0 (DsRawFrame, 1);
  f->phase = phase;
  f->frame_id = frame_id;
  f->timestamp_ns = timestamp_ns;
  f->image = image;
  g_ptr_array_add (raw->frames, f);
}

gboolean
ds_raw_frames_reserve (DsRawFrames *raw, guint count, DsSampleType type, guint width, guint height,
                       GError **error)
{
  for (guint i = 0; i < count; i++) {
    DsImage *img = ds_image_new (type, width, height, error);
    if (!img)
      return FALSE;
    memset (img->data, 0, img->stride * img->height);
    g_ptr_array_add (raw->spare, img);
  }
  return TRUE;
}

void
ds_raw_frames_trim (DsRawFrames *raw)
{
  g_ptr_array_set_size (raw->spare, 0);
}

gboolean
ds_raw_frames_add (DsRawFrames *raw, guint phase, guint64 frame_id, guint64 timestamp_ns, const DsImage *image,
                   GError **error)
{
  DsImage *copy = NULL;
  if (raw->spare->len > 0) {
    DsImage *room = g_ptr_array_index (raw->spare, raw->spare->len - 1);
    if (room->type == image->type && room->width == image->width && room->height == image->height) {
      copy = g_ptr_array_steal_index_fast (raw->spare, raw->spare->len - 1);
      gsize row = (gsize) image->width * ds_sample_size (image->type);
      for (guint y = 0; y < image->height; y++)
        memcpy (ds_image_row (copy, y), ds_image_row (image, y), row);
      copy->bit_depth = image->bit_depth;
    }
  }
  if (!copy)
    copy = ds_image_copy (image, error);
  if (!copy)
    return FALSE;
  ds_raw_frames_add_owned (raw, phase, frame_id, timestamp_ns, copy);
  return TRUE;
}

gboolean
ds_raw_frames_set_black (DsRawFrames *raw, const DsImage *black, const guint64 *ids, guint n_ids, GError **error)
{
  DsImage *copy = ds_image_copy (black, error);
  if (!copy)
    return FALSE;
  ds_image_free (raw->black);
  raw->black = copy;
  g_array_set_size (raw->black_ids, 0);
  if (n_ids)
    g_array_append_vals (raw->black_ids, ids, n_ids);
  return TRUE;
}

guint
ds_raw_frames_per_phase (const DsRawFrames *raw)
{
  if (raw->n_phases == 0)
    return 0;
  g_autofree guint *count = g_new0 (guint, raw->n_phases);
  for (guint i = 0; i < raw->frames->len; i++) {
    const DsRawFrame *f = raw->frames->pdata[i];
    if (f->phase < raw->n_phases)
      count[f->phase]++;
  }
  guint m = G_MAXUINT;
  for (guint k = 0; k < raw->n_phases; k++)
    m = MIN (m, count[k]);
  return m;
}

gsize
ds_raw_frames_bytes (const DsRawFrames *raw)
{
  gsize n = raw->black ? raw->black->stride * raw->black->height : 0;
  for (guint i = 0; i < raw->frames->len; i++) {
    const DsRawFrame *f = raw->frames->pdata[i];
    n += f->image->stride * f->image->height;
  }
  return n;
}
