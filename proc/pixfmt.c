#include "proc/pixfmt.h"

#include "proc/pixfmt_internal.h"
#include "proc/proc_error.h"

#include <string.h>

static const struct {
  const char *name;
  guint32 pfnc;
  guint depth;   /* significant bits */
  guint bits;    /* bits occupied in the payload */
} formats[DS_PIXFMT_COUNT] = {
  [DS_PIXFMT_MONO8] = { "Mono8", 0x01080001u, 8, 8 },
  [DS_PIXFMT_MONO10] = { "Mono10", 0x01100003u, 10, 16 },
  [DS_PIXFMT_MONO12] = { "Mono12", 0x01100005u, 12, 16 },
  [DS_PIXFMT_MONO16] = { "Mono16", 0x01100007u, 16, 16 },
  [DS_PIXFMT_MONO10P] = { "Mono10p", 0x010A0046u, 10, 10 },
  [DS_PIXFMT_MONO12P] = { "Mono12p", 0x010C0047u, 12, 12 },
  [DS_PIXFMT_MONO12PACKED] = { "Mono12Packed", 0x010C0006u, 12, 12 },
};

static gboolean
valid_format (DsPixelFormat fmt)
{
  return (int) fmt >= 0 && (int) fmt < DS_PIXFMT_COUNT;
}

const char *
ds_pixfmt_name (DsPixelFormat fmt)
{
  return valid_format (fmt) ? formats[fmt].name : "invalid";
}

gboolean
ds_pixfmt_from_name (const char *name, DsPixelFormat *out)
{
  if (!name)
    return FALSE;
  for (int i = 0; i < DS_PIXFMT_COUNT; i++)
    if (g_ascii_strcasecmp (name, formats[i].name) == 0) {
      *out = (DsPixelFormat) i;
      return TRUE;
    }
  return FALSE;
}

guint32
ds_pixfmt_to_pfnc (DsPixelFormat fmt)
{
  return valid_format (fmt) ? formats[fmt].pfnc : 0;
}

gboolean
ds_pixfmt_from_pfnc (guint32 code, DsPixelFormat *out)
{
  for (int i = 0; i < DS_PIXFMT_COUNT; i++)
    if (formats[i].pfnc == code) {
      *out = (DsPixelFormat) i;
      return TRUE;
    }
  return FALSE;
}

guint
ds_pixfmt_bit_depth (DsPixelFormat fmt)
{
  return valid_format (fmt) ? formats[fmt].depth : 0;
}

DsSampleType
ds_pixfmt_sample_type (DsPixelFormat fmt)
{
  return fmt == DS_PIXFMT_MONO8 ? DS_SAMPLE_U8 : DS_SAMPLE_U16;
}

guint
ds_pixfmt_bits_per_pixel (DsPixelFormat fmt)
{
  return valid_format (fmt) ? formats[fmt].bits : 0;
}

gsize
ds_pixfmt_row_bytes (DsPixelFormat fmt, guint width)
{
  if (!valid_format (fmt))
    return 0;
  return ((gsize) width * formats[fmt].bits + 7u) / 8u;
}

gsize
ds_pixfmt_image_bytes (DsPixelFormat fmt, guint width, guint height, gsize stride)
{
  if (!valid_format (fmt) || width == 0 || height == 0 || width > DS_IMAGE_MAX_SIDE ||
      height > DS_IMAGE_MAX_SIDE)
    return 0;
  gsize row = ds_pixfmt_row_bytes (fmt, width);
  if (stride == 0) {
    /* width, height <= 2^16 and bits <= 16: the bit count fits in 64 bits. */
    guint64 bits = (guint64) width * height * formats[fmt].bits;
    return (gsize) ((bits + 7u) / 8u);
  }
  if (stride < row)
    return 0;
  gsize total;
  if (!g_size_checked_mul (&total, stride, height - 1) || !g_size_checked_add (&total, total, row))
    return 0;
  return total;
}

