/* A calibration as JSON (calibration_json.h). */
#include <string.h>

#include "proc/calibration_json.h"
#include "proc/proc_error.h"

typedef struct {
  const char *key;
  gsize offset;
} NumberMember;

static const NumberMember numbers[] = {
  { "period_px", G_STRUCT_OFFSET (DsCalibration, period_px) },
  { "phase_offset_cycles", G_STRUCT_OFFSET (DsCalibration, phase_offset_cycles) },
  { "offset_spread_cycles", G_STRUCT_OFFSET (DsCalibration, offset_spread) },
  { "duty", G_STRUCT_OFFSET (DsCalibration, duty) },
  { "black_level", G_STRUCT_OFFSET (DsCalibration, black_level) },
  { "harmonic_gain", G_STRUCT_OFFSET (DsCalibration, harmonic_gain) },
  { "harmonic_gain_theory", G_STRUCT_OFFSET (DsCalibration, harmonic_gain_theory) },
  { "edge_blur_px", G_STRUCT_OFFSET (DsCalibration, edge_blur_px) },
};

void
ds_calibration_add_json_members (JsonBuilder *b, const DsCalibration *cal)
{
  json_builder_set_member_name (b, "pattern");
  json_builder_add_string_value (b, cal->pattern == DS_PATTERN_SINE ? "sine" : "square");
  json_builder_set_member_name (b, "n_phases");
  json_builder_add_int_value (b, cal->n_phases);
  json_builder_set_member_name (b, "frames_per_phase");
  json_builder_add_int_value (b, cal->frames_per_phase);
  json_builder_set_member_name (b, "period_measured");
  json_builder_add_boolean_value (b, cal->period_measured);
  for (guint i = 0; i < G_N_ELEMENTS (numbers); i++) {
    json_builder_set_member_name (b, numbers[i].key);
    json_builder_add_double_value (b, G_STRUCT_MEMBER (double, cal, numbers[i].offset));
  }
  json_builder_set_member_name (b, "pixels_used");
  json_builder_add_int_value (b, (gint64) cal->pixels_used);
}

static gboolean
member (JsonObject *obj, const char *key, JsonNode **node, GError **error)
{
  *node = json_object_get_member (obj, key);
  if (!*node || !JSON_NODE_HOLDS_VALUE (*node)) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_INVALID_ARGUMENT, "calibration: \"%s\" is %s", key,
                 *node ? "not a value" : "missing");
    return FALSE;
  }
  return TRUE;
}

gboolean
ds_calibration_from_json (JsonObject *obj, DsCalibration *cal, GError **error)
{
  memset (cal, 0, sizeof *cal);
  JsonNode *n;
  if (!member (obj, "pattern", &n, error))
    return FALSE;
  const char *pattern = json_node_get_value_type (n) == G_TYPE_STRING ? json_node_get_string (n) : "";
  if (strcmp (pattern, "square") != 0 && strcmp (pattern, "sine") != 0) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_INVALID_ARGUMENT,
                 "calibration: \"pattern\" is neither \"square\" nor \"sine\"");
    return FALSE;
  }
  cal->pattern = strcmp (pattern, "sine") == 0 ? DS_PATTERN_SINE : DS_PATTERN_SQUARE;
  const struct {
    const char *key;
    guint64 *u64;
    guint *u;
  } ints[] = {
    { "n_phases", NULL, &cal->n_phases },
    { "frames_per_phase", NULL, &cal->frames_per_phase },
    { "pixels_used", &cal->pixels_used, NULL },
  };
  for (guint i = 0; i < G_N_ELEMENTS (ints); i++) {
    if (!member (obj, ints[i].key, &n, error))
      return FALSE;
    if (json_node_get_value_type (n) != G_TYPE_INT64 || json_node_get_int (n) < 0) {
      g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_INVALID_ARGUMENT,
                   "calibration: \"%s\" is not a count", ints[i].key);
      return FALSE;
    }
    if (ints[i].u64)
      *ints[i].u64 = (guint64) json_node_get_int (n);
    else
      *ints[i].u = (guint) MIN (json_node_get_int (n), (gint64) G_MAXUINT);
  }
  if (!member (obj, "period_measured", &n, error))
    return FALSE;
  cal->period_measured = json_node_get_value_type (n) == G_TYPE_BOOLEAN && json_node_get_boolean (n);
  for (guint i = 0; i < G_N_ELEMENTS (numbers); i++) {
    if (!member (obj, numbers[i].key, &n, error))
      return FALSE;
    GType t = json_node_get_value_type (n);
    if (t != G_TYPE_DOUBLE && t != G_TYPE_INT64) {
      g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_INVALID_ARGUMENT, "calibration: \"%s\" is not a number",
                   numbers[i].key);
      return FALSE;
    }
    G_STRUCT_MEMBER (double, cal, numbers[i].offset) = json_node_get_double (n);
  }
  return TRUE;
}

char *
ds_calibration_config_lines (const DsCalibration *cal)
{
  return g_strdup_printf ("[illuminator]\npattern=%s\nperiod-px=%.4f\nduty=%.4f\nblack-level=%.4f\n"
                          "harmonic-gain=%.4f\nedge-blur-px=%.2f\n",
                          cal->pattern == DS_PATTERN_SINE ? "sine" : "square", cal->period_px, cal->duty,
                          cal->black_level, cal->harmonic_gain, cal->edge_blur_px);
}
