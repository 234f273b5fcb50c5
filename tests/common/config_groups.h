/* Tests compose configurations from snippets ("[camera]\nbackend=sim\n" plus a case's own
 * "[camera]\nroi=...\n"), and descatterd refuses a group given twice. This regroups such a text:
 * every line of a group's copies under its first header, groups in their order of first
 * appearance, lines kept verbatim (comments, duplicate or localized keys: whatever a case means
 * the daemon to see in one group). Lines before any header stay first. Header-only: any test. */
#pragma once
#include <glib.h>
#include <string.h>

static inline char *
test_config_groups_merge (const char *text)
{
  g_autoptr (GPtrArray) names = g_ptr_array_new_with_free_func (g_free);
  g_autoptr (GHashTable) body_of = g_hash_table_new_full (g_str_hash, g_str_equal, g_free, NULL);
  GPtrArray *strings = g_ptr_array_new (); /* the bodies, in the order of names */
  GString *head = g_string_new (NULL);
  GString *current = head;
  g_auto (GStrv) lines = g_strsplit (text, "\n", -1);
  for (guint i = 0; lines[i]; i++) {
    const char *l = lines[i];
    if (!lines[i + 1] && !*l)
      break; /* the split's empty tail after the last newline */
    const char *lead = l + strspn (l, " \t");
    const char *close = lead[0] == '[' ? strchr (lead, ']') : NULL;
    if (close) {
      char *name = g_strndup (lead + 1, (gsize) (close - lead - 1));
      current = g_hash_table_lookup (body_of, name);
      if (!current) {
        current = g_string_new (NULL);
        g_hash_table_insert (body_of, g_strdup (name), current);
        g_ptr_array_add (names, g_strdup (name));
        g_ptr_array_add (strings, current);
      }
      g_free (name);
      continue;
    }
    g_string_append (current, l);
    g_string_append_c (current, '\n');
  }
  GString *out = head;
  for (guint i = 0; i < names->len; i++) {
    GString *body = g_ptr_array_index (strings, i);
    g_string_append_printf (out, "[%s]\n%s", (const char *) g_ptr_array_index (names, i), body->str);
    g_string_free (body, TRUE);
  }
  g_ptr_array_free (strings, TRUE);
  return g_string_free (out, FALSE);
}
