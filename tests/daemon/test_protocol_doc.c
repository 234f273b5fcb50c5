/* docs/protocol.md, "Result settings", against what the daemon emits: every key of a result's
 * `settings` (ds_capture_settings_to_json, the one builder of it) is documented in that table,
 * every key the table lists is emitted, and the keys the table calls optional are exactly those
 * a set without calibration, clip level or automatic operating point leaves out. The table is
 * read from the source tree, so a field added without its line fails here. */
#include <glib.h>
#include <json-glib/json-glib.h>
#include <string.h>

#include "daemon/acquire/capture_settings.h"

typedef struct {
  GHashTable *keys;     /* dotted path -> "optional" or "" */
} DocTable;

static void
doc_table_load (DocTable *t)
{
  g_autofree char *path = g_build_filename (DS_SOURCE_DIR, "docs", "protocol.md", NULL);
  g_autofree char *text = NULL;
  g_autoptr (GError) error = NULL;
  g_assert_true (g_file_get_contents (path, &text, NULL, &error));
  g_assert_no_error (error);
  const char *start = strstr (text, "\n### Result settings\n");
  g_assert_nonnull (start);
  start += 1;
  const char *end = strstr (start + 4, "\n### ");
  g_autofree char *section = end ? g_strndup (start, (gsize) (end - start)) : g_strdup (start);
  t->keys = g_hash_table_new_full (g_str_hash, g_str_equal, g_free, g_free);
  g_auto (GStrv) lines = g_strsplit (section, "\n", -1);
  for (guint i = 0; lines[i]; i++) {
    /* | `key` | meaning | */
    if (!g_str_has_prefix (lines[i], "| `"))
      continue;
    const char *k = lines[i] + 3, *close = strchr (k, '`');
    g_assert_nonnull (close);
    const char *meaning = strstr (close, "| ");
    g_assert_nonnull (meaning);
    char *key = g_strndup (k, (gsize) (close - k));
    g_assert_false (g_hash_table_contains (t->keys, key));
    g_hash_table_insert (t->keys, key, g_strdup (g_str_has_prefix (meaning + 2, "optional") ? "optional" : ""));
  }
  g_assert_cmpuint (g_hash_table_size (t->keys), >, 10);
}

/* Dotted paths of every member, objects descended into (arrays are one key). */
static void
collect (JsonObject *o, const char *prefix, GHashTable *out)
{
  g_autoptr (GList) members = json_object_get_members (o);
  for (GList *l = members; l; l = l->next) {
    const char *name = l->data;
    char *path = prefix ? g_strdup_printf ("%s.%s", prefix, name) : g_strdup (name);
    JsonNode *n = json_object_get_member (o, name);
    if (JSON_NODE_HOLDS_OBJECT (n))
      collect (json_node_get_object (n), path, out);
    g_hash_table_add (out, path);
  }
}

static GHashTable *
emitted (const DsCaptureSettings *s)
{
  g_autoptr (JsonNode) node = ds_capture_settings_to_json (s);
  g_assert_true (JSON_NODE_HOLDS_OBJECT (node));
  GHashTable *keys = g_hash_table_new_full (g_str_hash, g_str_equal, g_free, NULL);
  collect (json_node_get_object (node), NULL, keys);
  return keys;
}

static void
plain_settings (DsCaptureSettings *s)
{
  memset (s, 0, sizeof *s);
  s->phases = 8;
  s->averages = 1;
  s->exposure_us = 5000;
  s->estimator = DS_ESTIMATOR_MAXMIN;
  s->pattern = DS_PATTERN_SQUARE;
  s->period_px = 8;
  s->duty = 0.5;
  s->phase_tolerance_deg = 20;
}

static void
test_settings_documented (void)
{
  DocTable doc;
  doc_table_load (&doc);

  /* Everything on: calibration, clip level, an automatic choice whose prediction is a lower
   * bound and rests on an assumed blur (so the lists are not empty). */
  DsCaptureSettings full;
  plain_settings (&full);
  full.harmonic_gain = 0.9;
  full.edge_blur_known = TRUE;
  full.edge_blur_px = 0.5;
  full.open_field_dn_per_ms = 250;
  full.acceptance_half_angle_deg = 7.5;
  full.saturation_dn = 4000;
  full.system_gain = 0.5; /* the camera's noise model */
  full.read_noise_dn = 2;
  full.roi_width = 64; /* a result's region, as the set runner fills it in */
  full.roi_height = 48;
  full.per_frame = TRUE; /* continuous mode's per-frame results */
  full.single_frame = TRUE; /* settings.single_frame and its window */
  full.automatic = TRUE;
  full.target_error = 0.05;
  full.operating.target_error = 0.05;
  full.operating.scale = 1;
  full.operating.probe.geometry.period_px = 8;
  full.operating.probe.blur.source = DS_BLUR_ASSUMED_SHARP;
  g_strlcpy (full.operating.probe.leak.note, "not measured (fixed by the test)", sizeof full.operating.probe.leak.note);
  g_autoptr (GHashTable) all = emitted (&full);

  GHashTableIter it;
  gpointer key, value;
  g_hash_table_iter_init (&it, all);
  while (g_hash_table_iter_next (&it, &key, NULL))
    if (!g_hash_table_contains (doc.keys, key))
      g_error ("settings.%s is emitted but not in docs/protocol.md, \"Result settings\"", (const char *) key);
  g_hash_table_iter_init (&it, doc.keys);
  while (g_hash_table_iter_next (&it, &key, NULL))
    if (!g_hash_table_contains (all, key))
      g_error ("docs/protocol.md, \"Result settings\" lists %s, which the daemon does not emit", (const char *) key);

  /* Nothing optional: exactly the keys the table calls optional (and what is under them) go. */
  DsCaptureSettings plain;
  plain_settings (&plain);
  g_autoptr (GHashTable) some = emitted (&plain);
  g_hash_table_iter_init (&it, doc.keys);
  while (g_hash_table_iter_next (&it, &key, &value)) {
    gboolean optional = strcmp (value, "optional") == 0;
    g_autofree char *parent = g_strdup (key);
    char *dot = strchr (parent, '.');
    if (dot)
      *dot = '\0';
    gboolean under_optional = dot && strcmp (g_hash_table_lookup (doc.keys, parent), "optional") == 0;
    if (optional || under_optional)
      g_assert_false (g_hash_table_contains (some, key));
    else if (!g_hash_table_contains (some, key))
      g_error ("settings.%s is left out of a plain set's settings but not marked optional in docs/protocol.md",
               (const char *) key);
  }
  g_hash_table_unref (doc.keys);
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  g_test_add_func ("/protocol-doc/result-settings", test_settings_documented);
  return g_test_run ();
}
