/* One result as the file writers see it: borrowed planes and metadata, whether they come from a
 * DsResult in descatterd or from payloads in descatterctl. */
#pragma once
#include <glib.h>
#include <json-glib/json-glib.h>

#include "daemon/output/raw_frames.h"
#include "proc/image.h"

G_BEGIN_DECLS

typedef struct {
  const DsImage *transmissive, *scattered; /* f32; required */
  const DsImage *mask;                     /* u8; required */
  const DsImage *max, *min, *mean;         /* f32; optional (NULL) */
  const DsImage *sigma_transmissive, *sigma_scattered; /* f32; optional */
  const DsRawFrames *raw;                  /* optional: the phase and black frames */
  JsonNode *meta;                          /* the result metadata (an object) */
} DsOutputResult;

/* The optional planes present, by name, in a fixed order; returns how many (<= 5). */
guint ds_output_result_optional (const DsOutputResult *r, const char **names, const DsImage **images);

G_END_DECLS
