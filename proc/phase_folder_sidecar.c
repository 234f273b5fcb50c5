/* frames.json, the phase folder's sidecar (docs/phase-folder.md): parsed and checked against
 * the folder; every refusal names the key (and the file). */
#include <json-glib/json-glib.h>
#include <math.h>
#include <string.h>

#include "proc/phase_folder.h"
#include "proc/proc_error.h"

typedef struct {
  const char *path;
  GError **error;
} Ctx;

static gboolean
fail (Ctx *c, const char *key, const char *fmt, ...) G_GNUC_PRINTF (3, 4);

static gboolean
fail (Ctx *c, const char *key, const char *fmt, ...)
{
  va_list ap;
  va_start (ap, fmt);
  g_autofree char *what = g_strdup_vprintf (fmt, ap);
  va_end (ap);
  g_set_error (c->error, DS_PROC_ERROR, DS_PROC_ERROR_FORMAT, "%s: key \"%s\": %s", c->path, key, what);
  return FALSE;
}

static gboolean
is_number (JsonNode *n)
{
  if (!n || !JSON_NODE_HOLDS_VALUE (n))
    return FALSE;
  GType t = json_node_get_value_type (n);
  return t == G_TYPE_INT64 || t == G_TYPE_DOUBLE;
}

/* A number member; absent: *out = fallback, TRUE unless required. */
static gboolean
get_number (Ctx *c, JsonObject *o, const char *name, const char *key, gboolean required,
            double fallback, double *out)
{
  JsonNode *n = o ? json_object_get_member (o, name) : NULL;
  if (!n || JSON_NODE_HOLDS_NULL (n)) {
    *out = fallback;
    return required ? fail (c, key, "missing") : TRUE;
  }
  if (!is_number (n))
    return fail (c, key, "not a number");
  *out = json_node_get_double (n);
  if (!isfinite (*out))
    return fail (c, key, "not a finite number");
  return TRUE;
}

static gboolean
get_uint (Ctx *c, JsonObject *o, const char *name, const char *key, gboolean required, guint lo,
          guint hi, guint *out)
{
  double v = NAN; /* GCC at -O3 cannot see that every failing path of get_number returns FALSE */
  if (!get_number (c, o, name, key, required, NAN, &v))
    return FALSE;
  if (isnan (v))
    return TRUE;
  if (v != floor (v) || v < lo || v > hi)
    return fail (c, key, "%g is not a whole number in %u..%u", v, lo, hi);
  *out = (guint) v;
  return TRUE;
}

static const char *
get_string (JsonObject *o, const char *name)
{
  JsonNode *n = o ? json_object_get_member (o, name) : NULL;
  return n && JSON_NODE_HOLDS_VALUE (n) && json_node_get_value_type (n) == G_TYPE_STRING
           ? json_node_get_string (n)
           : NULL;
}

static JsonObject *
get_object (JsonObject *o, const char *name)
{
  JsonNode *n = o ? json_object_get_member (o, name) : NULL;
  return n && JSON_NODE_HOLDS_OBJECT (n) ? json_node_get_object (n) : NULL;
}

/* A plain file name in the folder that exists. */
static gboolean
check_file (Ctx *c, DsPhaseFolder *f, const char *key, const char *name)
{
  if (!name || !*name || strchr (name, '/') || strcmp (name, ".") == 0 || strcmp (name, "..") == 0)
    return fail (c, key, "\"%s\" is not a file name in the folder", name ? name : "");
  g_autofree char *p = g_build_filename (f->dir, name, NULL);
  if (!g_file_test (p, G_FILE_TEST_IS_REGULAR))
    return fail (c, key, "names %s, which is not in the folder", name);
  return TRUE;
}

