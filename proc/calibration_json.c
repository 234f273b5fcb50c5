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
  /* the scattering check (calibration_scatter.h); "warning" only when the reference scatters */
  json_builder_set_member_name (b, "scattering");
  json_builder_begin_object (b);
  json_builder_set_member_name (b, "suspected");
  json_builder_add_boolean_value (b, cal->scatter.scattering);
  json_builder_set_member_name (b, "measured");
  json_builder_add_boolean_value (b, cal->scatter.measured);
  json_builder_set_member_name (b, "off_level_dim");
  json_builder_add_double_value (b, cal->scatter.off_dim);
  json_builder_set_member_name (b, "off_level_bright");
  json_builder_add_double_value (b, cal->scatter.off_bright);
  json_builder_set_member_name (b, "brightness_contrast");
  json_builder_add_double_value (b, cal->scatter.brightness_contrast);
  json_builder_set_member_name (b, "dim_parts_brighter");
  json_builder_add_boolean_value (b, cal->scatter.spatial);
  json_builder_set_member_name (b, "shape_residual");
  json_builder_add_double_value (b, cal->scatter.shape_residual);
  json_builder_set_member_name (b, "shape_noise");
  json_builder_add_double_value (b, cal->scatter.shape_noise);
  json_builder_set_member_name (b, "shape_misfit");
  json_builder_add_boolean_value (b, cal->scatter.shape_misfit);
  json_builder_end_object (b);
  g_autofree char *warning = ds_calibration_scatter_warning (cal);
  if (warning) {
    json_builder_set_member_name (b, "warning");
    json_builder_add_string_value (b, warning);
  }
}

/* The scattering check's object; absent (an older daemon) leaves it unmeasured. */
static gboolean
scatter_from_json (JsonObject *obj, DsScatterCheck *s, GError **error)
{
  JsonNode *node = json_object_get_member (obj, "scattering");
  if (!node)
    return TRUE;
  if (!JSON_NODE_HOLDS_OBJECT (node)) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_INVALID_ARGUMENT, "calibration: \"scattering\" is not an object");
    return FALSE;
  }
  JsonObject *o = json_node_get_object (node);
  const struct {
    const char *key;
    double *value;
  } fields[] = {
    { "off_level_dim", &s->off_dim },
    { "off_level_bright", &s->off_bright },
    { "brightness_contrast", &s->brightness_contrast },
    { "shape_residual", &s->shape_residual },
    { "shape_noise", &s->shape_noise },
  };
  for (guint i = 0; i < G_N_ELEMENTS (fields); i++) {
    JsonNode *n = json_object_get_member (o, fields[i].key);
    GType t = n && JSON_NODE_HOLDS_VALUE (n) ? json_node_get_value_type (n) : G_TYPE_INVALID;
    if (t != G_TYPE_DOUBLE && t != G_TYPE_INT64) {
      g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_INVALID_ARGUMENT,
                   "calibration: \"scattering.%s\" is %s", fields[i].key, n ? "not a number" : "missing");
      return FALSE;
    }
    *fields[i].value = json_node_get_double (n);
  }
  s->scattering = json_object_get_boolean_member_with_default (o, "suspected", FALSE);
  s->measured = json_object_get_boolean_member_with_default (o, "measured", FALSE);
  s->spatial = json_object_get_boolean_member_with_default (o, "dim_parts_brighter", FALSE);
  s->shape_misfit = json_object_get_boolean_member_with_default (o, "shape_misfit", FALSE);
  return TRUE;
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
  return scatter_from_json (obj, &cal->scatter, error);
}

char *
ds_calibration_config_lines (const DsCalibration *cal)
{
  return g_strdup_printf ("[illuminator]\npattern=%s\nperiod-px=%.4f\nduty=%.4f\nblack-level=%.4f\n"
                          "harmonic-gain=%.4f\nedge-blur-px=%.2f\n",
                          cal->pattern == DS_PATTERN_SINE ? "sine" : "square", cal->period_px, cal->duty,
                          cal->black_level, cal->harmonic_gain, cal->edge_blur_px);
}
