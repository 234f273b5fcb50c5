#include "drivers/sim/scene.h"

#include <errno.h>
#include <math.h>
#include <stddef.h>
#include <string.h>

#include "proc/image.h"

struct DsScene {
  DsSceneSpec spec;
};

typedef enum { T_UINT, T_DOUBLE, T_BOOL, T_CHOICE } KeyType;

typedef struct {
  const char *group, *key;
  KeyType type;
  size_t offset;
  const char *def;        /* NULL: required (when the group is present) */
  double min, max;        /* inclusive unless open_min/open_max */
  gboolean open_min, open_max;
  const char *choices;    /* "a|b": index stored as gboolean (0/1) */
} KeySpec;

#define F(f) offsetof (DsSceneSpec, f)
static const KeySpec keys[] = {
  { "scene", "max-render-s", T_DOUBLE, F (max_render_s), "20", 0, 1e9, TRUE, FALSE, NULL },
  { "sensor", "width", T_UINT, F (width), NULL, 8, 16384, FALSE, FALSE, NULL },
  { "sensor", "height", T_UINT, F (height), NULL, 8, 16384, FALSE, FALSE, NULL },
  { "sensor", "bit-depth", T_UINT, F (bit_depth), "12", 8, 16, FALSE, FALSE, NULL },
  { "sensor", "pixel-pitch-um", T_DOUBLE, F (pixel_pitch_um), "5", 0, 100, TRUE, FALSE, NULL },
  { "sensor", "quantum-efficiency", T_DOUBLE, F (quantum_efficiency), "0.4", 0, 1, TRUE, FALSE, NULL },
  { "sensor", "system-gain", T_DOUBLE, F (system_gain), "0.25", 0, 100, TRUE, FALSE, NULL },
  { "sensor", "read-noise-e", T_DOUBLE, F (read_noise_e), "6", 0, 1000, FALSE, FALSE, NULL },
  { "sensor", "dark-current-e-per-s", T_DOUBLE, F (dark_current_e_s), "20", 0, 1e6, FALSE, FALSE, NULL },
  { "sensor", "full-well-e", T_DOUBLE, F (full_well_e), "20000", 1, 1e7, FALSE, FALSE, NULL },
  { "sensor", "exposure-us", T_DOUBLE, F (exposure_us), "5000", 1, 1e7, FALSE, FALSE, NULL },
  { "illuminator", "pattern", T_CHOICE, F (sine), "square", 0, 0, FALSE, FALSE, "square|sine" },
  { "illuminator", "period-px", T_DOUBLE, F (period_px), NULL, 2, 1e5, FALSE, FALSE, NULL },
  { "illuminator", "duty", T_DOUBLE, F (duty), "0.5", 0, 1, TRUE, TRUE, NULL },
  { "illuminator", "black-level", T_DOUBLE, F (black_level), "0", 0, 1, FALSE, TRUE, NULL },
  { "illuminator", "edge-blur-px", T_DOUBLE, F (edge_blur_px), "0", 0, 100, FALSE, FALSE, NULL },
  { "illuminator", "irradiance", T_DOUBLE, F (irradiance), NULL, 0, 1e6, TRUE, FALSE, NULL },
  { "illuminator", "wavelength-nm", T_DOUBLE, F (wavelength_nm), "850", 300, 3000, FALSE, FALSE, NULL },
  { "medium", "thickness-mm", T_DOUBLE, F (thickness_mm), NULL, 0, 1e3, TRUE, FALSE, NULL },
  { "medium", "mua", T_DOUBLE, F (mua), NULL, 0, 1e3, FALSE, FALSE, NULL },
  { "medium", "mus", T_DOUBLE, F (mus), NULL, 0, 1e4, FALSE, FALSE, NULL },
  { "medium", "g", T_DOUBLE, F (g), "0", -1, 1, TRUE, TRUE, NULL },
  { "medium", "n", T_DOUBLE, F (n_medium), "1.0", 1, 4, FALSE, FALSE, NULL },
  { "medium", "model", T_CHOICE, F (diffusion), "monte-carlo", 0, 0, FALSE, FALSE, "monte-carlo|diffusion" },
  { "medium", "photons", T_UINT, F (photons), "200000", 1000, 1e10, FALSE, FALSE, NULL },
  { "medium", "seed", T_UINT, F (mc_seed), "1", 0, 1e15, FALSE, FALSE, NULL },
  { "camera", "magnification", T_DOUBLE, F (magnification), "0.05", 0, 100, TRUE, FALSE, NULL },
  { "camera", "acceptance-half-angle-deg", T_DOUBLE, F (acceptance_half_angle_deg), "10", 0, 90, TRUE, FALSE, NULL },
  { "ambient", "level", T_DOUBLE, F (ambient_level), NULL, 0, 1e6, FALSE, FALSE, NULL },
};
#undef F

