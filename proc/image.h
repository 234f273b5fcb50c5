/* A 2-D single-channel image: the unit of exchange between proc/, the simulator, the drivers
 * and the file system. It owns its pixels, or is a view over pixels someone else owns (a
 * camera buffer, a pooled plane). Rows may be padded (stride >= row bytes) so that frames from
 * a camera can be wrapped without repacking. */
#pragma once
#include <glib.h>
#include <stdint.h>

G_BEGIN_DECLS

typedef enum {
  DS_SAMPLE_U8 = 1,
  DS_SAMPLE_U16 = 2,
  DS_SAMPLE_F32 = 3,
} DsSampleType;

/* Largest side we accept; 8192x8192 float32 is 256 MiB and must still work. */
#define DS_IMAGE_MAX_SIDE 65536u

typedef struct {
  guint width;
  guint height;
  gsize stride;        /* bytes from one row to the next */
  DsSampleType type;
  guint bit_depth;     /* significant bits of integer samples (1..16); 32 for float */
  guint8 *data;        /* owned and 64-byte aligned, or a view's (aligned to the sample) */
  void *allocation;    /* what data points into (freed with the image); NULL for a view */
} DsImage;

gsize ds_sample_size (DsSampleType type);
const char *ds_sample_type_name (DsSampleType type);

/* Zero-filled image with the tightest 64-byte-aligned stride. bit_depth defaults to the
 * full width of the sample type. Fails with DS_PROC_ERROR_TOO_LARGE or INVALID_ARGUMENT. */
DsImage *ds_image_new (DsSampleType type, guint width, guint height, GError **error);
/* As ds_image_new but with an explicit stride (>= width * sample size). */
DsImage *ds_image_new_with_stride (DsSampleType type, guint width, guint height, gsize stride,
                                   GError **error);
DsImage *ds_image_copy (const DsImage *src, GError **error);

/* A view: *view describes `data`, which the caller owns and keeps valid and unchanged while
 * the view is used; nothing is copied. For a DsImage on the stack or inside another struct:
 * never pass it to ds_image_free. bit_depth 0 = the type's full width. Fails INVALID_ARGUMENT
 * (a side outside 1..DS_IMAGE_MAX_SIDE, stride below a row, data not aligned to the sample
 * size, bit depth outside the type), SIZE_MISMATCH (size below (height-1)*stride + a row). */
gboolean ds_image_view_init (DsImage *view, DsSampleType type, guint bit_depth, guint width,
                             guint height, gsize stride, const void *data, gsize size,
                             GError **error);
/* The same on the heap: ds_image_free frees the DsImage, never the pixels. */
DsImage *ds_image_new_view (DsSampleType type, guint bit_depth, guint width, guint height,
                            gsize stride, const void *data, gsize size, GError **error);
static inline gboolean
ds_image_is_view (const DsImage *image)
{
  return image->allocation == NULL;
}
void ds_image_free (DsImage *image);
G_DEFINE_AUTOPTR_CLEANUP_FUNC (DsImage, ds_image_free)

static inline void *
ds_image_row (const DsImage *image, guint y)
{
  return image->data + (gsize) y * image->stride;
}

/* Sample x of a row of `image` as a double, whatever the sample type: for statistics over
 * frames of any depth, not for the hot per-pixel loops (those are written per type). */
static inline double
ds_image_sample (const DsImage *image, const void *row, guint x)
{
  switch (image->type) {
  case DS_SAMPLE_U8:
    return ((const guint8 *) row)[x];
  case DS_SAMPLE_U16:
    return ((const guint16 *) row)[x];
  default:
    return ((const float *) row)[x];
  }
}

/* The pixels with rows packed back to back (no stride padding), little-endian as in memory on
 * the platforms we build for: the wire and file layout of a payload. */
GBytes *ds_image_to_packed_bytes (const DsImage *image);

/* Float to integer samples for files and wire formats that want integers: rounded to nearest,
 * clamped to 0..max_value (<= the type's range), NaN to 0. `to` is DS_SAMPLE_U8 or U16; the
 * result's bit_depth is the bits max_value needs. */
DsImage *ds_image_convert_f32_clamped (const DsImage *src, DsSampleType to, double max_value,
                                       GError **error);

/* TRUE when both have the same width, height and sample type. */
gboolean ds_image_same_shape (const DsImage *a, const DsImage *b);

/* Reads PNG (8/16-bit), TIFF (8/16-bit, float32) and whatever else OpenCV decodes.
 * A colour file whose channels are all equal (grey saved as RGB) is read as grey; a colour
 * file with differing channels is refused (DS_PROC_ERROR_FORMAT) rather than converted,
 * because mixing channels of different spectral response would falsify the separation.
 * bit_depth of a 16-bit file is 16 (PNG carries no narrower depth through OpenCV).
 * The error names the file. */
DsImage *ds_image_read (const char *path, GError **error);

/* Writes by extension (.png for u8/u16, .tif/.tiff for u8/u16/f32). The file appears whole
 * or not at all: written to a temporary file in the same folder, fsynced, then renamed. */
gboolean ds_image_write (const DsImage *image, const char *path, GError **error);

G_END_DECLS