static gboolean
read_pattern (Ctx *c, DsPhaseFolderSidecar *sc, JsonObject *root)
{
  JsonObject *pat = get_object (root, "pattern");
  if (!pat)
    return TRUE;
  const char *kind = get_string (pat, "kind");
  if (kind) {
    if (strcmp (kind, "square") == 0)
      sc->pattern_kind = DS_PATTERN_SQUARE;
    else if (strcmp (kind, "sine") == 0)
      sc->pattern_kind = DS_PATTERN_SINE;
    else
      return fail (c, "pattern.kind", "\"%s\" is neither square nor sine", kind);
    sc->has_pattern_kind = TRUE;
  }
  if (!get_number (c, pat, "period_px", "pattern.period_px", FALSE, NAN, &sc->period_px) ||
      !get_number (c, pat, "duty", "pattern.duty", FALSE, NAN, &sc->duty) ||
      !get_number (c, pat, "black_level", "pattern.black_level", FALSE, NAN, &sc->black_level) ||
      !get_number (c, pat, "edge_blur_px", "pattern.edge_blur_px", FALSE, NAN, &sc->edge_blur_px) ||
      !get_number (c, pat, "harmonic_gain", "pattern.harmonic_gain", FALSE, NAN, &sc->harmonic_gain))
    return FALSE;
  if (!isnan (sc->harmonic_gain) && !(sc->harmonic_gain > 0 && sc->harmonic_gain <= 1))
    return fail (c, "pattern.harmonic_gain", "%g is outside (0, 1]", sc->harmonic_gain);
  if (!isnan (sc->edge_blur_px) && !(sc->edge_blur_px >= 0 && sc->edge_blur_px < 1e3))
    return fail (c, "pattern.edge_blur_px", "%g is outside [0, 1000) pixels", sc->edge_blur_px);
  if (!isnan (sc->period_px) && !(sc->period_px > 2))
    return fail (c, "pattern.period_px", "%g: a period must exceed 2 pixels", sc->period_px);
  if (!isnan (sc->duty) && !(sc->duty > 0 && sc->duty < 1))
    return fail (c, "pattern.duty", "%g is outside (0, 1)", sc->duty);
  if (!isnan (sc->black_level) && !(sc->black_level >= 0 && sc->black_level < 1))
    return fail (c, "pattern.black_level", "%g is outside [0, 1)", sc->black_level);
  double off;
  if (!get_number (c, pat, "phase_offset_cycles", "pattern.phase_offset_cycles", FALSE, NAN, &off))
    return FALSE;
  if (!isnan (off)) {
    sc->has_phase_offset = TRUE;
    sc->phase_offset_cycles = off - floor (off);
  }
  return TRUE;
}

static gboolean
read_frames (Ctx *c, DsPhaseFolder *f, JsonObject *root)
{
  JsonNode *fn = json_object_get_member (root, "frames");
  if (!fn || !JSON_NODE_HOLDS_ARRAY (fn))
    return fail (c, "frames", "missing or not a list");
  JsonArray *frames = json_node_get_array (fn);
  guint n = json_array_get_length (frames);
  g_autofree guint *per_phase = g_new0 (guint, f->n_phases);
  g_autoptr (GHashTable) seen = g_hash_table_new (g_str_hash, g_str_equal);
  for (guint i = 0; i < n; i++) {
    g_autofree char *key = g_strdup_printf ("frames[%u]", i);
    JsonNode *en = json_array_get_element (frames, i);
    JsonObject *e = JSON_NODE_HOLDS_OBJECT (en) ? json_node_get_object (en) : NULL;
    if (!e)
      return fail (c, key, "not an object");
    g_autofree char *kfile = g_strdup_printf ("%s.file", key), *kphase = g_strdup_printf ("%s.phase", key);
    const char *file = get_string (e, "file");
    if (!check_file (c, f, kfile, file))
      return FALSE;
    if (g_hash_table_contains (seen, file))
      return fail (c, kfile, "%s is listed twice", file);
    g_hash_table_add (seen, (gpointer) file);
    guint phase = 0;
    if (!get_uint (c, e, "phase", kphase, TRUE, 0, f->n_phases - 1, &phase))
      return FALSE;
    DsPhaseFolderFrame fr = { .file = g_strdup (file), .phase = phase };
    double id;
    g_autofree char *kid = g_strdup_printf ("%s.frame_id", key);
    if (!get_number (c, e, "frame_id", kid, FALSE, NAN, &id)) {
      g_free (fr.file);
      return FALSE;
    }
    if (!isnan (id) && id >= 0) {
      fr.has_frame_id = TRUE;
      fr.frame_id = (guint64) id;
    }
    g_array_append_val (f->frames, fr);
    per_phase[phase]++;
  }
  for (guint k = 0; k < f->n_phases; k++)
    if (per_phase[k] == 0)
      return fail (c, "frames", "no frame of phase %u (n_phases is %u)", k, f->n_phases);
  JsonObject *black = get_object (root, "black");
  JsonNode *bn = black ? json_object_get_member (black, "files") : NULL;
  if (black && (!bn || !JSON_NODE_HOLDS_ARRAY (bn)))
    return fail (c, "black.files", "missing or not a list");
  for (guint i = 0; bn && i < json_array_get_length (json_node_get_array (bn)); i++) {
    g_autofree char *key = g_strdup_printf ("black.files[%u]", i);
    JsonNode *e = json_array_get_element (json_node_get_array (bn), i);
    const char *file = JSON_NODE_HOLDS_VALUE (e) && json_node_get_value_type (e) == G_TYPE_STRING
                         ? json_node_get_string (e)
                         : NULL;
    if (!check_file (c, f, key, file))
      return FALSE;
    if (g_hash_table_contains (seen, file))
      return fail (c, key, "%s is also listed as a phase frame", file);
    g_ptr_array_add (f->black_files, g_strdup (file));
  }
  return TRUE;
}