static const char *const object_keys[] = { "shape", "position", "size", "radius", "pitch", "line-width",
                                            "amplitude", "mask", "depth-mm", "transmittance", "velocity", NULL };
static const char *const groups[] = { "scene", "sensor", "illuminator", "medium", "camera", "ambient", NULL };

/* The line of `key` in `group` (1-based), found by scanning the text, or 0. GKeyFile does not
 * keep line numbers, and an error without one sends people hunting. */
static guint
line_of (const char *text, const char *group, const char *key)
{
  if (!text)
    return 0;
  g_auto (GStrv) lines = g_strsplit (text, "\n", -1);
  gboolean in = FALSE;
  for (guint i = 0; lines[i]; i++) {
    char *l = g_strstrip (lines[i]);
    if (l[0] == '[') {
      g_autofree char *name = g_strndup (l + 1, strcspn (l + 1, "]"));
      in = strcmp (name, group) == 0;
      if (in && !key)
        return i + 1;
      continue;
    }
    if (in && key && g_str_has_prefix (l, key)) {
      const char *rest = l + strlen (key);
      while (*rest == ' ' || *rest == '\t')
        rest++;
      if (*rest == '=')
        return i + 1;
    }
  }
  return 0;
}

static void
fail_at (GError **error, DsSimError code, const char *file, const char *text, const char *group,
         const char *key, const char *fmt, ...) G_GNUC_PRINTF (7, 8);

static void
fail_at (GError **error, DsSimError code, const char *file, const char *text, const char *group,
         const char *key, const char *fmt, ...)
{
  va_list ap;
  va_start (ap, fmt);
  g_autofree char *msg = g_strdup_vprintf (fmt, ap);
  va_end (ap);
  guint line = line_of (text, group, key);
  g_autofree char *where = line ? g_strdup_printf ("%s:%u", file, line) : g_strdup (file);
  if (key)
    g_set_error (error, DS_SIM_ERROR, code, "%s: [%s] %s: %s", where, group, key, msg);
  else
    g_set_error (error, DS_SIM_ERROR, code, "%s: [%s]: %s", where, group, msg);
}

/* Decimal notation only: [+-]digits[.digits][e[+-]digits]. strtod also reads hexadecimal
 * (0x10), inf and nan, which no scene means and the documented ranges never contain. */
static gboolean
is_decimal (const char *s)
{
  const char *p = s;
  while (*p == ' ' || *p == '\t')
    p++;
  if (*p == '+' || *p == '-')
    p++;
  gsize digits = 0;
  while (g_ascii_isdigit (*p))
    p++, digits++;
  if (*p == '.') {
    p++;
    while (g_ascii_isdigit (*p))
      p++, digits++;
  }
  if (digits == 0)
    return FALSE;
  if (*p == 'e' || *p == 'E') {
    p++;
    if (*p == '+' || *p == '-')
      p++;
    if (!g_ascii_isdigit (*p))
      return FALSE;
    while (g_ascii_isdigit (*p))
      p++;
  }
  while (*p == ' ' || *p == '\t')
    p++;
  return *p == 0;
}

