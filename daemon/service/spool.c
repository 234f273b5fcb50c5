#include "daemon/service/spool.h"

#include <errno.h>
#include <glib/gstdio.h>
#include <string.h>

typedef struct {
  char *stem;      /* "set-000042-<time>" */
  guint64 bytes;
} SpoolEntry;

struct DsSpool {
  char *dir;
  guint64 max_bytes;
  guint64 bytes;
  guint64 removed;
  GQueue entries;  /* oldest first */
};

static void
entry_free (gpointer data)
{
  SpoolEntry *e = data;
  g_free (e->stem);
  g_free (e);
}

static const char *const suffixes[] = { "-transmissive.tiff", "-scattered.tiff", "-mask.png", ".json" };

static guint64
file_size (const char *path)
{
  GStatBuf st;
  return g_stat (path, &st) == 0 ? (guint64) st.st_size : 0;
}

static gint
compare_entries (gconstpointer a, gconstpointer b, gpointer user_data)
{
  (void) user_data;
  return strcmp (((const SpoolEntry *) a)->stem, ((const SpoolEntry *) b)->stem);
}

DsSpool *
ds_spool_new (const char *dir, guint64 max_bytes, GError **error)
{
  if (g_mkdir_with_parents (dir, 0750) != 0) {
    int e = errno;
    g_set_error (error, G_FILE_ERROR, g_file_error_from_errno (e), "spool %s: %s", dir,
                 g_strerror (e));
    return NULL;
  }
  g_autoptr (GDir) d = g_dir_open (dir, 0, error);
  if (!d) {
    g_prefix_error (error, "spool: ");
    return NULL;
  }
  DsSpool *spool = g_new0 (DsSpool, 1);
  spool->dir = g_strdup (dir);
  spool->max_bytes = max_bytes;
  g_queue_init (&spool->entries);
  const char *name;
  while ((name = g_dir_read_name (d))) {
    /* Only complete sets (the sidecar is written last) count; anything else is a leftover of
     * an interrupted write and is removed. */
    if (g_str_has_prefix (name, "set-") && g_str_has_suffix (name, ".json")) {
      SpoolEntry *e = g_new0 (SpoolEntry, 1);
      e->stem = g_strndup (name, strlen (name) - strlen (".json"));
      for (guint i = 0; i < G_N_ELEMENTS (suffixes); i++) {
        g_autofree char *path = g_strdup_printf ("%s/%s%s", dir, e->stem, suffixes[i]);
        e->bytes += file_size (path);
      }
      spool->bytes += e->bytes;
      g_queue_insert_sorted (&spool->entries, e, compare_entries, NULL);
    } else if (name[0] == '.' && strstr (name, ".tmp")) {
      g_autofree char *path = g_build_filename (dir, name, NULL);
      g_unlink (path);
    }
  }
  return spool;
}

void
ds_spool_free (DsSpool *spool)
{
  if (!spool)
    return;
  g_queue_clear_full (&spool->entries, entry_free);
  g_free (spool->dir);
  g_free (spool);
}

static void
remove_entry (DsSpool *spool, SpoolEntry *e)
{
  /* Sidecar first: from then on the set no longer counts as complete. */
  for (int i = (int) G_N_ELEMENTS (suffixes) - 1; i >= 0; i--) {
    g_autofree char *path = g_strdup_printf ("%s/%s%s", spool->dir, e->stem, suffixes[i]);
    g_unlink (path);
  }
  spool->bytes -= MIN (spool->bytes, e->bytes);
  spool->removed++;
  entry_free (e);
}

static gboolean
write_text_atomic (const char *path, const char *text, GError **error)
{
  /* g_file_set_contents_full with FSYNC writes a temporary file, fsyncs and renames. */
  return g_file_set_contents_full (path, text, -1,
                                   G_FILE_SET_CONTENTS_CONSISTENT | G_FILE_SET_CONTENTS_DURABLE,
                                   0640, error);
}

gboolean
ds_spool_record (DsSpool *spool, DsResult *result, GError **error)
{
  const DsSeparation *sep = ds_result_separation (result);
  g_autoptr (GDateTime) now = g_date_time_new_now_utc ();
  g_autofree char *stamp = g_date_time_format (now, "%Y%m%dT%H%M%S");
  SpoolEntry *e = g_new0 (SpoolEntry, 1);
  e->stem = g_strdup_printf ("set-%s-%06" G_GUINT64_FORMAT, stamp, ds_result_set_id (result));
  const DsImage *images[] = { sep->transmissive, sep->scattered, sep->mask };
  guint written = 0;
  for (; written < G_N_ELEMENTS (images); written++) {
    g_autofree char *path = g_strdup_printf ("%s/%s%s", spool->dir, e->stem, suffixes[written]);
    if (!ds_image_write (images[written], path, error))
      break;
    e->bytes += file_size (path);
  }
  if (written == G_N_ELEMENTS (images)) {
    g_autoptr (JsonNode) meta = ds_result_to_json (result);
    g_autofree char *text = json_to_string (meta, TRUE);
    g_autofree char *path = g_strdup_printf ("%s/%s.json", spool->dir, e->stem);
    if (write_text_atomic (path, text, error)) {
      e->bytes += file_size (path);
      spool->bytes += e->bytes;
      g_queue_push_tail (&spool->entries, e);
      while (spool->bytes > spool->max_bytes && spool->entries.length > 1)
        remove_entry (spool, g_queue_pop_head (&spool->entries));
      return TRUE;
    }
  }
  /* Leave nothing of a failed set: the images alone would look like data. */
  for (guint i = 0; i < written; i++) {
    g_autofree char *path = g_strdup_printf ("%s/%s%s", spool->dir, e->stem, suffixes[i]);
    g_unlink (path);
  }
  g_prefix_error (error, "spool: ");
  entry_free (e);
  return FALSE;
}

guint64
ds_spool_bytes (const DsSpool *spool)
{
  return spool->bytes;
}

guint64
ds_spool_sets_removed (const DsSpool *spool)
{
  return spool->removed;
}
