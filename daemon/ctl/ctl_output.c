#include "daemon/ctl/ctl_output.h"

#include <glib/gstdio.h>
#include <string.h>

#include "proc/image.h"
#include "proc/preview.h"

static DsImage *
payload_image (const DsPayloadInfo *info, GBytes *bytes, GError **error)
{
  DsSampleType type = strcmp (info->dtype, "f32") == 0   ? DS_SAMPLE_F32
                      : strcmp (info->dtype, "u16") == 0 ? DS_SAMPLE_U16
                                                         : DS_SAMPLE_U8;
  DsImage *img = ds_image_new (type, info->width, info->height, error);
  if (!img)
    return NULL;
  gsize n;
  const guint8 *src = g_bytes_get_data (bytes, &n);
  gsize row = (gsize) info->width * ds_sample_size (type);
  for (guint y = 0; y < info->height; y++)
    memcpy (ds_image_row (img, y), src + (gsize) y * row, row);
  return img;
}

gboolean
ds_ctl_write_result (const DsMessage *m, const char *dir, const char *prefix, GError **error)
{
  if (g_mkdir_with_parents (dir, 0755) != 0) {
    g_set_error (error, G_FILE_ERROR, G_FILE_ERROR_FAILED, "cannot create %s", dir);
    return FALSE;
  }
  for (guint i = 0; i < m->reply->n_payloads; i++) {
    const DsPayloadInfo *info = &m->reply->payloads[i];
    g_autoptr (DsImage) img = payload_image (info, m->payloads[i], error);
    if (!img)
      return FALSE;
    gboolean is_float = img->type == DS_SAMPLE_F32;
    g_autofree char *path = g_strdup_printf ("%s/%s%s.%s", dir, prefix, info->name,
                                             is_float ? "tiff" : "png");
    if (!ds_image_write (img, path, error))
      return FALSE;
    if (strcmp (info->name, "mask") != 0) {
      /* Previews span the 0.5th..99.5th percentile: a person sees the structure, not the
       * few saturated or negative pixels. */
      g_autoptr (DsImage) preview = ds_preview_u8 (img, 0.5, 99.5, error);
      g_autofree char *ppath = g_strdup_printf ("%s/%s%s-preview.png", dir, prefix, info->name);
      if (!preview || !ds_image_write (preview, ppath, error))
        return FALSE;
    }
  }
  g_autofree char *json = m->reply->body ? json_to_string (m->reply->body, TRUE) : g_strdup ("{}");
  g_autofree char *jpath = g_strdup_printf ("%s/%sresult.json", dir, prefix);
  return g_file_set_contents_full (jpath, json, -1,
                                   G_FILE_SET_CONTENTS_CONSISTENT | G_FILE_SET_CONTENTS_DURABLE,
                                   0644, error);
}
