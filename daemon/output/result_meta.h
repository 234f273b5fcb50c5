/* The metadata keys every result file shares, built in one place so that descatterd (result.c,
 * its spool and the socket), descatterctl capture/stream and descatterctl separate say the same
 * thing the same way (docs/operations.md, "Result files"):
 *   producer     program, version, git describe, host
 *   time_utc     ISO 8601 with milliseconds and Z
 *   separation   estimator, phases, duty, black level, ... (DsSeparationMeta)
 *   planes       per plane: units, long_name, dtype
 *   mask_bits    the quality mask's legend: per bit its value and meaning
 * Pure functions, any thread. */
#pragma once
#include <glib.h>
#include <json-glib/json-glib.h>

#include "proc/separation.h"

G_BEGIN_DECLS

/* The format name and version of result metadata (result.json, TIFF ImageDescription, HDF5). */
#define DS_RESULT_FORMAT "descatter-result"
#define DS_RESULT_FORMAT_VERSION 1

/* Mask bit names and meanings: ds_mask_bit_name and ds_mask_bit_meaning (proc/separation.h). */
/* "saturated dark low_modulation ...": the names in bit order, space-separated (CF's
 * flag_meanings). */
char *ds_output_mask_flag_meanings (void);

/* "2026-11-25T16:02:11.123Z". */
char *ds_output_time_string (GDateTime *time);
/* The producer object: {"program", "version", "git", "host"}. */
JsonNode *ds_output_producer_json (const char *program);
/* The separation object (the same keys from the daemon and from `separate`). */
JsonNode *ds_output_separation_json (const DsSeparationMeta *meta);
/* {"saturated": {"bit": 0, "value": 1, "meaning": "..."}, ...} */
JsonNode *ds_output_mask_bits_json (void);

/* Units and long names of the planes a result may hold, by plane name (transmissive,
 * scattered, mask, max, min, mean, sigma_transmissive, sigma_scattered, phases, black). NULL
 * for unknown names. */
const char *ds_output_plane_units (const char *plane);
const char *ds_output_plane_long_name (const char *plane);
/* {"transmissive": {"units": "counts", "long_name": "...", "dtype": "f32"}, ...} for the
 * NULL-terminated list of planes with their dtypes ("f32", "u16", "u8"), given pairwise. */
JsonNode *ds_output_planes_json (const char *const *plane_dtype_pairs);

/* SHA-256 (hex) of a text: the effective configuration's fingerprint. */
char *ds_output_sha256_hex (const char *text);

/* A copy sharing nothing with node (json_node_copy shares objects and arrays): safe to modify,
 * and to hand to another thread. */
JsonNode *ds_json_deep_copy (JsonNode *node);

/* Helpers for reading metadata back: the member at a dotted path ("camera.serial"), or NULL. */
JsonNode *ds_json_path (JsonNode *root, const char *dotted);
const char *ds_json_path_string (JsonNode *root, const char *dotted, const char *fallback);
double ds_json_path_double (JsonNode *root, const char *dotted, double fallback);
gint64 ds_json_path_int (JsonNode *root, const char *dotted, gint64 fallback);

/* The object-plane pixel size of a result in µm (pixel_size_um: the sensor's pixel pitch over the
 * optics' magnification), or NAN when the metadata says it is unknown (null or absent). */
double ds_output_pixel_size_um (JsonNode *meta);

/* For writing metadata: the member `key` with the value v, or null where v is not finite (JSON has
 * no NaN or infinity, and json-glib's generator writes them as text no parser reads). */
void ds_json_add_double_or_null (JsonBuilder *b, const char *key, double v);

G_END_DECLS