gsize
ds_pixfmt_check_geometry (DsPixelFormat fmt, guint width, guint height, gsize stride, GError **error)
{
  if (!valid_format (fmt)) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_FORMAT, "unknown pixel format %d", (int) fmt);
    return 0;
  }
  if (width == 0 || height == 0 || width > DS_IMAGE_MAX_SIDE || height > DS_IMAGE_MAX_SIDE) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_INVALID_ARGUMENT,
                 "%s image of %ux%u: each side must be 1..%u", formats[fmt].name, width, height,
                 DS_IMAGE_MAX_SIDE);
    return 0;
  }
  gsize row = ds_pixfmt_row_bytes (fmt, width);
  if (stride != 0 && stride < row) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_INVALID_ARGUMENT,
                 "%s stride %zu is smaller than a row of %u pixels (%zu bytes)", formats[fmt].name,
                 stride, width, row);
    return 0;
  }
  gsize need = ds_pixfmt_image_bytes (fmt, width, height, stride);
  if (need == 0)
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_TOO_LARGE,
                 "%s image of %ux%u with stride %zu overflows", formats[fmt].name, width, height, stride);
  return need;
}

static inline void
write_bits (guint8 *p, guint64 bit, guint d, guint value)
{
  guint8 *b = p + (bit >> 3);
  guint shift = (guint) (bit & 7u);
  guint nbytes = (shift + d + 7u) >> 3;
  guint32 v = (guint32) value << shift;
  for (guint i = 0; i < nbytes; i++)
    b[i] |= (guint8) (v >> (8u * i));
}

static inline void
write_mono12packed (guint8 *p, guint64 q, guint value)
{
  guint8 *b = p + (q >> 1) * 3u;
  if ((q & 1u) == 0) {
    b[0] = (guint8) (value >> 4);
    b[1] = (guint8) ((b[1] & 0xF0u) | (value & 0x0Fu));
  } else {
    b[2] = (guint8) (value >> 4);
    b[1] = (guint8) ((b[1] & 0x0Fu) | ((value & 0x0Fu) << 4));
  }
}

DsImage *
ds_pixfmt_unpack (DsPixelFormat fmt, const void *data, gsize size, guint width, guint height,
                  gsize stride, GError **error)
{
  if (!ds_pixfmt_check_payload (fmt, data, size, width, height, stride, error))
    return NULL;
  g_autoptr (DsImage) img = ds_image_new (ds_pixfmt_sample_type (fmt), width, height, error);
  if (!img || !ds_pixfmt_unpack_into (fmt, data, size, stride, img, error))
    return NULL;
  return g_steal_pointer (&img);
}

GBytes *
ds_pixfmt_pack (DsPixelFormat fmt, const DsImage *image, gsize stride, GError **error)
{
  if (!image) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_INVALID_ARGUMENT, "no image to pack");
    return NULL;
  }
  gsize need = ds_pixfmt_check_geometry (fmt, image->width, image->height, stride, error);
  if (need == 0)
    return NULL;
  DsSampleType want = fmt == DS_PIXFMT_MONO8 ? DS_SAMPLE_U8 : DS_SAMPLE_U16;
  if (image->type != want) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_FORMAT, "%s needs %s samples, the image has %s",
                 formats[fmt].name, ds_sample_type_name (want), ds_sample_type_name (image->type));
    return NULL;
  }
  const guint d = formats[fmt].depth;
  const guint w = image->width;
  guint8 *dst = g_try_malloc0 (need);
  if (!dst) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_TOO_LARGE, "cannot allocate %zu bytes", need);
    return NULL;
  }
  for (guint y = 0; y < image->height; y++) {
    guint64 first = stride ? 0 : (guint64) y * w;
    guint8 *row = stride ? dst + (gsize) y * stride : dst;
    if (fmt == DS_PIXFMT_MONO8) {
      memcpy (row + first, ds_image_row (image, y), w);
      continue;
    }
    const guint16 *in = ds_image_row (image, y);
    for (guint x = 0; x < w; x++) {
      if (d < 16 && (in[x] >> d) != 0) {
        g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_FORMAT,
                     "pixel (%u, %u) = %u does not fit %s (%u bits)", x, y, in[x], formats[fmt].name, d);
        g_free (dst);
        return NULL;
      }
      guint64 q = first + x;
      switch (fmt) {
      case DS_PIXFMT_MONO10:
      case DS_PIXFMT_MONO12:
      case DS_PIXFMT_MONO16:
        row[2 * q] = (guint8) (in[x] & 0xFFu);
        row[2 * q + 1] = (guint8) (in[x] >> 8);
        break;
      case DS_PIXFMT_MONO10P:
      case DS_PIXFMT_MONO12P:
        write_bits (row, q * d, d, in[x]);
        break;
      case DS_PIXFMT_MONO12PACKED:
        write_mono12packed (row, q, in[x]);
        break;
      case DS_PIXFMT_MONO8:
        break;
      }
    }
  }
  return g_bytes_new_take (dst, need);
}
