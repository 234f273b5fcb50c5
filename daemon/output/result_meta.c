#include "daemon/output/result_meta.h"

#include <math.h>
#include <string.h>

#include "build_info.h"

char *
ds_output_mask_flag_meanings (void)
{
  GString *s = g_string_new (NULL);
  for (guint i = 0; i < DS_MASK_N_BITS; i++)
    g_string_append_printf (s, "%s%s", i ? " " : "", ds_mask_bit_name (i));
  return g_string_free (s, FALSE);
}

char *
ds_output_time_string (GDateTime *time)
{
  g_autoptr (GDateTime) utc = g_date_time_to_utc (time);
  g_autofree char *base = g_date_time_format (utc, "%Y-%m-%dT%H:%M:%S");
  return g_strdup_printf ("%s.%03dZ", base, g_date_time_get_microsecond (utc) / 1000);
}

JsonNode *
ds_output_producer_json (const char *program)
{
  g_autoptr (JsonBuilder) b = json_builder_new ();
  json_builder_begin_object (b);
  json_builder_set_member_name (b, "program");
  json_builder_add_string_value (b, program);
  json_builder_set_member_name (b, "version");
  json_builder_add_string_value (b, DS_VERSION);
  json_builder_set_member_name (b, "git");
  json_builder_add_string_value (b, DS_GIT_DESCRIBE);
  json_builder_set_member_name (b, "host");
  json_builder_add_string_value (b, g_get_host_name ());
  json_builder_end_object (b);
  return json_builder_get_root (b);
}

void
ds_json_add_double_or_null (JsonBuilder *b, const char *key, double v)
{
  json_builder_set_member_name (b, key);
  if (isfinite (v))
    json_builder_add_double_value (b, v);
  else
    json_builder_add_null_value (b);
}

JsonNode *
ds_output_separation_json (const DsSeparationMeta *m)
{
  g_autoptr (JsonBuilder) b = json_builder_new ();
  json_builder_begin_object (b);
  json_builder_set_member_name (b, "estimator");
  json_builder_add_string_value (b, ds_estimator_name (m->estimator));
  json_builder_set_member_name (b, "phases");
  json_builder_add_int_value (b, m->n_phases);
  json_builder_set_member_name (b, "frames_per_phase");
  json_builder_add_int_value (b, m->frames_per_phase);
  ds_json_add_double_or_null (b, "duty", m->duty);
  ds_json_add_double_or_null (b, "black_level", m->black_level);
  ds_json_add_double_or_null (b, "pattern_mean", m->pattern_mean);
  ds_json_add_double_or_null (b, "harmonic_gain", m->harmonic_gain);
  ds_json_add_double_or_null (b, "saturation_level", m->saturation_level);
  json_builder_set_member_name (b, "dark_subtracted");
  json_builder_add_boolean_value (b, m->dark_subtracted);
  ds_json_add_double_or_null (b, "noise_dn", m->noise_dn);
  json_builder_set_member_name (b, "valid_pixels");
  json_builder_add_int_value (b, (gint64) m->valid_pixels);
  json_builder_set_member_name (b, "flagged");
  json_builder_begin_object (b);
  for (guint i = 0; i < DS_MASK_N_BITS; i++) {
    json_builder_set_member_name (b, ds_mask_bit_name (i));
    json_builder_add_int_value (b, (gint64) m->flagged[i]);
  }
  json_builder_end_object (b);
  /* whether flagged.motion was judged at all: 0 then means no motion seen */
  json_builder_set_member_name (b, "motion_checked");
  json_builder_add_boolean_value (b, m->motion_checked);
  json_builder_end_object (b);
  return json_builder_get_root (b);
}

JsonNode *
ds_output_mask_bits_json (void)
{
  g_autoptr (JsonBuilder) b = json_builder_new ();
  json_builder_begin_object (b);
  for (guint i = 0; i < DS_MASK_N_BITS; i++) {
    json_builder_set_member_name (b, ds_mask_bit_name (i));
    json_builder_begin_object (b);
    json_builder_set_member_name (b, "bit");
    json_builder_add_int_value (b, i);
    json_builder_set_member_name (b, "value");
    json_builder_add_int_value (b, 1 << i);
    json_builder_set_member_name (b, "meaning");
    json_builder_add_string_value (b, ds_mask_bit_meaning (i));
    json_builder_end_object (b);
  }
  json_builder_end_object (b);
  return json_builder_get_root (b);
}

/* "counts" are the sensor's digital numbers (DN) after dark subtraction: the unit name NeXus
 * and UDUNITS readers know. */
static const struct {
  const char *plane, *units, *long_name;
} planes[] = {
  { "transmissive", "counts", "transmissive (direct, unscattered) component, dark-subtracted" },
  { "scattered", "counts", "scattered (global) component, dark-subtracted" },
  { "mask", "", "quality flags, one bit each (legend: mask_bits)" },
  { "max", "counts", "per-pixel maximum over the phases, dark-subtracted" },
  { "min", "counts", "per-pixel minimum over the phases, dark-subtracted" },
  { "mean", "counts", "per-pixel mean over the phases (the plain average), dark-subtracted" },
  { "sigma_transmissive", "counts", "1-sigma uncertainty of the transmissive component" },
  { "sigma_scattered", "counts", "1-sigma uncertainty of the scattered component" },
  { "phases", "counts", "raw phase frames as the camera delivered them" },
  { "black", "counts", "dark frame (illuminator off) subtracted from every phase" },
};

