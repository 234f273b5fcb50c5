#include "proc/image.h"

#include "proc/cv_bridge.h"
#include "proc/proc_error.h"

#include <errno.h>
#include <fcntl.h>
#include <glib/gstdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

gsize
ds_sample_size (DsSampleType type)
{
  switch (type) {
  case DS_SAMPLE_U8: return 1;
  case DS_SAMPLE_U16: return 2;
  case DS_SAMPLE_F32: return 4;
  }
  return 0;
}

const char *
ds_sample_type_name (DsSampleType type)
{
  switch (type) {
  case DS_SAMPLE_U8: return "u8";
  case DS_SAMPLE_U16: return "u16";
  case DS_SAMPLE_F32: return "f32";
  }
  return "invalid";
}

static guint
full_depth (DsSampleType type)
{
  return type == DS_SAMPLE_F32 ? 32 : (guint) ds_sample_size (type) * 8;
}

DsImage *
ds_image_new_with_stride (DsSampleType type, guint width, guint height, gsize stride,
                          GError **error)
{
  gsize ss = ds_sample_size (type);
  if (ss == 0) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_FORMAT, "invalid sample type %d", (int) type);
    return NULL;
  }
  if (width == 0 || height == 0 || width > DS_IMAGE_MAX_SIDE || height > DS_IMAGE_MAX_SIDE) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_INVALID_ARGUMENT,
                 "image size %ux%u outside 1..%u on each side", width, height, DS_IMAGE_MAX_SIDE);
    return NULL;
  }
  if (stride < (gsize) width * ss) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_INVALID_ARGUMENT,
                 "stride %zu is smaller than a row of %u %s samples", stride, width,
                 ds_sample_type_name (type));
    return NULL;
  }
  gsize bytes;
  if (!g_size_checked_mul (&bytes, stride, height)) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_TOO_LARGE, "image of %ux%u with stride %zu overflows",
                 width, height, stride);
    return NULL;
  }
  DsImage *img = g_new0 (DsImage, 1);
  img->width = width;
  img->height = height;
  img->stride = stride;
  img->type = type;
  img->bit_depth = full_depth (type);
  /* 64-byte alignment (as image.h promises) lets row loops vectorise on aligned loads.
   * calloc rather than memalign + memset: large blocks come zeroed from fresh pages that are
   * not touched until used, so callers can still ask for huge pages before the first write.
   * A failed allocation of a huge image is an error, not an abort. */
  gsize padded;
  if (g_size_checked_add (&padded, bytes, 64) && (img->allocation = calloc (1, padded)))
    img->data = (guint8 *) (((guintptr) img->allocation + 63) & ~(guintptr) 63);
  if (!img->data) {
    g_free (img);
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_TOO_LARGE, "cannot allocate %zu bytes for a %ux%u image",
                 bytes, width, height);
    return NULL;
  }
  return img;
}

DsImage *
ds_image_new (DsSampleType type, guint width, guint height, GError **error)
{
  gsize ss = ds_sample_size (type);
  /* Rows start on 64-byte boundaries so that vectorized loops never straddle cache lines. */
  gsize stride = ((gsize) width * (ss ? ss : 1) + 63u) & ~(gsize) 63u;
  return ds_image_new_with_stride (type, width, height, stride, error);
}

DsImage *
ds_image_copy (const DsImage *src, GError **error)
{
  DsImage *dst = ds_image_new_with_stride (src->type, src->width, src->height, src->stride, error);
  if (!dst)
    return NULL;
  dst->bit_depth = src->bit_depth;
  memcpy (dst->data, src->data, src->stride * src->height);
  return dst;
}

