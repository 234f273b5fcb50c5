/* A calibration as JSON (calibration_json.h). */
#include <math.h>
#include <string.h>

#include "proc/calibration_json.h"
#include "proc/proc_error.h"

/* Every member but "pattern" and "warning", in the order written: its key, its type and where
 * it lives. Writer and reader walk the same tables. A count is a non-negative integer; a
 * number a double or an integer. */
typedef enum {
  M_COUNT_UINT,
  M_COUNT_U64,
  M_BOOL,
  M_NUMBER,
} MemberType;

typedef struct {
  const char *key;
  MemberType type;
  gsize offset;
} Member;

#define CAL(field) G_STRUCT_OFFSET (DsCalibration, field)
static const Member members[] = {
  { "n_phases", M_COUNT_UINT, CAL (n_phases) },
  { "frames_per_phase", M_COUNT_UINT, CAL (frames_per_phase) },
  { "period_measured", M_BOOL, CAL (period_measured) },
  { "period_px", M_NUMBER, CAL (period_px) },
  { "phase_offset_cycles", M_NUMBER, CAL (phase_offset_cycles) },
  { "offset_spread_cycles", M_NUMBER, CAL (offset_spread) },
  { "duty", M_NUMBER, CAL (duty) },
  { "black_level", M_NUMBER, CAL (black_level) },
  { "black_level_measured", M_BOOL, CAL (black_level_measured) },
  { "contrast", M_NUMBER, CAL (contrast) },
  { "second_period_px", M_NUMBER, CAL (second_period_px) },
  { "second_contrast", M_NUMBER, CAL (second_contrast) },
  { "harmonic_gain", M_NUMBER, CAL (harmonic_gain) },
  { "harmonic_gain_theory", M_NUMBER, CAL (harmonic_gain_theory) },
  { "edge_blur_px", M_NUMBER, CAL (edge_blur_px) },
  { "pixels_used", M_COUNT_U64, CAL (pixels_used) },
};
#undef CAL

/* The "scattering" object (calibration_scatter.h). Its booleans are optional: absent reads as
 * FALSE. */
#define SC(field) G_STRUCT_OFFSET (DsScatterCheck, field)
static const Member scatter_members[] = {
  { "suspected", M_BOOL, SC (scattering) },
  { "measured", M_BOOL, SC (measured) },
  { "off_level_dim", M_NUMBER, SC (off_dim) },
  { "off_level_bright", M_NUMBER, SC (off_bright) },
  { "brightness_contrast", M_NUMBER, SC (brightness_contrast) },
  { "dim_parts_brighter", M_BOOL, SC (spatial) },
  { "shape_residual", M_NUMBER, SC (shape_residual) },
  { "shape_noise", M_NUMBER, SC (shape_noise) },
  { "shape_misfit", M_BOOL, SC (shape_misfit) },
};
#undef SC

/* The "pattern_check" object (calibration_pattern.h) but its "expected". */
#define PC(field) G_STRUCT_OFFSET (DsPatternCheck, field)
static const Member pattern_members[] = {
  { "detected", M_BOOL, PC (detected) },
  { "sine_residual", M_NUMBER, PC (sine_residual) },
  { "square_residual", M_NUMBER, PC (square_residual) },
  { "square_blur_px", M_NUMBER, PC (square_blur_px) },
  { "noise", M_NUMBER, PC (noise) },
  { "square_fits", M_BOOL, PC (square_fits) },
};
#undef PC

static void
add_members (JsonBuilder *b, const Member *table, guint n, gconstpointer base)
{
  for (guint i = 0; i < n; i++) {
    json_builder_set_member_name (b, table[i].key);
    switch (table[i].type) {
    case M_COUNT_UINT:
      json_builder_add_int_value (b, G_STRUCT_MEMBER (guint, base, table[i].offset));
      break;
    case M_COUNT_U64:
      json_builder_add_int_value (b, (gint64) G_STRUCT_MEMBER (guint64, base, table[i].offset));
      break;
    case M_BOOL:
      json_builder_add_boolean_value (b, G_STRUCT_MEMBER (gboolean, base, table[i].offset));
      break;
    case M_NUMBER:
      json_builder_add_double_value (b, G_STRUCT_MEMBER (double, base, table[i].offset));
      break;
    }
  }
}

/* Reads the table's members from obj into base; `within` names the enclosing object in errors
 * ("" at the top level, "scattering." inside it). */
