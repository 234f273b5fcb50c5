/* TIFF files through libtiff (not OpenCV's imgcodecs), so that each image carries its
 * metadata: ImageDescription holds the result's metadata JSON, Software the program and
 * version, DateTime the acquisition time (UTC; TIFF has no time zone field, the JSON's
 * time_utc is exact), SampleFormat says IEEE float for f32 (unsigned integer otherwise).
 * Uncompressed, one sample per pixel, MinIsBlack: every TIFF reader understands it.
 * Any thread (libtiff errors are collected per file, not through its global handlers). */
#pragma once
#include <glib.h>

#include "proc/image.h"

G_BEGIN_DECLS

typedef struct {
  const char *description;   /* ImageDescription; NULL: none */
  const char *software;      /* Software; NULL: "descatter VERSION (GIT)" */
  GDateTime *time;           /* DateTime; NULL: now */
  const char *document_name; /* DocumentName (e.g. "transmissive"); NULL: none */
  double pixel_size_um;      /* XResolution = YResolution in pixels per cm; 0 or NAN: unknown, no tags */
} DsTiffTags;

/* Writes u8, u16 or f32 (row stride honoured) atomically (daemon/output/atomic_file.h). */
gboolean ds_tiff_write (const DsImage *image, const char *path, const DsTiffTags *tags, GError **error);

/* Reads back the ImageDescription of the first directory (tests, tools). NULL with error when
 * absent or unreadable. */
char *ds_tiff_read_description (const char *path, GError **error);

G_END_DECLS
