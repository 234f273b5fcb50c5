#include "daemon/output/tiff_file.h"

#include <glib/gstdio.h>
#include <math.h>
#include <stdio.h>
#include <tiffio.h>

#include "build_info.h"
#include "daemon/output/atomic_file.h"
#include "daemon/output/output_error.h"

/* The first libtiff message about this file, kept for the GError. */
typedef struct {
  char message[256];
} TiffErrors;

static int
on_tiff_error (TIFF *tif, void *user_data, const char *module, const char *fmt, va_list ap)
{
  (void) tif;
  TiffErrors *e = user_data;
  if (e && !e->message[0]) {
    char text[200];
    vsnprintf (text, sizeof text, fmt, ap);
    g_snprintf (e->message, sizeof e->message, "%s%s%s", module ? module : "", module ? ": " : "", text);
  }
  return 1; /* handled: the global handler (stderr) stays silent */
}

static TIFF *
open_tiff (const char *path, const char *mode, TiffErrors *errors)
{
  TIFFOpenOptions *opts = TIFFOpenOptionsAlloc ();
  TIFFOpenOptionsSetErrorHandlerExtR (opts, on_tiff_error, errors);
  TIFFOpenOptionsSetWarningHandlerExtR (opts, on_tiff_error, NULL);
  TIFF *tif = TIFFOpenExt (path, mode, opts);
  TIFFOpenOptionsFree (opts);
  return tif;
}

static gboolean
tiff_failed (GError **error, const char *path, const TiffErrors *errors, const char *what)
{
  g_set_error (error, DS_OUTPUT_ERROR, DS_OUTPUT_ERROR_IO, "%s: %s%s%s", path, what,
               errors->message[0] ? ": " : "", errors->message);
  return FALSE;
}

static gboolean
write_tiff_file (const DsImage *img, const char *tmp, const char *path, const DsTiffTags *tags,
                 GError **error)
{
  TiffErrors errors = { { 0 } };
  TIFF *tif = open_tiff (tmp, "w", &errors);
  if (!tif)
    return tiff_failed (error, path, &errors, "cannot create");
  guint bits = (guint) ds_sample_size (img->type) * 8;
  g_autofree char *software = tags && tags->software ? g_strdup (tags->software)
                                                     : g_strdup ("descatter " DS_VERSION " (" DS_GIT_DESCRIBE ")");
  g_autoptr (GDateTime) now = g_date_time_new_now_utc ();
  g_autoptr (GDateTime) utc = g_date_time_to_utc (tags && tags->time ? tags->time : now);
  g_autofree char *stamp = g_date_time_format (utc, "%Y:%m:%d %H:%M:%S");
  /* About 64 KiB per strip: small enough for any reader's buffers, few enough strips. */
  gsize row_bytes = (gsize) img->width * ds_sample_size (img->type);
  guint32 rows_per_strip = (guint32) MAX (1, MIN ((gsize) img->height, 65536 / MAX (row_bytes, 1)));
  gboolean ok = TIFFSetField (tif, TIFFTAG_IMAGEWIDTH, (guint32) img->width) &&
                TIFFSetField (tif, TIFFTAG_IMAGELENGTH, (guint32) img->height) &&
                TIFFSetField (tif, TIFFTAG_SAMPLESPERPIXEL, 1) &&
                TIFFSetField (tif, TIFFTAG_BITSPERSAMPLE, bits) &&
                TIFFSetField (tif, TIFFTAG_SAMPLEFORMAT,
                              img->type == DS_SAMPLE_F32 ? SAMPLEFORMAT_IEEEFP : SAMPLEFORMAT_UINT) &&
                TIFFSetField (tif, TIFFTAG_PHOTOMETRIC, PHOTOMETRIC_MINISBLACK) &&
                TIFFSetField (tif, TIFFTAG_PLANARCONFIG, PLANARCONFIG_CONTIG) &&
                TIFFSetField (tif, TIFFTAG_COMPRESSION, COMPRESSION_NONE) &&
                TIFFSetField (tif, TIFFTAG_ROWSPERSTRIP, rows_per_strip) &&
                TIFFSetField (tif, TIFFTAG_SOFTWARE, software) &&
                TIFFSetField (tif, TIFFTAG_DATETIME, stamp) &&
                (!tags || !tags->description || TIFFSetField (tif, TIFFTAG_IMAGEDESCRIPTION, tags->description)) &&
                (!tags || !tags->document_name || TIFFSetField (tif, TIFFTAG_DOCUMENTNAME, tags->document_name));
  /* The physical scale, as ImageJ, napari (tifffile) and GIMP read it: pixels per centimetre. */
  if (ok && tags && isfinite (tags->pixel_size_um) && tags->pixel_size_um > 0) {
    float per_cm = (float) (1e4 / tags->pixel_size_um);
    ok = TIFFSetField (tif, TIFFTAG_RESOLUTIONUNIT, RESUNIT_CENTIMETER) &&
         TIFFSetField (tif, TIFFTAG_XRESOLUTION, per_cm) && TIFFSetField (tif, TIFFTAG_YRESOLUTION, per_cm);
  }
  /* Integer images that use fewer bits say so (a 12-bit frame in 16-bit samples). */
  if (ok && img->type != DS_SAMPLE_F32 && img->bit_depth < bits)
    ok = TIFFSetField (tif, TIFFTAG_MAXSAMPLEVALUE, (guint16) ((1u << img->bit_depth) - 1));
  for (guint y = 0; ok && y < img->height; y++)
    ok = TIFFWriteScanline (tif, ds_image_row (img, y), y, 0) == 1;
  if (ok)
    ok = TIFFWriteDirectory (tif) == 1;
  TIFFClose (tif);
  if (!ok)
    return tiff_failed (error, path, &errors, "writing failed");
  return TRUE;
}

gboolean
ds_tiff_write (const DsImage *img, const char *path, const DsTiffTags *tags, GError **error)
{
  g_autofree char *tmp = ds_atomic_temp_path (path);
  if (!write_tiff_file (img, tmp, path, tags, error)) {
    g_unlink (tmp);
    return FALSE;
  }
  return ds_atomic_commit (tmp, path, error);
}

char *
ds_tiff_read_description (const char *path, GError **error)
{
  TiffErrors errors = { { 0 } };
  TIFF *tif = open_tiff (path, "r", &errors);
  if (!tif) {
    tiff_failed (error, path, &errors, "cannot open");
    return NULL;
  }
  char *text = NULL;
  char *out = NULL;
  if (TIFFGetField (tif, TIFFTAG_IMAGEDESCRIPTION, &text) == 1 && text)
    out = g_strdup (text);
  TIFFClose (tif);
  if (!out)
    g_set_error (error, DS_OUTPUT_ERROR, DS_OUTPUT_ERROR_INVALID, "%s: no ImageDescription", path);
  return out;
}