static gboolean
read_members (JsonObject *obj, const Member *table, guint n, gpointer base, const char *within, GError **error)
{
  for (guint i = 0; i < n; i++) {
    const Member *m = &table[i];
    JsonNode *node = json_object_get_member (obj, m->key);
    GType t = node && JSON_NODE_HOLDS_VALUE (node) ? json_node_get_value_type (node) : G_TYPE_INVALID;
    const char *wrong = NULL;
    switch (m->type) {
    case M_COUNT_UINT:
    case M_COUNT_U64:
      if (t != G_TYPE_INT64 || json_node_get_int (node) < 0)
        wrong = "not a count";
      else if (m->type == M_COUNT_U64)
        G_STRUCT_MEMBER (guint64, base, m->offset) = (guint64) json_node_get_int (node);
      else
        G_STRUCT_MEMBER (guint, base, m->offset) = (guint) MIN (json_node_get_int (node), (gint64) G_MAXUINT);
      break;
    case M_BOOL:
      /* Inside an object a flag an older writer did not send reads as FALSE. */
      if (!node && *within)
        break;
      if (t != G_TYPE_BOOLEAN)
        wrong = "not a boolean";
      else
        G_STRUCT_MEMBER (gboolean, base, m->offset) = json_node_get_boolean (node);
      break;
    case M_NUMBER:
      if (t != G_TYPE_DOUBLE && t != G_TYPE_INT64)
        wrong = "not a number";
      else
        G_STRUCT_MEMBER (double, base, m->offset) = json_node_get_double (node);
      break;
    }
    if (wrong) {
      g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_INVALID_ARGUMENT, "calibration: \"%s%s\" is %s", within,
                   m->key, node ? wrong : "missing");
      return FALSE;
    }
  }
  return TRUE;
}

void
ds_calibration_add_json_members (JsonBuilder *b, const DsCalibration *cal)
{
  json_builder_set_member_name (b, "pattern");
  json_builder_add_string_value (b, cal->pattern == DS_PATTERN_SINE ? "sine" : "square");
  add_members (b, members, G_N_ELEMENTS (members), cal);
  /* the scattering check (calibration_scatter.h); "warning" only when the reference scatters */
  json_builder_set_member_name (b, "scattering");
  json_builder_begin_object (b);
  add_members (b, scatter_members, G_N_ELEMENTS (scatter_members), &cal->scatter);
  json_builder_end_object (b);
  /* sine or square (calibration_pattern.h); "pattern_notice" when not what was expected */
  json_builder_set_member_name (b, "pattern_check");
  json_builder_begin_object (b);
  json_builder_set_member_name (b, "expected");
  json_builder_add_string_value (b, cal->pattern_check.expected == DS_PATTERN_SINE ? "sine" : "square");
  add_members (b, pattern_members, G_N_ELEMENTS (pattern_members), &cal->pattern_check);
  json_builder_end_object (b);
  /* only where measured (the daemon's calibrate with a dark frame) */
  if (cal->open_field_dn_per_ms > 0) {
    json_builder_set_member_name (b, "open_field_dn_per_ms");
    json_builder_add_double_value (b, cal->open_field_dn_per_ms);
    if (cal->open_field_pixel_format[0]) {
      json_builder_set_member_name (b, "open_field_pixel_format");
      json_builder_add_string_value (b, cal->open_field_pixel_format);
    }
  }
  g_autofree char *notice = ds_calibration_pattern_notice (cal);
  if (notice) {
    json_builder_set_member_name (b, "pattern_notice");
    json_builder_add_string_value (b, notice);
  }
  g_autofree char *level_note = ds_calibration_black_level_note (cal);
  if (level_note) {
    json_builder_set_member_name (b, "black_level_notice");
    json_builder_add_string_value (b, level_note);
  }
  g_autofree char *warning = ds_calibration_scatter_warning (cal);
  if (warning) {
    json_builder_set_member_name (b, "warning");
    json_builder_add_string_value (b, warning);
  }
}

