/* Private to proc/pixfmt*.c. */
#pragma once
#include <glib.h>

#include "proc/pixfmt.h"

G_BEGIN_DECLS

/* Checks the arguments shared by unpack and pack; returns the byte count the payload needs,
 * 0 with error set when they are invalid. */
gsize ds_pixfmt_check_geometry (DsPixelFormat fmt, guint width, guint height, gsize stride,
                                GError **error);

/* ds_pixfmt_check_geometry, and data non-NULL with at least the bytes needed (SIZE_MISMATCH). */
gboolean ds_pixfmt_check_payload (DsPixelFormat fmt, const void *data, gsize size, guint width,
                                  guint height, gsize stride, GError **error);

/* Unpacks pixels [0, width) of one row into dst (u8 or u16 samples); see pixfmt_unpack.c. */
guint ds_pixfmt_unpack_row (DsPixelFormat fmt, const guint8 *row, guint64 first, guint width,
                            void *dst);

G_END_DECLS
