#include "daemon/output/png_file.h"

#include <errno.h>
#include <glib/gstdio.h>
#include <png.h>
#include <setjmp.h>
#include <stdio.h>

#include "daemon/output/atomic_file.h"
#include "daemon/output/output_error.h"

/* The first libpng message about this file, kept for the GError. */
typedef struct {
  char message[200];
} PngErrors;

static void
on_png_error (png_structp png, png_const_charp msg)
{
  PngErrors *e = png_get_error_ptr (png);
  if (!e->message[0])
    g_strlcpy (e->message, msg, sizeof e->message);
  png_longjmp (png, 1);
}

static void
on_png_warning (png_structp png, png_const_charp msg)
{
  (void) png;
  (void) msg; /* warnings (e.g. a text chunk's keyword trimmed) do not spoil the file */
}

/* The part that may longjmp: nothing in it needs freeing beyond what png_destroy_write_struct
 * frees, and the locals the caller reads after a jump are not modified after setjmp. */
static gboolean
encode (FILE *fp, const DsImage *img, guint significant_bits, const DsPngText *texts, guint n_texts,
        PngErrors *errors)
{
  png_structp png = png_create_write_struct (PNG_LIBPNG_VER_STRING, errors, on_png_error, on_png_warning);
  if (!png) {
    g_strlcpy (errors->message, "libpng: out of memory", sizeof errors->message);
    return FALSE;
  }
  png_infop info = png_create_info_struct (png);
  if (!info || setjmp (png_jmpbuf (png))) {
    png_destroy_write_struct (&png, info ? &info : NULL);
    return FALSE;
  }
  png_init_io (png, fp);
  png_set_IHDR (png, info, img->width, img->height, 16, PNG_COLOR_TYPE_GRAY, PNG_INTERLACE_NONE,
                PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
  png_color_8 sig = { .gray = (png_byte) significant_bits };
  png_set_sBIT (png, info, &sig);
  png_text chunks[16];
  guint n = MIN (n_texts, G_N_ELEMENTS (chunks));
  for (guint i = 0; i < n; i++)
    chunks[i] = (png_text) { .compression = PNG_TEXT_COMPRESSION_NONE, .key = (png_charp) texts[i].key,
                             .text = (png_charp) texts[i].text };
  png_set_text (png, info, chunks, (int) n);
  png_write_info (png, info);
  /* PNG stores 16-bit samples big-endian; libpng swaps them from the host's order. */
  if (G_BYTE_ORDER == G_LITTLE_ENDIAN)
    png_set_swap (png);
  for (guint y = 0; y < img->height; y++)
    png_write_row (png, (png_const_bytep) ds_image_row (img, y));
  png_write_end (png, NULL);
  png_destroy_write_struct (&png, &info);
  return TRUE;
}

gboolean
ds_png16_write (const DsImage *img, const char *path, guint significant_bits, const DsPngText *texts, guint n_texts,
                GError **error)
{
  if (img->type != DS_SAMPLE_U16 || significant_bits < 1 || significant_bits > 16 || n_texts > 16) {
    g_set_error (error, DS_OUTPUT_ERROR, DS_OUTPUT_ERROR_INVALID,
                 "%s: a 16-bit PNG needs a u16 image (got %s), 1..16 significant bits (got %u) and at most 16 "
                 "texts (got %u)",
                 path, ds_sample_type_name (img->type), significant_bits, n_texts);
    return FALSE;
  }
  g_autofree char *tmp = ds_atomic_temp_path (path);
  FILE *fp = g_fopen (tmp, "wb");
  if (!fp) {
    int e = errno;
    g_set_error (error, DS_OUTPUT_ERROR, DS_OUTPUT_ERROR_IO, "%s: cannot create: %s", path, g_strerror (e));
    return FALSE;
  }
  PngErrors errors = { { 0 } };
  gboolean ok = encode (fp, img, significant_bits, texts, n_texts, &errors);
  int e = 0;
  if (fflush (fp) != 0 && ok) {
    e = errno;
    ok = FALSE;
  }
  if (fclose (fp) != 0 && ok) {
    e = errno;
    ok = FALSE;
  }
  if (!ok) {
    g_set_error (error, DS_OUTPUT_ERROR, DS_OUTPUT_ERROR_IO, "%s: writing failed: %s", path,
                 errors.message[0] ? errors.message : g_strerror (e));
    g_unlink (tmp);
    return FALSE;
  }
  return ds_atomic_commit (tmp, path, error);
}