gboolean
ds_calibration_from_json (JsonObject *obj, DsCalibration *cal, GError **error)
{
  memset (cal, 0, sizeof *cal);
  JsonNode *n = json_object_get_member (obj, "pattern");
  const char *pattern = n && JSON_NODE_HOLDS_VALUE (n) && json_node_get_value_type (n) == G_TYPE_STRING
                          ? json_node_get_string (n)
                          : "";
  if (strcmp (pattern, "square") != 0 && strcmp (pattern, "sine") != 0) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_INVALID_ARGUMENT,
                 n ? "calibration: \"pattern\" is neither \"square\" nor \"sine\"" : "calibration: \"pattern\" is missing");
    return FALSE;
  }
  cal->pattern = strcmp (pattern, "sine") == 0 ? DS_PATTERN_SINE : DS_PATTERN_SQUARE;
  if (!read_members (obj, members, G_N_ELEMENTS (members), cal, "", error))
    return FALSE;
  /* absent (not measured, or an older daemon): 0 */
  n = json_object_get_member (obj, "open_field_dn_per_ms");
  if (n) {
    double v = JSON_NODE_HOLDS_VALUE (n) && (json_node_get_value_type (n) == G_TYPE_DOUBLE ||
                                             json_node_get_value_type (n) == G_TYPE_INT64)
                 ? json_node_get_double (n)
                 : NAN;
    if (!(v > 0) || !isfinite (v)) {
      g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_INVALID_ARGUMENT,
                   "calibration: \"open_field_dn_per_ms\" is not a positive number");
      return FALSE;
    }
    cal->open_field_dn_per_ms = v;
  }
  /* absent (not said, or an older daemon): "" */
  n = json_object_get_member (obj, "open_field_pixel_format");
  if (n) {
    if (!JSON_NODE_HOLDS_VALUE (n) || json_node_get_value_type (n) != G_TYPE_STRING ||
        !*json_node_get_string (n) ||
        g_strlcpy (cal->open_field_pixel_format, json_node_get_string (n), sizeof cal->open_field_pixel_format) >=
          sizeof cal->open_field_pixel_format) {
      g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_INVALID_ARGUMENT,
                   "calibration: \"open_field_pixel_format\" is not a pixel format's name");
      return FALSE;
    }
  }
  /* absent (an older daemon): the pattern was not detected, it is what was expected */
  cal->pattern_check.expected = cal->pattern;
  n = json_object_get_member (obj, "pattern_check");
  if (n) {
    if (!JSON_NODE_HOLDS_OBJECT (n)) {
      g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_INVALID_ARGUMENT,
                   "calibration: \"pattern_check\" is not an object");
      return FALSE;
    }
    JsonObject *pc = json_node_get_object (n);
    const char *expected = json_object_get_string_member_with_default (pc, "expected", "");
    if (strcmp (expected, "square") != 0 && strcmp (expected, "sine") != 0) {
      g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_INVALID_ARGUMENT,
                   "calibration: \"pattern_check.expected\" is neither \"square\" nor \"sine\"");
      return FALSE;
    }
    cal->pattern_check.expected = strcmp (expected, "sine") == 0 ? DS_PATTERN_SINE : DS_PATTERN_SQUARE;
    if (!read_members (pc, pattern_members, G_N_ELEMENTS (pattern_members), &cal->pattern_check, "pattern_check.",
                       error))
      return FALSE;
  }
  /* absent (an older daemon): the scattering check stays unmeasured */
  n = json_object_get_member (obj, "scattering");
  if (!n)
    return TRUE;
  if (!JSON_NODE_HOLDS_OBJECT (n)) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_INVALID_ARGUMENT, "calibration: \"scattering\" is not an object");
    return FALSE;
  }
  return read_members (json_node_get_object (n), scatter_members, G_N_ELEMENTS (scatter_members), &cal->scatter,
                       "scattering.", error);
}

char *
ds_calibration_config_lines (const DsCalibration *cal)
{
  /* The open field's DN are its pixel format's: the line naming it travels with it. */
  g_autofree char *open = cal->open_field_dn_per_ms <= 0 ? g_strdup ("")
                          : cal->open_field_pixel_format[0]
                            ? g_strdup_printf ("open-field-dn-per-ms=%.6g\nopen-field-pixel-format=%s\n",
                                               cal->open_field_dn_per_ms, cal->open_field_pixel_format)
                            : g_strdup_printf ("open-field-dn-per-ms=%.6g\n", cal->open_field_dn_per_ms);
  /* sine stripes have no duty, and their blur is in the harmonic gain */
  if (cal->pattern == DS_PATTERN_SINE)
    return g_strdup_printf ("[illuminator]\npattern=sine\nperiod-px=%.4f\nblack-level=%.4f\nharmonic-gain=%.4f\n%s",
                            cal->period_px, cal->black_level, cal->harmonic_gain, open);
  return g_strdup_printf ("[illuminator]\npattern=%s\nperiod-px=%.4f\nduty=%.4f\nblack-level=%.4f\n"
                          "harmonic-gain=%.4f\nedge-blur-px=%.2f\n%s",
                          cal->pattern == DS_PATTERN_SINE ? "sine" : "square", cal->period_px, cal->duty,
                          cal->black_level, cal->harmonic_gain, cal->edge_blur_px, open);
}
