/* Pixel formats to images: unpacking row by row into an image the caller provides (a pooled
 * frame: no allocation per frame), and views of payloads that need no unpacking. The group
 * loops (2 pixels in 3 bytes, 4 in 5) are written for the auto-vectoriser (proc/CMakeLists.txt)
 * and built for AVX2 and AVX-512 as well; the odd pixels at the ends of a row whose bitstream
 * does not start on a byte go through the bit reader. */
#include <string.h>

#include "proc/pixfmt.h"
#include "proc/pixfmt_internal.h"
#include "proc/proc_error.h"
#include "proc/simd.h"

/* One d-bit pixel starting at bit offset `bit` of an LSB-first bitstream; reads only the bytes
 * holding its bits. */
static inline guint
read_bits (const guint8 *p, guint64 bit, guint d)
{
  const guint8 *b = p + (bit >> 3);
  guint shift = (guint) (bit & 7u);
  guint nbytes = (shift + d + 7u) >> 3;
  guint32 v = 0;
  for (guint i = 0; i < nbytes; i++)
    v |= (guint32) b[i] << (8u * i);
  return (v >> shift) & ((1u << d) - 1u);
}

/* Mono12Packed pixel q of a run of pairs starting at p. */
static inline guint
read_mono12packed (const guint8 *p, guint64 q)
{
  const guint8 *b = p + (q >> 1) * 3u;
  if ((q & 1u) == 0)
    return ((guint) b[0] << 4) | (b[1] & 0x0Fu);
  return ((guint) b[2] << 4) | (b[1] >> 4);
}

DS_KERNEL void
pairs_12p (const guint8 *restrict b, guint16 *restrict out, gsize pairs)
{
  for (gsize i = 0; i < pairs; i++) {
    const guint8 *p = b + 3 * i;
    out[2 * i] = (guint16) (p[0] | ((p[1] & 0x0Fu) << 8));
    out[2 * i + 1] = (guint16) ((p[1] >> 4) | ((guint) p[2] << 4));
  }
}

DS_KERNEL void
pairs_12packed (const guint8 *restrict b, guint16 *restrict out, gsize pairs)
{
  for (gsize i = 0; i < pairs; i++) {
    const guint8 *p = b + 3 * i;
    out[2 * i] = (guint16) (((guint) p[0] << 4) | (p[1] & 0x0Fu));
    out[2 * i + 1] = (guint16) (((guint) p[2] << 4) | (p[1] >> 4));
  }
}

DS_KERNEL void
quads_10p (const guint8 *restrict b, guint16 *restrict out, gsize quads)
{
  for (gsize i = 0; i < quads; i++) {
    const guint8 *p = b + 5 * i;
    out[4 * i] = (guint16) (p[0] | ((p[1] & 0x03u) << 8));
    out[4 * i + 1] = (guint16) ((p[1] >> 2) | ((p[2] & 0x0Fu) << 6));
    out[4 * i + 2] = (guint16) ((p[2] >> 4) | ((p[3] & 0x3Fu) << 4));
    out[4 * i + 3] = (guint16) ((p[3] >> 6) | ((guint) p[4] << 2));
  }
}

/* Pixels [0, width) of an LSB-first d-bit bitstream (Mono12p: d = 12, pairs in 3 bytes;
 * Mono10p: d = 10, quads in 5 bytes) whose first pixel is pixel `first`: the bit reader up to
 * the first pixel that starts on a byte, the group loop, the bit reader for the rest. Inlined
 * with a constant d, so each format gets its own straight code as if written out. */
DS_KERNEL void
unpack_bitstream (const guint8 *row, guint64 first, guint width, guint d, guint16 *out)
{
  guint64 bit = first * d;
  guint x = 0;
  for (; x < width && ((bit + (guint64) x * d) & 7u) != 0; x++)
    out[x] = (guint16) read_bits (row, bit + (guint64) x * d, d);
  const guint8 *groups_start = row + ((bit + (guint64) x * d) >> 3);
  if (d == 12) {
    gsize pairs = (width - x) / 2;
    pairs_12p (groups_start, out + x, pairs);
    x += (guint) (2 * pairs);
  } else {
    gsize quads = (width - x) / 4;
    quads_10p (groups_start, out + x, quads);
    x += (guint) (4 * quads);
  }
  for (; x < width; x++)
    out[x] = (guint16) read_bits (row, bit + (guint64) x * d, d);
}

/* Little-endian 16-bit words: the host's layout on every platform we build for. */
DS_KERNEL guint
words_16 (const guint8 *restrict b, guint16 *restrict out, gsize w)
{
  guint over = 0;
#if G_BYTE_ORDER == G_LITTLE_ENDIAN
  memcpy (out, b, w * 2);
  for (gsize x = 0; x < w; x++)
    over |= out[x];
#else
  for (gsize x = 0; x < w; x++) {
    out[x] = (guint16) (b[2 * x] | ((guint) b[2 * x + 1] << 8));
    over |= out[x];
  }
#endif
  return over;
}

/* Pixels [0, width) of a row whose first pixel is pixel `first` of the payload's stream
 * (stride 0), or of a row that starts fresh at `row` (first = 0). Returns the OR of the
 * 16-bit words (Mono10/12/16) for the depth check, else 0. */