gboolean
ds_phase_folder_read_sidecar (DsPhaseFolder *f, const char *path, DsSidecarReader read, GError **error)
{
  Ctx c = { path, error };
  g_autoptr (GError) local = NULL;
  g_autoptr (JsonNode) rn = read ? read (path, &local) : NULL;
  if (!rn) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_FORMAT, "%s: %s", path,
                 local ? local->message : "no JSON reader given to read it");
    return FALSE;
  }
  JsonObject *root = rn && JSON_NODE_HOLDS_OBJECT (rn) ? json_node_get_object (rn) : NULL;
  if (!root) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_FORMAT, "%s: not a JSON object", path);
    return FALSE;
  }
  const char *format = get_string (root, "format");
  if (!format || strcmp (format, "descatter-phase-folder") != 0)
    return fail (&c, "format", "\"%s\" is not descatter-phase-folder", format ? format : "");
  guint version = 0;
  if (!get_uint (&c, root, "version", "version", TRUE, 1, G_MAXUINT32, &version))
    return FALSE;
  if (version > 1)
    return fail (&c, "version", "version %u is newer than this reader (1)", version);
  DsPhaseFolderSidecar *sc = &f->sidecar;
  sc->present = TRUE;
  JsonObject *producer = get_object (root, "producer");
  sc->producer = g_strdup (get_string (producer, "program"));
  guint bit_depth = 0;
  if (!get_uint (&c, root, "width", "width", TRUE, 1, DS_IMAGE_MAX_SIDE, &sc->width) ||
      !get_uint (&c, root, "height", "height", TRUE, 1, DS_IMAGE_MAX_SIDE, &sc->height) ||
      !get_uint (&c, root, "bit_depth", "bit_depth", TRUE, 1, 32, &bit_depth) ||
      !get_uint (&c, root, "n_phases", "n_phases", TRUE, 2, DS_MAX_PHASES, &f->n_phases) ||
      !get_number (&c, root, "saturation_dn", "saturation_dn", FALSE, NAN, &sc->saturation_dn))
    return FALSE;
  if (bit_depth > 16 && bit_depth != 32)
    return fail (&c, "bit_depth", "%u: integer samples have 1..16 bits (32: float)", bit_depth);
  sc->bit_depth = bit_depth;
  f->bit_depth = bit_depth;
  if (!isnan (sc->saturation_dn) && !(sc->saturation_dn > 0))
    return fail (&c, "saturation_dn", "%g is not a positive level", sc->saturation_dn);
  sc->pixel_format = g_strdup (get_string (root, "pixel_format"));
  sc->estimator = g_strdup (get_string (get_object (root, "settings"), "estimator"));
  JsonObject *settings = get_object (root, "settings");
  JsonNode *motion = settings ? json_object_get_member (settings, "detect_motion") : NULL;
  if (motion && !JSON_NODE_HOLDS_NULL (motion)) {
    if (!JSON_NODE_HOLDS_VALUE (motion) || json_node_get_value_type (motion) != G_TYPE_BOOLEAN)
      return fail (&c, "settings.detect_motion", "not true or false");
    sc->has_detect_motion = TRUE;
    sc->detect_motion = json_node_get_boolean (motion);
  }
  return read_pattern (&c, sc, root) && read_frames (&c, f, root);
}
