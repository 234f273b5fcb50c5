/* An image file's width and height read from its header alone, before anything decodes it:
 * a few kilobytes of PNG or JPEG can declare a picture of gigabytes, and the decoder
 * allocates it in full before the first row. PNG (IHDR), TIFF (libtiff, first directory),
 * BMP, PNM and JPEG (the start-of-frame segment); other content is refused, since the phase
 * folder lists no other kind. Any thread; reads the start of the file. */
#pragma once
#include <glib.h>

G_BEGIN_DECLS

/* Fails DS_PROC_ERROR_IO (cannot open, not a regular file) or DS_PROC_ERROR_FORMAT (no
 * header of a known kind, or one that is cut short); messages start with the path. */
gboolean ds_image_header_size (const char *path, guint64 *width, guint64 *height, GError **error);

G_END_DECLS