const char *
ds_output_plane_units (const char *plane)
{
  for (guint i = 0; i < G_N_ELEMENTS (planes); i++)
    if (strcmp (planes[i].plane, plane) == 0)
      return planes[i].units;
  return NULL;
}

const char *
ds_output_plane_long_name (const char *plane)
{
  for (guint i = 0; i < G_N_ELEMENTS (planes); i++)
    if (strcmp (planes[i].plane, plane) == 0)
      return planes[i].long_name;
  return NULL;
}

JsonNode *
ds_output_planes_json (const char *const *pairs)
{
  g_autoptr (JsonBuilder) b = json_builder_new ();
  json_builder_begin_object (b);
  for (guint i = 0; pairs[i] && pairs[i + 1]; i += 2) {
    const char *units = ds_output_plane_units (pairs[i]);
    if (!units)
      continue;
    json_builder_set_member_name (b, pairs[i]);
    json_builder_begin_object (b);
    json_builder_set_member_name (b, "units");
    json_builder_add_string_value (b, units);
    json_builder_set_member_name (b, "long_name");
    json_builder_add_string_value (b, ds_output_plane_long_name (pairs[i]));
    json_builder_set_member_name (b, "dtype");
    json_builder_add_string_value (b, pairs[i + 1]);
    json_builder_end_object (b);
  }
  json_builder_end_object (b);
  return json_builder_get_root (b);
}

char *
ds_output_sha256_hex (const char *text)
{
  return g_compute_checksum_for_string (G_CHECKSUM_SHA256, text, -1);
}

JsonNode *
ds_json_deep_copy (JsonNode *node)
{
  if (JSON_NODE_HOLDS_OBJECT (node)) {
    JsonObject *src = json_node_get_object (node), *dst = json_object_new ();
    JsonObjectIter it;
    const char *name;
    JsonNode *member;
    json_object_iter_init (&it, src);
    while (json_object_iter_next (&it, &name, &member))
      json_object_set_member (dst, name, ds_json_deep_copy (member));
    JsonNode *out = json_node_new (JSON_NODE_OBJECT);
    json_node_take_object (out, dst);
    return out;
  }
  if (JSON_NODE_HOLDS_ARRAY (node)) {
    JsonArray *src = json_node_get_array (node), *dst = json_array_sized_new (json_array_get_length (src));
    for (guint i = 0; i < json_array_get_length (src); i++)
      json_array_add_element (dst, ds_json_deep_copy (json_array_get_element (src, i)));
    JsonNode *out = json_node_new (JSON_NODE_ARRAY);
    json_node_take_array (out, dst);
    return out;
  }
  return json_node_copy (node); /* values and null: nothing shared */
}

JsonNode *
ds_json_path (JsonNode *root, const char *dotted)
{
  g_auto (GStrv) parts = g_strsplit (dotted, ".", -1);
  JsonNode *node = root;
  for (guint i = 0; parts[i] && node; i++) {
    if (!JSON_NODE_HOLDS_OBJECT (node))
      return NULL;
    node = json_object_get_member (json_node_get_object (node), parts[i]);
  }
  return node;
}

const char *
ds_json_path_string (JsonNode *root, const char *dotted, const char *fallback)
{
  JsonNode *n = root ? ds_json_path (root, dotted) : NULL;
  return n && JSON_NODE_HOLDS_VALUE (n) && json_node_get_value_type (n) == G_TYPE_STRING ? json_node_get_string (n)
                                                                                        : fallback;
}

double
ds_json_path_double (JsonNode *root, const char *dotted, double fallback)
{
  JsonNode *n = root ? ds_json_path (root, dotted) : NULL;
  if (!n || !JSON_NODE_HOLDS_VALUE (n))
    return fallback;
  GType t = json_node_get_value_type (n);
  return t == G_TYPE_DOUBLE || t == G_TYPE_INT64 ? json_node_get_double (n) : fallback;
}

gint64
ds_json_path_int (JsonNode *root, const char *dotted, gint64 fallback)
{
  JsonNode *n = root ? ds_json_path (root, dotted) : NULL;
  if (!n || !JSON_NODE_HOLDS_VALUE (n))
    return fallback;
  GType t = json_node_get_value_type (n);
  return t == G_TYPE_INT64 ? json_node_get_int (n) : t == G_TYPE_DOUBLE ? (gint64) json_node_get_double (n) : fallback;
}

double
ds_output_pixel_size_um (JsonNode *meta)
{
  double v = ds_json_path_double (meta, "pixel_size_um", NAN);
  return isfinite (v) && v > 0 ? v : NAN;
}
