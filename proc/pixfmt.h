/* Camera pixel formats (monochrome only) and their conversion to and from DsImage.
 *
 * Layouts (GenICam PFNC 2.x and GigE Vision 1.x):
 *   Mono8         one byte per pixel.
 *   Mono10/12/16  one little-endian 16-bit word per pixel; bits above the depth must be 0.
 *   Mono10p/12p   PFNC "p": a bitstream, pixel i occupies bits [i*d, i*d + d) counted from the
 *                 least significant bit of byte 0 (LSB first), d = 10 or 12.
 *   Mono12Packed  GigE Vision legacy: pixels in pairs of 3 bytes; byte 0 = P0[11:4],
 *                 byte 1 = P1[3:0] << 4 | P0[3:0], byte 2 = P1[11:4]. An unpaired last pixel
 *                 takes bytes 0 and 1 of a pair.
 *
 * Rows: stride 0 means every row follows the previous one inside one continuous bitstream (a
 * GigE Vision payload: with odd widths a packed row may start in the middle of a byte or of a
 * Mono12Packed pair). stride > 0 means row r starts at byte r * stride and pixel 0 of every row
 * starts a fresh pair / bitstream; stride must be >= ds_pixfmt_row_bytes (fmt, width).
 *
 * All functions are pure (no state), callable from any thread. */
#pragma once
#include <glib.h>

#include "proc/image.h"

G_BEGIN_DECLS

typedef enum {
  DS_PIXFMT_MONO8 = 0,
  DS_PIXFMT_MONO10,
  DS_PIXFMT_MONO12,
  DS_PIXFMT_MONO16,
  DS_PIXFMT_MONO10P,
  DS_PIXFMT_MONO12P,
  DS_PIXFMT_MONO12PACKED,
} DsPixelFormat;
#define DS_PIXFMT_COUNT 7

/* GenICam name ("Mono8", "Mono10p", "Mono12Packed", ...); "invalid" for out-of-range values. */
const char *ds_pixfmt_name (DsPixelFormat fmt);
/* Exact GenICam name, case-insensitive. FALSE (and *out untouched) when unknown. */
gboolean ds_pixfmt_from_name (const char *name, DsPixelFormat *out);

/* PFNC 32-bit pixel format code as sent in GigE Vision leaders (Mono8 = 0x01080001). */
guint32 ds_pixfmt_to_pfnc (DsPixelFormat fmt);
gboolean ds_pixfmt_from_pfnc (guint32 code, DsPixelFormat *out);

/* Significant bits per pixel: 8, 10, 12 or 16. */
guint ds_pixfmt_bit_depth (DsPixelFormat fmt);
/* The sample type a frame of this format is held in once unpacked: u8 for Mono8, u16 for every
 * other format. */
DsSampleType ds_pixfmt_sample_type (DsPixelFormat fmt);
/* Bits one pixel occupies in the payload: 8, 16, 10 or 12. */
guint ds_pixfmt_bits_per_pixel (DsPixelFormat fmt);
/* Bytes of one row of `width` pixels starting a fresh row (rounded up to whole bytes). */
gsize ds_pixfmt_row_bytes (DsPixelFormat fmt, guint width);
/* Bytes a whole image needs: continuous bitstream when stride == 0, otherwise
 * (height - 1) * stride + row bytes. 0 when the size overflows or the arguments are invalid. */
gsize ds_pixfmt_image_bytes (DsPixelFormat fmt, guint width, guint height, gsize stride);

/* Unpacks a payload into a new image: DS_SAMPLE_U8 for Mono8, DS_SAMPLE_U16 with bit_depth =
 * ds_pixfmt_bit_depth for the others. Bytes after the image are ignored. Fails (DsProcError):
 * FORMAT for an unknown format or a Mono10/12 word with bits above the depth (names the
 * pixel), SIZE_MISMATCH when size is smaller than needed (says expected and got),
 * INVALID_ARGUMENT for a stride below the row size or a zero side, TOO_LARGE on overflow.
 * Never reads past data + size. */
DsImage *ds_pixfmt_unpack (DsPixelFormat fmt, const void *data, gsize size, guint width,
                           guint height, gsize stride, GError **error);

/* As ds_pixfmt_unpack, into an image the caller provides and keeps (a pooled one: no
 * allocation per frame). Its width and height say the frame's; its type must be U8 for Mono8,
 * U16 otherwise (INVALID_ARGUMENT), any stride; bit_depth is set. Rows are unpacked with
 * vectorised group loops. Otherwise the errors of ds_pixfmt_unpack; on error the image's
 * pixels are unspecified. */
gboolean ds_pixfmt_unpack_into (DsPixelFormat fmt, const void *data, gsize size, gsize stride,
                                DsImage *image, GError **error);

/* Mono8 and Mono16 need no unpacking: *view (ds_image_view_init) describes the payload in
 * place, so a frame can be folded straight from the camera's buffer while the caller holds it.
 * Fails FORMAT for the other formats and for Mono16 data or stride not on 2-byte boundaries
 * (unpack those), else as ds_pixfmt_unpack. */
gboolean ds_pixfmt_view (DsPixelFormat fmt, const void *data, gsize size, guint width, guint height,
                         gsize stride, DsImage *view, GError **error);
/* TRUE when ds_pixfmt_view accepts this format, address and stride. */
gboolean ds_pixfmt_viewable (DsPixelFormat fmt, const void *data, gsize stride);

/* The inverse: image (U8 for Mono8, U16 otherwise) to a payload with the given stride
 * (0 = continuous bitstream); padding bytes and unused bits are 0. Fails FORMAT when the
 * sample type does not fit the format or a value does not fit the depth (names the pixel). */
GBytes *ds_pixfmt_pack (DsPixelFormat fmt, const DsImage *image, gsize stride, GError **error);

G_END_DECLS