gboolean
ds_image_view_init (DsImage *view, DsSampleType type, guint bit_depth, guint width, guint height,
                    gsize stride, const void *data, gsize size, GError **error)
{
  gsize ss = ds_sample_size (type);
  if (ss == 0) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_INVALID_ARGUMENT, "image view: invalid sample type %d",
                 (int) type);
    return FALSE;
  }
  if (bit_depth == 0)
    bit_depth = full_depth (type);
  gboolean depth_ok = type == DS_SAMPLE_F32 ? bit_depth == 32 : bit_depth <= full_depth (type);
  if (!depth_ok) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_INVALID_ARGUMENT, "image view: bit depth %u does not fit %s samples",
                 bit_depth, ds_sample_type_name (type));
    return FALSE;
  }
  if (width == 0 || height == 0 || width > DS_IMAGE_MAX_SIDE || height > DS_IMAGE_MAX_SIDE) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_INVALID_ARGUMENT,
                 "image view of %ux%u: each side must be 1..%u", width, height, DS_IMAGE_MAX_SIDE);
    return FALSE;
  }
  gsize row = (gsize) width * ss;
  if (stride < row || stride % ss != 0) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_INVALID_ARGUMENT,
                 "image view: stride %zu is not a multiple of %zu bytes at least a row of %u %s samples",
                 stride, ss, width, ds_sample_type_name (type));
    return FALSE;
  }
  if (!data || ((guintptr) data % ss) != 0) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_INVALID_ARGUMENT,
                 "image view: data at %p is not aligned to its %zu-byte samples", data, ss);
    return FALSE;
  }
  gsize need;
  if (!g_size_checked_mul (&need, stride, height - 1) || !g_size_checked_add (&need, need, row) || size < need) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_SIZE_MISMATCH,
                 "image view of %ux%u %s with stride %zu needs %zu bytes, got %zu", width, height,
                 ds_sample_type_name (type), stride, need, size);
    return FALSE;
  }
  *view = (DsImage) {
    .width = width, .height = height, .stride = stride, .type = type, .bit_depth = bit_depth,
    .data = (guint8 *) data, .allocation = NULL,
  };
  return TRUE;
}

DsImage *
ds_image_new_view (DsSampleType type, guint bit_depth, guint width, guint height, gsize stride,
                   const void *data, gsize size, GError **error)
{
  DsImage view;
  if (!ds_image_view_init (&view, type, bit_depth, width, height, stride, data, size, error))
    return NULL;
  return g_memdup2 (&view, sizeof view);
}

void
ds_image_free (DsImage *image)
{
  if (!image)
    return;
  free (image->allocation);
  g_free (image);
}

GBytes *
ds_image_to_packed_bytes (const DsImage *image)
{
  gsize row = (gsize) image->width * ds_sample_size (image->type);
  if (row == image->stride)
    return g_bytes_new (image->data, row * image->height);
  guint8 *buf = g_malloc (row * image->height);
  for (guint y = 0; y < image->height; y++)
    memcpy (buf + y * row, ds_image_row (image, y), row);
  return g_bytes_new_take (buf, row * image->height);
}

DsImage *
ds_image_convert_f32_clamped (const DsImage *src, DsSampleType to, double max_value, GError **error)
{
  double type_max = to == DS_SAMPLE_U8 ? 255.0 : 65535.0;
  if (src->type != DS_SAMPLE_F32 || (to != DS_SAMPLE_U8 && to != DS_SAMPLE_U16) || !(max_value >= 1.0) ||
      max_value > type_max) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_INVALID_ARGUMENT,
                 "conversion from %s to %s with maximum %g is not supported", ds_sample_type_name (src->type),
                 ds_sample_type_name (to), max_value);
    return NULL;
  }
  DsImage *dst = ds_image_new (to, src->width, src->height, error);
  if (!dst)
    return NULL;
  guint bits = 1;
  while (bits < 16 && (double) ((1u << bits) - 1) < max_value)
    bits++;
  dst->bit_depth = bits;
  const float top = (float) max_value;
  for (guint y = 0; y < src->height; y++) {
    const float *in = ds_image_row (src, y);
    if (to == DS_SAMPLE_U8) {
      guint8 *out = ds_image_row (dst, y);
      for (guint x = 0; x < src->width; x++) {
        float v = in[x] > 0.0f ? in[x] : 0.0f; /* also maps NaN to 0: comparisons with NaN fail */
        out[x] = (guint8) (v < top ? v + 0.5f : top);
      }
    } else {
      guint16 *out = ds_image_row (dst, y);
      for (guint x = 0; x < src->width; x++) {
        float v = in[x] > 0.0f ? in[x] : 0.0f;
        out[x] = (guint16) (v < top ? v + 0.5f : top);
      }
    }
  }
  return dst;
}

