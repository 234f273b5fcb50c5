#include "daemon/ctl/image_header.h"

#include <errno.h>
#include <fcntl.h>
#include <string.h>
#include <sys/stat.h>
#include <tiffio.h>
#include <unistd.h>

#include "proc/proc_error.h"

/* A JPEG's start-of-frame segment may follow EXIF and ICC segments of up to 64 KiB each. */
#define HEAD_BYTES (1u << 20)

static gboolean
bad (GError **error, const char *path, const char *what)
{
  g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_FORMAT, "%s: %s", path, what);
  return FALSE;
}

static guint32
be32 (const guint8 *p)
{
  return (guint32) p[0] << 24 | (guint32) p[1] << 16 | (guint32) p[2] << 8 | p[3];
}

static guint32
le32 (const guint8 *p)
{
  return (guint32) p[3] << 24 | (guint32) p[2] << 16 | (guint32) p[1] << 8 | p[0];
}

static gboolean
png_size (const guint8 *h, gsize n, const char *path, guint64 *w, guint64 *ht, GError **error)
{
  if (n < 24 || memcmp (h + 12, "IHDR", 4) != 0)
    return bad (error, path, "PNG without an IHDR chunk first");
  *w = be32 (h + 16);
  *ht = be32 (h + 20);
  return TRUE;
}

static gboolean
bmp_size (const guint8 *h, gsize n, const char *path, guint64 *w, guint64 *ht, GError **error)
{
  if (n < 26)
    return bad (error, path, "BMP header cut short");
  if (le32 (h + 14) == 12) { /* OS/2 core header: 16-bit sides */
    *w = (guint64) (h[18] | h[19] << 8);
    *ht = (guint64) (h[20] | h[21] << 8);
    return TRUE;
  }
  gint32 sw = (gint32) le32 (h + 18), sh = (gint32) le32 (h + 22);
  /* a negative height is a top-down bitmap */
  *w = sw < 0 ? 0 : (guint64) sw;
  *ht = sh < 0 ? (guint64) (-(gint64) sh) : (guint64) sh;
  return TRUE;
}

/* P1..P6: magic, then width and height as decimal text, with # comments between. */
static gboolean
pnm_size (const guint8 *h, gsize n, const char *path, guint64 *w, guint64 *ht, GError **error)
{
  gsize i = 2;
  guint64 v[2];
  for (int k = 0; k < 2; k++) {
    for (;;) {
      while (i < n && g_ascii_isspace (h[i]))
        i++;
      if (i < n && h[i] == '#') {
        while (i < n && h[i] != '\n')
          i++;
        continue;
      }
      break;
    }
    if (i >= n || !g_ascii_isdigit (h[i]))
      return bad (error, path, "PNM header without a width and height");
    v[k] = 0;
    while (i < n && g_ascii_isdigit (h[i]) && v[k] < G_MAXUINT32)
      v[k] = v[k] * 10 + (guint64) (h[i++] - '0');
  }
  *w = v[0];
  *ht = v[1];
  return TRUE;
}

/* Walks the marker segments to the first start-of-frame (SOF0..SOF15 but DHT, JPG, DAC). */
static gboolean
jpeg_size (const guint8 *h, gsize n, const char *path, guint64 *w, guint64 *ht, GError **error)
{
  gsize i = 2;
  while (i + 4 <= n) {
    if (h[i] != 0xFF)
      return bad (error, path, "JPEG marker expected");
    guint8 m = h[i + 1];
    if (m == 0xFF) {
      i++;
      continue;
    }
    gsize len = (gsize) (h[i + 2] << 8 | h[i + 3]);
    if (m >= 0xC0 && m <= 0xCF && m != 0xC4 && m != 0xC8 && m != 0xCC) {
      if (i + 9 > n || len < 7)
        return bad (error, path, "JPEG frame header cut short");
      *ht = (guint64) (h[i + 5] << 8 | h[i + 6]);
      *w = (guint64) (h[i + 7] << 8 | h[i + 8]);
      return TRUE;
    }
    if (m == 0xD9 || m == 0xDA || len < 2)
      break;
    i += 2 + len;
  }
  return bad (error, path, "JPEG without a frame header in its first megabyte");
}

static int
tiff_error_handler (TIFF *tif, void *user, const char *module, const char *fmt, va_list ap)
{
  (void) tif;
  (void) module;
  GString *s = user;
  if (s && s->len == 0)
    g_string_append_vprintf (s, fmt, ap);
  return 1;
}

static gboolean
tiff_size (const char *path, guint64 *w, guint64 *ht, GError **error)
{
  g_autoptr (GString) msg = g_string_new (NULL);
  TIFFOpenOptions *opts = TIFFOpenOptionsAlloc ();
  TIFFOpenOptionsSetErrorHandlerExtR (opts, tiff_error_handler, msg);
  TIFFOpenOptionsSetWarningHandlerExtR (opts, tiff_error_handler, NULL);
  /* the first directory only: no strip is read until asked for */
  TIFF *tif = TIFFOpenExt (path, "r", opts);
  TIFFOpenOptionsFree (opts);
  if (!tif) {
    g_autofree char *what = g_strdup_printf ("TIFF header does not read: %s", msg->len ? msg->str : "unknown");
    return bad (error, path, what);
  }
  guint32 tw = 0, th = 0;
  gboolean ok = TIFFGetField (tif, TIFFTAG_IMAGEWIDTH, &tw) && TIFFGetField (tif, TIFFTAG_IMAGELENGTH, &th);
  TIFFClose (tif);
  if (!ok)
    return bad (error, path, "TIFF without ImageWidth and ImageLength");
  *w = tw;
  *ht = th;
  return TRUE;
}

gboolean
ds_image_header_size (const char *path, guint64 *width, guint64 *height, GError **error)
{
  int fd = open (path, O_RDONLY | O_NONBLOCK | O_CLOEXEC | O_NOCTTY);
  if (fd < 0) {
    int e = errno;
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_IO, "%s: cannot open: %s", path, g_strerror (e));
    return FALSE;
  }
  struct stat st;
  if (fstat (fd, &st) != 0 || !S_ISREG (st.st_mode)) {
    close (fd);
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_IO, "%s: not a regular file", path);
    return FALSE;
  }
  g_autofree guint8 *h = g_malloc (HEAD_BYTES);
  gsize n = 0;
  while (n < HEAD_BYTES) {
    ssize_t r = read (fd, h + n, HEAD_BYTES - n);
    if (r < 0 && errno == EINTR)
      continue;
    if (r <= 0)
      break;
    n += (gsize) r;
  }
  close (fd);
  *width = *height = 0;
  if (n >= 8 && memcmp (h, "\x89PNG\r\n\x1a\n", 8) == 0)
    return png_size (h, n, path, width, height, error);
  if (n >= 4 && (memcmp (h, "II*\0", 4) == 0 || memcmp (h, "MM\0*", 4) == 0 || memcmp (h, "II+\0", 4) == 0 ||
                 memcmp (h, "MM\0+", 4) == 0))
    return tiff_size (path, width, height, error);
  if (n >= 2 && h[0] == 'B' && h[1] == 'M')
    return bmp_size (h, n, path, width, height, error);
  if (n >= 2 && h[0] == 'P' && h[1] >= '1' && h[1] <= '6')
    return pnm_size (h, n, path, width, height, error);
  if (n >= 3 && h[0] == 0xFF && h[1] == 0xD8 && h[2] == 0xFF)
    return jpeg_size (h, n, path, width, height, error);
  return bad (error, path, "not a PNG, TIFF, BMP, PNM or JPEG image");
}