DS_CLONES_WIDE guint
ds_pixfmt_unpack_row (DsPixelFormat fmt, const guint8 *row, guint64 first, guint width, void *dst)
{
  guint16 *out = dst;
  guint x = 0;
  switch (fmt) {
  case DS_PIXFMT_MONO8:
    memcpy (dst, row + first, width);
    return 0;
  case DS_PIXFMT_MONO10:
  case DS_PIXFMT_MONO12:
  case DS_PIXFMT_MONO16:
    return words_16 (row + first * 2u, out, width);
  case DS_PIXFMT_MONO12P:
    unpack_bitstream (row, first, width, 12, out);
    return 0;
  case DS_PIXFMT_MONO10P:
    unpack_bitstream (row, first, width, 10, out);
    return 0;
  case DS_PIXFMT_MONO12PACKED: {
    /* an odd first pixel is the second of a pair */
    for (; x < width && ((first + x) & 1u) != 0; x++)
      out[x] = (guint16) read_mono12packed (row, first + x);
    gsize pairs = (width - x) / 2;
    pairs_12packed (row + ((first + x) >> 1) * 3u, out + x, pairs);
    x += (guint) (2 * pairs);
    for (; x < width; x++)
      out[x] = (guint16) read_mono12packed (row, first + x);
    return 0;
  }
  }
  return 0;
}

gboolean
ds_pixfmt_check_payload (DsPixelFormat fmt, const void *data, gsize size, guint width, guint height,
                         gsize stride, GError **error)
{
  gsize need = ds_pixfmt_check_geometry (fmt, width, height, stride, error);
  if (need == 0)
    return FALSE;
  if (!data || size < need) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_SIZE_MISMATCH,
                 "%s %ux%u (stride %zu) needs %zu bytes, got %zu", ds_pixfmt_name (fmt), width, height,
                 stride, need, data ? size : 0);
    return FALSE;
  }
  return TRUE;
}

gboolean
ds_pixfmt_unpack_into (DsPixelFormat fmt, const void *data, gsize size, gsize stride, DsImage *dst,
                       GError **error)
{
  if (!dst) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_INVALID_ARGUMENT, "%s: no image to unpack into",
                 ds_pixfmt_name (fmt));
    return FALSE;
  }
  guint width = dst->width, height = dst->height;
  if (!ds_pixfmt_check_payload (fmt, data, size, width, height, stride, error))
    return FALSE;
  DsSampleType type = fmt == DS_PIXFMT_MONO8 ? DS_SAMPLE_U8 : DS_SAMPLE_U16;
  if (dst->type != type) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_INVALID_ARGUMENT,
                 "%s unpacks to %s samples, the image has %s", ds_pixfmt_name (fmt),
                 ds_sample_type_name (type), ds_sample_type_name (dst->type));
    return FALSE;
  }
  const guint8 *src = data;
  const guint d = ds_pixfmt_bit_depth (fmt);
  for (guint y = 0; y < height; y++) {
    /* stride 0: one continuous bitstream, row y starts at pixel y * width of it */
    const guint8 *row = stride ? src + (gsize) y * stride : src;
    guint64 first = stride ? 0 : (guint64) y * width;
    guint over = ds_pixfmt_unpack_row (fmt, row, first, width, ds_image_row (dst, y));
    if (d < 16 && (over >> d) != 0) {
      const guint16 *out = ds_image_row (dst, y);
      for (guint x = 0; x < width; x++)
        if (out[x] >> d) {
          g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_FORMAT,
                       "%s pixel (%u, %u) is 0x%04x: bits above bit %u are set", ds_pixfmt_name (fmt),
                       x, y, out[x], d - 1);
          return FALSE;
        }
    }
  }
  dst->bit_depth = d;
  return TRUE;
}

gboolean
ds_pixfmt_viewable (DsPixelFormat fmt, const void *data, gsize stride)
{
  if (fmt == DS_PIXFMT_MONO8)
    return data != NULL;
  return fmt == DS_PIXFMT_MONO16 && G_BYTE_ORDER == G_LITTLE_ENDIAN && data &&
         ((guintptr) data % 2) == 0 && stride % 2 == 0;
}

gboolean
ds_pixfmt_view (DsPixelFormat fmt, const void *data, gsize size, guint width, guint height,
                gsize stride, DsImage *view, GError **error)
{
  if (!ds_pixfmt_check_payload (fmt, data, size, width, height, stride, error))
    return FALSE;
  if (!ds_pixfmt_viewable (fmt, data, stride)) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_FORMAT,
                 "%s payload at %p with stride %zu cannot be viewed in place (only Mono8, and "
                 "Mono16 on 2-byte boundaries, can): unpack it",
                 ds_pixfmt_name (fmt), data, stride);
    return FALSE;
  }
  DsSampleType type = fmt == DS_PIXFMT_MONO8 ? DS_SAMPLE_U8 : DS_SAMPLE_U16;
  gsize row_stride = stride ? stride : ds_pixfmt_row_bytes (fmt, width);
  return ds_image_view_init (view, type, ds_pixfmt_bit_depth (fmt), width, height, row_stride, data,
                             size, error);
}