static gboolean
parse_number (const char *s, double *out)
{
  if (!is_decimal (s))
    return FALSE;
  char *end = NULL;
  errno = 0;
  *out = g_ascii_strtod (s, &end);
  while (end && (*end == ' ' || *end == '\t'))
    end++;
  return errno == 0 && end && end != s && *end == 0 && isfinite (*out);
}

static gboolean
in_range (double v, double min, double max, gboolean open_min, gboolean open_max)
{
  return (open_min ? v > min : v >= min) && (open_max ? v < max : v <= max);
}

static char *
range_text (const KeySpec *k)
{
  return g_strdup_printf ("%c%g, %g%c", k->open_min ? '(' : '[', k->min, k->max, k->open_max ? ')' : ']');
}

static gboolean
set_key (DsSceneSpec *spec, const KeySpec *k, const char *value, const char *file, const char *text,
         GError **error)
{
  void *field = (char *) spec + k->offset;
  if (k->type == T_CHOICE) {
    g_auto (GStrv) ch = g_strsplit (k->choices, "|", -1);
    for (guint i = 0; ch[i]; i++)
      if (strcmp (value, ch[i]) == 0) {
        *(gboolean *) field = i != 0;
        return TRUE;
      }
    fail_at (error, DS_SIM_ERROR_INVALID, file, text, k->group, k->key, "\"%s\" is not one of %s",
             value, k->choices);
    return FALSE;
  }
  double v;
  if (!parse_number (value, &v)) {
    fail_at (error, DS_SIM_ERROR_PARSE, file, text, k->group, k->key, "\"%s\" is not a number", value);
    return FALSE;
  }
  if (!in_range (v, k->min, k->max, k->open_min, k->open_max) || (k->type == T_UINT && v != floor (v))) {
    g_autofree char *r = range_text (k);
    fail_at (error, DS_SIM_ERROR_INVALID, file, text, k->group, k->key, "%s is outside %s%s", value, r,
             k->type == T_UINT ? " (whole numbers)" : "");
    return FALSE;
  }
  if (k->type == T_UINT) {
    if (k->offset == offsetof (DsSceneSpec, photons) || k->offset == offsetof (DsSceneSpec, mc_seed))
      *(guint64 *) field = (guint64) v;
    else
      *(guint *) field = (guint) v;
  } else
    *(double *) field = v;
  return TRUE;
}

/* "a;b" (GKeyFile list syntax, ',' also accepted) into two finite numbers. */
static gboolean
parse_pair (const char *v, double *a, double *b)
{
  g_auto (GStrv) parts = g_strsplit_set (v, ";,", -1);
  guint n = 0;
  double vals[2] = { 0, 0 };
  for (guint i = 0; parts[i]; i++) {
    g_strstrip (parts[i]);
    if (!parts[i][0] && !parts[i + 1])
      break; /* trailing separator */
    if (n == 2 || !parse_number (parts[i], &vals[n]))
      return FALSE;
    n++;
  }
  *a = vals[0];
  *b = vals[1];
  return n == 2;
}

/* The fastest an object may move: a million pixels per second crosses the largest sensor in
 * 16 ms, faster than any frame; larger values are typing errors. */
#define DS_SCENE_MAX_SPEED_PX_S 1e6

/* velocity = VX, VY in px/s on the sensor (GKeyFile's ';' also accepted). */
static gboolean
parse_velocity (GKeyFile *kf, const char *group, const char *file, const char *text, DsSceneObject *o,
                GError **error)
{
  g_autofree char *v = g_key_file_get_value (kf, group, "velocity", NULL);
  if (!v)
    return TRUE;
  double a, b;
  if (!parse_pair (v, &a, &b) || fabs (a) > DS_SCENE_MAX_SPEED_PX_S || fabs (b) > DS_SCENE_MAX_SPEED_PX_S) {
    fail_at (error, DS_SIM_ERROR_INVALID, file, text, group, "velocity",
             "\"%s\" is not two numbers VX, VY in px/s with |value| <= %g", g_strstrip (v), DS_SCENE_MAX_SPEED_PX_S);
    return FALSE;
  }
  o->vx = a;
  o->vy = b;
  return TRUE;
}