gboolean
ds_image_same_shape (const DsImage *a, const DsImage *b)
{
  return a->width == b->width && a->height == b->height && a->type == b->type;
}

DsImage *
ds_image_read (const char *path, GError **error)
{
  if (!g_file_test (path, G_FILE_TEST_IS_REGULAR)) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_IO, "%s: no such file", path);
    return NULL;
  }
  int w = 0, h = 0, t = 0;
  void *data = NULL;
  char err[256];
  if (ds_cv_imread (path, &w, &h, &t, &data, err, sizeof err) != 0) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_FORMAT, "%s: %s", path, err);
    return NULL;
  }
  DsSampleType type = t == DS_CV_U8 ? DS_SAMPLE_U8 : t == DS_CV_U16 ? DS_SAMPLE_U16 : DS_SAMPLE_F32;
  GError *local = NULL;
  DsImage *img = ds_image_new (type, (guint) w, (guint) h, &local);
  if (!img) {
    free (data);
    g_propagate_prefixed_error (error, local, "%s: ", path);
    return NULL;
  }
  gsize row = (gsize) w * ds_sample_size (type);
  for (guint y = 0; y < img->height; y++)
    memcpy (ds_image_row (img, y), (guint8 *) data + y * row, row);
  free (data);
  return img;
}

static gboolean
extension_allows (const char *path, DsSampleType type)
{
  const char *dot = strrchr (path, '.');
  if (!dot)
    return FALSE;
  if (g_ascii_strcasecmp (dot, ".png") == 0)
    return type != DS_SAMPLE_F32;
  if (g_ascii_strcasecmp (dot, ".tif") == 0 || g_ascii_strcasecmp (dot, ".tiff") == 0)
    return TRUE;
  return FALSE;
}

static gboolean
fsync_path (const char *path, int flags, GError **error)
{
  int fd = open (path, flags | O_CLOEXEC);
  if (fd < 0 || fsync (fd) != 0) {
    int e = errno;
    if (fd >= 0)
      close (fd);
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_IO, "%s: fsync failed: %s", path, g_strerror (e));
    return FALSE;
  }
  close (fd);
  return TRUE;
}

gboolean
ds_image_write (const DsImage *image, const char *path, GError **error)
{
  if (!extension_allows (path, image->type)) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_FORMAT,
                 "%s: cannot store %s samples there (use .png for u8/u16, .tif/.tiff for any)", path,
                 ds_sample_type_name (image->type));
    return FALSE;
  }
  /* The temporary name keeps the real extension: OpenCV picks the encoder from it. */
  g_autofree char *dir = g_path_get_dirname (path);
  g_autofree char *base = g_path_get_basename (path);
  const char *ext = strrchr (base, '.');
  g_autofree char *tmp = g_strdup_printf ("%s/.%.*s.tmp-%d-%u%s", dir, (int) (ext - base), base,
                                          (int) getpid (), g_random_int (), ext);
  DsCvView view = {
    .width = (int) image->width,
    .height = (int) image->height,
    .type = image->type == DS_SAMPLE_U8 ? DS_CV_U8 : image->type == DS_SAMPLE_U16 ? DS_CV_U16 : DS_CV_F32,
    .stride = image->stride,
    .data = image->data,
  };
  char err[256];
  if (ds_cv_imwrite (tmp, &view, err, sizeof err) != 0) {
    g_unlink (tmp);
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_IO, "%s: %s", path, err);
    return FALSE;
  }
  if (!fsync_path (tmp, O_RDONLY, error)) {
    g_unlink (tmp);
    return FALSE;
  }
  if (g_rename (tmp, path) != 0) {
    int e = errno;
    g_unlink (tmp);
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_IO, "%s: rename failed: %s", path, g_strerror (e));
    return FALSE;
  }
  /* Without syncing the directory the rename itself may be lost in a power cut. */
  return fsync_path (dir, O_RDONLY | O_DIRECTORY, error);
}
