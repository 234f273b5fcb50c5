/* 16-bit grey PNG files through libpng (not OpenCV's imgcodecs), so that each file carries what
 * its values mean: text chunks (tEXt) with the scale and units, and sBIT, the significant bits.
 * Any thread (libpng's errors are collected per file, not through a global handler). */
#pragma once
#include <glib.h>

#include "proc/image.h"

G_BEGIN_DECLS

typedef struct {
  const char *key;  /* PNG keyword: 1..79 printable Latin-1 characters */
  const char *text; /* ASCII */
} DsPngText;

/* Writes a u16 image (row stride honoured) atomically (daemon/output/atomic_file.h) with an sBIT
 * chunk of significant_bits (1..16) and the given tEXt chunks. Fails INVALID for another sample
 * type or a bad significant_bits, IO when the file cannot be written. */
gboolean ds_png16_write (const DsImage *image, const char *path, guint significant_bits, const DsPngText *texts,
                         guint n_texts, GError **error);

G_END_DECLS