static gboolean
parse_object (DsSceneSpec *spec, GKeyFile *kf, const char *group, const char *file, const char *text,
              DsSceneObject *o, GError **error)
{
  g_auto (GStrv) ks = g_key_file_get_keys (kf, group, NULL, NULL);
  for (guint i = 0; ks && ks[i]; i++)
    if (!g_strv_contains (object_keys, ks[i])) {
      fail_at (error, DS_SIM_ERROR_PARSE, file, text, group, ks[i], "unknown key (keys: shape, position, "
               "size, radius, pitch, line-width, amplitude, mask, depth-mm, transmittance, velocity)");
      return FALSE;
    }
  o->name = g_strdup (group + strlen ("object."));
  if (!*o->name) {
    fail_at (error, DS_SIM_ERROR_PARSE, file, text, group, NULL, "an object needs a name: [object.NAME]");
    return FALSE;
  }
  g_autofree char *shape = g_key_file_get_value (kf, group, "shape", NULL);
  if (!shape) {
    fail_at (error, DS_SIM_ERROR_PARSE, file, text, group, NULL, "missing key shape (rect|disc|grid|lines|mask)");
    return FALSE;
  }
  g_strstrip (shape);
  static const char *const shapes[] = { "rect", "disc", "grid", "lines", "mask", NULL };
  guint si = 0;
  while (shapes[si] && strcmp (shapes[si], shape) != 0)
    si++;
  if (!shapes[si]) {
    fail_at (error, DS_SIM_ERROR_INVALID, file, text, group, "shape", "\"%s\" is not one of rect|disc|grid|lines|mask",
             shape);
    return FALSE;
  }
  o->shape = (DsShape) si;
  /* Which keys each shape needs; a key a shape does not use is an error, not silently ignored. */
  struct {
    const char *key;
    guint shapes_required, shapes_allowed; /* bit masks over DsShape */
  } use[] = {
    { "position", 1u << DS_SHAPE_RECT | 1u << DS_SHAPE_DISC, 1u << DS_SHAPE_RECT | 1u << DS_SHAPE_DISC },
    { "size", 1u << DS_SHAPE_RECT, 1u << DS_SHAPE_RECT },
    { "radius", 1u << DS_SHAPE_DISC, 1u << DS_SHAPE_DISC },
    { "pitch", 1u << DS_SHAPE_GRID | 1u << DS_SHAPE_LINES, 1u << DS_SHAPE_GRID | 1u << DS_SHAPE_LINES },
    { "line-width", 0, 1u << DS_SHAPE_GRID | 1u << DS_SHAPE_LINES },
    { "amplitude", 0, 1u << DS_SHAPE_LINES },
    { "mask", 1u << DS_SHAPE_MASK, 1u << DS_SHAPE_MASK },
    /* A mask is an image of the sensor's size: moving it would need the scene beyond it. */
    { "velocity", 0, ~(1u << DS_SHAPE_MASK) },
  };
  for (guint i = 0; i < G_N_ELEMENTS (use); i++) {
    gboolean has = g_key_file_has_key (kf, group, use[i].key, NULL);
    if (!has && (use[i].shapes_required & (1u << si))) {
      fail_at (error, DS_SIM_ERROR_PARSE, file, text, group, NULL, "missing key %s (needed by shape %s)",
               use[i].key, shape);
      return FALSE;
    }
    if (has && !(use[i].shapes_allowed & (1u << si))) {
      fail_at (error, DS_SIM_ERROR_PARSE, file, text, group, use[i].key, "not used by shape %s", shape);
      return FALSE;
    }
  }
  const char *pair_keys[] = { "position", "size" };
  double *pair_fields[][2] = { { &o->x, &o->y }, { &o->width, &o->height } };
  for (guint i = 0; i < G_N_ELEMENTS (pair_keys); i++) {
    g_autofree char *v = g_key_file_get_value (kf, group, pair_keys[i], NULL);
    if (!v)
      continue;
    double a, b;
    if (!parse_pair (v, &a, &b) || fabs (a) > 1e6 || fabs (b) > 1e6 || (i == 1 && (a <= 0 || b <= 0))) {
      fail_at (error, DS_SIM_ERROR_INVALID, file, text, group, pair_keys[i],
               "\"%s\" is not two numbers X;Y in px%s", v, i == 1 ? ", both > 0" : ", |value| <= 1e6");
      return FALSE;
    }
    *pair_fields[i][0] = a;
    *pair_fields[i][1] = b;
  }
  if (!parse_velocity (kf, group, file, text, o, error))
    return FALSE;
  struct {
    const char *key;
    double *field;
    double def, min, max;
  } nums[] = {
    { "radius", &o->radius, 0, 0, 1e6 },
    { "pitch", &o->pitch, 0, 1, 1e6 },
    { "line-width", &o->line_width, 1, 0, 1e6 },
    { "amplitude", &o->amplitude, 0, 0, 1e6 },
    { "depth-mm", &o->depth_mm, -1, 0, 1e3 },
    { "transmittance", &o->transmittance, 0, 0, 1 },
  };
  for (guint i = 0; i < G_N_ELEMENTS (nums); i++) {
    g_autofree char *v = g_key_file_get_value (kf, group, nums[i].key, NULL);
    if (!v) {
      *nums[i].field = nums[i].def;
      continue;
    }
    double d;
    if (!parse_number (v, &d) || d < nums[i].min || d > nums[i].max) {
      fail_at (error, DS_SIM_ERROR_INVALID, file, text, group, nums[i].key, "\"%s\" is outside [%g, %g]",
               g_strstrip (v), nums[i].min, nums[i].max);
      return FALSE;
    }
    *nums[i].field = d;
  }
  if (si == DS_SHAPE_MASK) {
    g_autofree char *m = g_key_file_get_value (kf, group, "mask", NULL);
    g_strstrip (m);
    if (g_path_is_absolute (m))
      o->mask_path = g_strdup (m);
    else {
      g_autofree char *dir = g_path_get_dirname (file);
      o->mask_path = g_build_filename (dir, m, NULL);
    }
  }
  if (o->depth_mm < 0)
    o->depth_mm = spec->has_medium ? spec->thickness_mm / 2 : 0;
  if (spec->has_medium && o->depth_mm > spec->thickness_mm) {
    fail_at (error, DS_SIM_ERROR_INVALID, file, text, group, "depth-mm",
             "%g mm is outside the medium [0, %g] mm", o->depth_mm, spec->thickness_mm);
    return FALSE;
  }
  return TRUE;
}

