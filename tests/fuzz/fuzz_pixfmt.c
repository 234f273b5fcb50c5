/* Fuzz target: pixel-format unpacking. Header bytes choose format, width, height and stride;
 * the rest is the payload. Any input either unpacks, or fails with a message without reading
 * past the payload; an unpacked image packs and unpacks back to itself. */
#include <stdint.h>
#include <string.h>

#include "proc/pixfmt.h"

int LLVMFuzzerTestOneInput (const uint8_t *data, size_t size);

int
LLVMFuzzerTestOneInput (const uint8_t *data, size_t size)
{
  if (size < 4)
    return 0;
  DsPixelFormat fmt = (DsPixelFormat) (data[0] % DS_PIXFMT_COUNT);
  guint width = 1u + data[1] % 64u, height = 1u + data[2] % 16u;
  gsize row = ds_pixfmt_row_bytes (fmt, width);
  /* 0: continuous; 255: one byte too small (must be refused); else padded by 0..7. */
  gsize stride = data[3] == 0 ? 0 : data[3] == 255 ? row - 1 : row + (data[3] - 1u) % 8u;
  /* An exactly sized copy, so that the sanitizer sees any overread. */
  gsize n = size - 4;
  guint8 *payload = g_malloc (n ? n : 1);
  memcpy (payload, data + 4, n);
  GError *error = NULL;
  DsImage *img = ds_pixfmt_unpack (fmt, payload, n, width, height, stride, &error);
  if (!img) {
    g_assert (error && error->message && *error->message);
    g_error_free (error);
    g_free (payload);
    return 0;
  }
  g_assert (stride == 0 || stride >= row);
  GBytes *packed = ds_pixfmt_pack (fmt, img, stride, &error);
  g_assert (packed != NULL);
  gsize pn;
  const void *pp = g_bytes_get_data (packed, &pn);
  DsImage *back = ds_pixfmt_unpack (fmt, pp, pn, width, height, stride, &error);
  g_assert (back != NULL);
  for (guint y = 0; y < height; y++)
    g_assert (memcmp (ds_image_row (img, y), ds_image_row (back, y), width * ds_sample_size (img->type)) == 0);
  ds_image_free (back);
  g_bytes_unref (packed);
  ds_image_free (img);
  g_free (payload);
  return 0;
}