/* Objects at up to DS_SCENE_MAX_DEPTHS depths inside the medium: the scattering stage follows
 * the light from plane to plane (docs/scene-format.md, "Objects inside the medium"). */
static gboolean
check_depths (const DsSceneSpec *spec, GPtrArray *objs, const char *file, const char *text, GError **error)
{
  double depths[DS_SCENE_MAX_DEPTHS];
  guint n_depths = 0;
  for (guint i = 0; spec->has_medium && i < objs->len; i++) {
    const DsSceneObject *o = g_ptr_array_index (objs, i);
    if (o->depth_mm <= 0 || o->depth_mm >= spec->thickness_mm)
      continue;
    gboolean seen = FALSE;
    for (guint j = 0; j < n_depths && !seen; j++)
      seen = fabs (depths[j] - o->depth_mm) <= DS_SCENE_DEPTH_TOLERANCE_MM;
    if (seen)
      continue;
    if (n_depths == DS_SCENE_MAX_DEPTHS) {
      g_autofree char *grp = g_strconcat ("object.", o->name, NULL);
      g_autoptr (GString) list = g_string_new (NULL);
      for (guint j = 0; j < n_depths; j++)
        g_string_append_printf (list, "%s%g", j ? ", " : "", depths[j]);
      fail_at (error, DS_SIM_ERROR_INVALID, file, text, grp, "depth-mm",
               "%g mm would be a depth beyond the %u allowed inside the medium (%s mm; the faces 0 and %g "
               "do not count)", o->depth_mm, DS_SCENE_MAX_DEPTHS, list->str, spec->thickness_mm);
      return FALSE;
    }
    depths[n_depths++] = o->depth_mm;
  }
  return TRUE;
}

static DsScene *
load (GKeyFile *kf, const char *file, const char *text, GError **error)
{
  g_autoptr (GPtrArray) objs = g_ptr_array_new ();
  DsScene *scene = g_new0 (DsScene, 1);
  DsSceneSpec *spec = &scene->spec;
  spec->path = g_strdup (file);
  g_auto (GStrv) gs = g_key_file_get_groups (kf, NULL);
  for (guint i = 0; gs[i]; i++)
    if (!g_strv_contains (groups, gs[i]) && !g_str_has_prefix (gs[i], "object.")) {
      fail_at (error, DS_SIM_ERROR_PARSE, file, text, gs[i], NULL,
               "unknown group (groups: scene, sensor, illuminator, medium, camera, ambient, object.NAME)");
      goto fail;
    }
  if (!g_key_file_has_group (kf, "sensor") || !g_key_file_has_group (kf, "illuminator")) {
    g_set_error (error, DS_SIM_ERROR, DS_SIM_ERROR_PARSE, "%s: [sensor] and [illuminator] are required", file);
    goto fail;
  }
  spec->has_medium = g_key_file_has_group (kf, "medium");
  spec->has_ambient = g_key_file_has_group (kf, "ambient");
  spec->name = g_key_file_get_string (kf, "scene", "name", NULL);
  if (g_key_file_has_group (kf, "scene")) {
    g_auto (GStrv) ks = g_key_file_get_keys (kf, "scene", NULL, NULL);
    for (guint i = 0; ks && ks[i]; i++)
      if (strcmp (ks[i], "name") != 0 && strcmp (ks[i], "description") != 0 && strcmp (ks[i], "max-render-s") != 0) {
        fail_at (error, DS_SIM_ERROR_PARSE, file, text, "scene", ks[i],
                 "unknown key (keys: name, description, max-render-s)");
        goto fail;
      }
  }
  for (const char *const *g = groups + 1; *g; g++) {
    if (!g_key_file_has_group (kf, *g))
      continue;
    g_auto (GStrv) ks = g_key_file_get_keys (kf, *g, NULL, NULL);
    for (guint i = 0; ks && ks[i]; i++) {
      gboolean known = FALSE;
      for (guint k = 0; k < G_N_ELEMENTS (keys) && !known; k++)
        known = strcmp (keys[k].group, *g) == 0 && strcmp (keys[k].key, ks[i]) == 0;
      if (!known) {
        fail_at (error, DS_SIM_ERROR_PARSE, file, text, *g, ks[i], "unknown key");
        goto fail;
      }
    }
  }
  for (guint k = 0; k < G_N_ELEMENTS (keys); k++) {
    const KeySpec *ks = &keys[k];
    gboolean group_present = g_key_file_has_group (kf, ks->group);
    g_autofree char *v = group_present ? g_key_file_get_value (kf, ks->group, ks->key, NULL) : NULL;
    if (v)
      g_strstrip (v);
    if (!v && !ks->def) {
      if (!group_present && (strcmp (ks->group, "medium") == 0 || strcmp (ks->group, "ambient") == 0))
        continue; /* an optional group left out: clear air, no ambient light */
      g_autofree char *r = range_text (ks);
      fail_at (error, DS_SIM_ERROR_PARSE, file, text, ks->group, NULL, "missing required key %s (allowed %s)",
               ks->key, r);
      goto fail;
    }
    if (!set_key (spec, ks, v ? v : ks->def, file, text, error))
      goto fail;
  }
  if (spec->has_medium && spec->mua + spec->mus <= 0) {
    fail_at (error, DS_SIM_ERROR_INVALID, file, text, "medium", NULL,
             "mua + mus must be > 0 (leave out [medium] for clear air)");
    goto fail;
  }
  if (spec->period_px > spec->width) {
    fail_at (error, DS_SIM_ERROR_INVALID, file, text, "illuminator", "period-px",
             "%g px is wider than the sensor (%u px)", spec->period_px, spec->width);
    goto fail;
  }
  for (guint i = 0; gs[i]; i++)
    if (g_str_has_prefix (gs[i], "object.")) {
      DsSceneObject *o = g_new0 (DsSceneObject, 1);
      g_ptr_array_add (objs, o);
      if (!parse_object (spec, kf, gs[i], file, text, o, error))
        goto fail;
    }
  if (!check_depths (spec, objs, file, text, error))
    goto fail;
  spec->n_objects = objs->len;
  spec->objects = g_new0 (DsSceneObject, MAX (1u, objs->len));
  for (guint i = 0; i < objs->len; i++) {
    spec->objects[i] = *(DsSceneObject *) g_ptr_array_index (objs, i);
    g_free (g_ptr_array_index (objs, i));
  }
  g_ptr_array_set_size (objs, 0);
  if (!spec->name)
    spec->name = g_path_get_basename (file);
  return scene;
fail:
  for (guint i = 0; i < objs->len; i++) {
    DsSceneObject *o = g_ptr_array_index (objs, i);
    g_free (o->name);
    g_free (o->mask_path);
    g_free (o);
  }
  ds_scene_free (scene);
  return NULL;
}

DsScene *
ds_scene_load_data (const char *data, gsize length, const char *name, GError **error)
{
  if (!name)
    name = "(scene text)";
  if (!data) {
    g_set_error (error, DS_SIM_ERROR, DS_SIM_ERROR_PARSE, "%s: no text", name);
    return NULL;
  }
  g_autoptr (GKeyFile) kf = g_key_file_new ();
  g_autofree char *text = g_strndup (data, length);
  g_autoptr (GError) local = NULL;
  if (!g_key_file_load_from_data (kf, text, length, G_KEY_FILE_NONE, &local)) {
    g_set_error (error, DS_SIM_ERROR, DS_SIM_ERROR_PARSE, "%s: %s", name, local->message);
    return NULL;
  }
  return load (kf, name, text, error);
}

DsScene *
ds_scene_load (const char *path, GError **error)
{
  g_autofree char *text = NULL;
  gsize len = 0;
  g_autoptr (GError) local = NULL;
  if (!g_file_get_contents (path, &text, &len, &local)) {
    g_set_error (error, DS_SIM_ERROR, DS_SIM_ERROR_IO, "scene %s: %s", path, local->message);
    return NULL;
  }
  return ds_scene_load_data (text, len, path, error);
}

void
ds_scene_free (DsScene *scene)
{
  if (!scene)
    return;
  for (guint i = 0; i < scene->spec.n_objects; i++) {
    g_free (scene->spec.objects[i].name);
    g_free (scene->spec.objects[i].mask_path);
  }
  g_free (scene->spec.objects);
  g_free (scene->spec.name);
  g_free (scene->spec.path);
  g_free (scene);
}

const DsSceneSpec *ds_scene_spec (const DsScene *s) { return &s->spec; }
guint ds_scene_width (const DsScene *s) { return s->spec.width; }
guint ds_scene_height (const DsScene *s) { return s->spec.height; }
guint ds_scene_bit_depth (const DsScene *s) { return s->spec.bit_depth; }
double ds_scene_period_px (const DsScene *s) { return s->spec.period_px; }
double ds_scene_duty (const DsScene *s) { return s->spec.duty; }
double ds_scene_black_level (const DsScene *s) { return s->spec.black_level; }
gboolean ds_scene_pattern_is_sine (const DsScene *s) { return s->spec.sine; }
double ds_scene_edge_blur_px (const DsScene *s) { return s->spec.edge_blur_px; }
double ds_scene_pattern_aperture_px (const DsScene *s) { return s->spec.sine ? 0.0 : 1.0; }
double ds_scene_system_gain (const DsScene *s) { return s->spec.system_gain; }
double ds_scene_read_noise_dn (const DsScene *s) { return s->spec.read_noise_e * s->spec.system_gain; }
double ds_scene_default_exposure_us (const DsScene *s) { return s->spec.exposure_us; }
gboolean ds_scene_object_moves (const DsSceneObject *o) { return o->vx != 0 || o->vy != 0; }

gboolean
ds_scene_has_motion (const DsScene *scene)
{
  for (guint i = 0; i < scene->spec.n_objects; i++)
    if (ds_scene_object_moves (&scene->spec.objects[i]))
      return TRUE;
  return FALSE;
}

gboolean
ds_scene_check_files (const DsScene *scene, GError **error)
{
  const DsSceneSpec *sp = ds_scene_spec (scene);
  for (guint i = 0; i < sp->n_objects; i++) {
    const DsSceneObject *o = &sp->objects[i];
    if (o->shape != DS_SHAPE_MASK)
      continue;
    g_autoptr (GError) local = NULL;
    g_autoptr (DsImage) m = ds_image_read (o->mask_path, &local);
    if (!m) {
      g_set_error (error, DS_SIM_ERROR, DS_SIM_ERROR_IO, "[object.%s] mask: %s", o->name, local->message);
      return FALSE;
    }
    if (m->width != sp->width || m->height != sp->height) {
      g_set_error (error, DS_SIM_ERROR, DS_SIM_ERROR_INVALID, "[object.%s] mask %s is %ux%u, the sensor %ux%u",
                   o->name, o->mask_path, m->width, m->height, sp->width, sp->height);
      return FALSE;
    }
  }
  return TRUE;
}

DsScene *
ds_scene_copy (const DsScene *scene)
{
  DsScene *c = g_new0 (DsScene, 1);
  c->spec = scene->spec;
  c->spec.name = g_strdup (scene->spec.name);
  c->spec.path = g_strdup (scene->spec.path);
  c->spec.objects = g_new0 (DsSceneObject, MAX (1u, scene->spec.n_objects));
  for (guint i = 0; i < scene->spec.n_objects; i++) {
    c->spec.objects[i] = scene->spec.objects[i];
    c->spec.objects[i].name = g_strdup (scene->spec.objects[i].name);
    c->spec.objects[i].mask_path = g_strdup (scene->spec.objects[i].mask_path);
  }
  return c;
}

DsScene *
ds_scene_copy_resized (const DsScene *scene, guint width, guint height)
{
  DsScene *c = ds_scene_copy (scene);
  double fx = (double) width / scene->spec.width, fy = (double) height / scene->spec.height;
  c->spec.width = width;
  c->spec.height = height;
  for (guint i = 0; i < c->spec.n_objects; i++) {
    DsSceneObject *o = &c->spec.objects[i];
    o->x *= fx;
    o->y *= fy;
    o->width *= fx;
    o->height *= fy;
    o->radius *= MIN (fx, fy);
    o->vx *= fx;
    o->vy *= fy;
  }
  return c;
}

double
ds_scene_object_pitch_mm (const DsScene *s)
{
  return s->spec.pixel_pitch_um * 1e-3 / s->spec.magnification;
}

double
ds_scene_open_field_dn_per_ms (const DsScene *s)
{
  double pitch_um = ds_scene_object_pitch_mm (s) * 1000;
  return s->spec.irradiance * pitch_um * pitch_um * s->spec.quantum_efficiency * s->spec.system_gain;
}
