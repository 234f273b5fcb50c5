#include "daemon/service/spool.h"

#include <errno.h>
#include <glib/gstdio.h>
#include <string.h>
#include <sys/stat.h>

#include "daemon/output/hdf5_run.h"
#include "daemon/output/output_error.h"
#include "daemon/output/result_files.h"

typedef struct {
  char *name;      /* "set-<time>-<id>" (a stem: files <name>*) or "run-<time>-<id>.h5[.partial]" */
  char *key;       /* the time-and-id part: entries sort by it, oldest first */
  gboolean is_run;
  guint64 bytes;
} SpoolEntry;

typedef enum { JOB_RECORD, JOB_END_RUN, JOB_FLUSH, JOB_QUIT } JobKind;

typedef struct {
  JobKind kind;
  DsResult *result;        /* ref; keeps the planes alive */
  DsOutputResult planes;   /* meta: a copy owned by the job */
  gboolean in_run;
  gboolean *done;          /* JOB_FLUSH: set under the lock, then signalled */
} Job;

struct DsSpool {
  char *dir;
  guint64 max_bytes;
  guint kinds;
  guint max_pending;
  GThread *thread;
  GAsyncQueue *jobs;
  GMutex lock;             /* stats and pending; cond for flushes */
  GCond cond;
  DsSpoolStats stats;
  /* Writer thread only. */
  GQueue entries;          /* SpoolEntry, oldest first */
  DsHdf5Run *run;
  SpoolEntry *run_entry;   /* in entries while the run is open */
};

static void
entry_free (gpointer data)
{
  SpoolEntry *e = data;
  g_free (e->name);
  g_free (e->key);
  g_free (e);
}

static gint
compare_entries (gconstpointer a, gconstpointer b, gpointer user_data)
{
  (void) user_data;
  return strcmp (((const SpoolEntry *) a)->key, ((const SpoolEntry *) b)->key);
}

static guint64
path_bytes (const char *path)
{
  GStatBuf st;
  if (g_lstat (path, &st) != 0)
    return 0;
  if (!S_ISDIR (st.st_mode))
    return (guint64) st.st_size;
  guint64 n = 0;
  g_autoptr (GDir) d = g_dir_open (path, 0, NULL);
  const char *name;
  while (d && (name = g_dir_read_name (d))) {
    g_autofree char *p = g_build_filename (path, name, NULL);
    n += path_bytes (p);
  }
  return n;
}

static void
remove_path (const char *path)
{
  GStatBuf st;
  if (g_lstat (path, &st) == 0 && S_ISDIR (st.st_mode)) {
    g_autoptr (GDir) d = g_dir_open (path, 0, NULL);
    const char *name;
    while (d && (name = g_dir_read_name (d))) {
      g_autofree char *p = g_build_filename (path, name, NULL);
      remove_path (p);
    }
    g_rmdir (path);
  } else
    g_unlink (path);
}

/* "set-20261125T160211Z-000042-transmissive.tiff" -> "set-20261125T160211Z-000042". */
static char *
set_stem_of (const char *name)
{
  if (!g_str_has_prefix (name, "set-"))
    return NULL;
  const char *p = name + 4;
  const char *dash = strchr (p, '-');
  if (!dash)
    return NULL;
  const char *id = dash + 1;
  gsize n = 0;
  while (g_ascii_isdigit (id[n]))
    n++;
  return n ? g_strndup (name, (gsize) (id + n - name)) : NULL;
}

/* The files of one set: <stem>.json, <stem>.h5, <stem>-*. */
static gboolean
belongs_to (const char *name, const char *stem)
{
  gsize n = strlen (stem);
  return strncmp (name, stem, n) == 0 && (name[n] == '-' || name[n] == '.');
}

static guint64
stem_bytes (const char *dir, const char *stem)
{
  guint64 n = 0;
  g_autoptr (GDir) d = g_dir_open (dir, 0, NULL);
  const char *name;
  while (d && (name = g_dir_read_name (d)))
    if (belongs_to (name, stem)) {
      g_autofree char *p = g_build_filename (dir, name, NULL);
      n += path_bytes (p);
    }
  return n;
}

static void
remove_stem (const char *dir, const char *stem)
{
  /* Sidecar first: from then on the set no longer counts as complete. */
  g_autofree char *json = g_strdup_printf ("%s/%s.json", dir, stem);
  g_unlink (json);
  g_autoptr (GDir) d = g_dir_open (dir, 0, NULL);
  g_autoptr (GPtrArray) doomed = g_ptr_array_new_with_free_func (g_free);
  const char *name;
  while (d && (name = g_dir_read_name (d)))
    if (belongs_to (name, stem))
      g_ptr_array_add (doomed, g_build_filename (dir, name, NULL));
  for (guint i = 0; i < doomed->len; i++)
    remove_path (doomed->pdata[i]);
}

static SpoolEntry *
entry_new (const char *name, gboolean is_run, guint64 bytes)
{
  SpoolEntry *e = g_new0 (SpoolEntry, 1);
  e->name = g_strdup (name);
  const char *dash = strchr (name, '-');
  e->key = g_strdup (dash ? dash + 1 : name);
  e->is_run = is_run;
  e->bytes = bytes;
  return e;
}

/* Takes stock at start-up: complete sets (with a sidecar) and runs count; files of a set
 * without its sidecar are the leftovers of an interrupted write and are removed, as are
 * hidden temporaries. */
static void
take_stock (DsSpool *spool, GDir *d)
{
  g_autoptr (GHashTable) complete = g_hash_table_new_full (g_str_hash, g_str_equal, g_free, NULL);
  g_autoptr (GPtrArray) names = g_ptr_array_new_with_free_func (g_free);
  const char *name;
  while ((name = g_dir_read_name (d))) {
    g_ptr_array_add (names, g_strdup (name));
    if (g_str_has_prefix (name, "set-") && g_str_has_suffix (name, ".json"))
      g_hash_table_add (complete, g_strndup (name, strlen (name) - strlen (".json")));
  }
  for (guint i = 0; i < names->len; i++) {
    const char *n = names->pdata[i];
    g_autofree char *path = g_build_filename (spool->dir, n, NULL);
    g_autofree char *stem = set_stem_of (n);
    if (n[0] == '.' && strstr (n, ".tmp")) {
      remove_path (path);
    } else if (g_str_has_prefix (n, "run-") && (g_str_has_suffix (n, ".h5") || g_str_has_suffix (n, ".h5.partial"))) {
      /* A .partial run is what a crash left: readable up to its last complete set, kept. */
      g_queue_insert_sorted (&spool->entries, entry_new (n, TRUE, path_bytes (path)), compare_entries, NULL);
    } else if (stem && !g_hash_table_contains (complete, stem)) {
      g_message ("spool: removing %s (its set has no sidecar: an interrupted write)", n);
      remove_path (path);
    }
  }
  GHashTableIter it;
  gpointer key;
  g_hash_table_iter_init (&it, complete);
  while (g_hash_table_iter_next (&it, &key, NULL))
    g_queue_insert_sorted (&spool->entries, entry_new (key, FALSE, stem_bytes (spool->dir, key)), compare_entries, NULL);
  for (GList *l = spool->entries.head; l; l = l->next)
    spool->stats.bytes += ((SpoolEntry *) l->data)->bytes;
}

/* ---- the writer thread ---- */

static void
set_error (DsSpool *spool, const GError *error)
{
  g_warning ("spool: %s", error->message);
  g_mutex_lock (&spool->lock);
  spool->stats.errors++;
  g_strlcpy (spool->stats.last_error, error->message, sizeof spool->stats.last_error);
  g_mutex_unlock (&spool->lock);
}

static void
add_bytes (DsSpool *spool, gint64 delta)
{
  g_mutex_lock (&spool->lock);
  spool->stats.bytes = (guint64) MAX (0, (gint64) spool->stats.bytes + delta);
  g_mutex_unlock (&spool->lock);
}

static void
evict (DsSpool *spool)
{
  for (;;) {
    g_mutex_lock (&spool->lock);
    gboolean over = spool->stats.bytes > spool->max_bytes;
    g_mutex_unlock (&spool->lock);
    if (!over)
      return;
    GList *l = spool->entries.head;
    while (l && l->data == spool->run_entry)
      l = l->next;
    /* Never the newest entry: the cap never removes what was just recorded. */
    if (!l || l == spool->entries.tail)
      return;
    SpoolEntry *e = l->data;
    g_queue_delete_link (&spool->entries, l);
    if (e->is_run) {
      g_autofree char *p = g_build_filename (spool->dir, e->name, NULL);
      g_unlink (p);
    } else
      remove_stem (spool->dir, e->name);
    add_bytes (spool, -(gint64) e->bytes);
    g_mutex_lock (&spool->lock);
    spool->stats.sets_removed++;
    g_mutex_unlock (&spool->lock);
    entry_free (e);
  }
}

static void
close_run (DsSpool *spool)
{
  if (!spool->run)
    return;
  g_autoptr (GError) error = NULL;
  g_autofree char *final = g_path_get_basename (ds_hdf5_run_path (spool->run));
  if (!ds_hdf5_run_close (spool->run, &error))
    set_error (spool, error);
  else {
    g_free (spool->run_entry->name);
    spool->run_entry->name = g_steal_pointer (&final);
  }
  spool->run = NULL;
  spool->run_entry = NULL;
  g_mutex_lock (&spool->lock);
  spool->stats.run_open = FALSE;
  g_mutex_unlock (&spool->lock);
}

static gboolean
append_to_run (DsSpool *spool, const DsOutputResult *planes, GError **error)
{
  for (guint attempt = 0; attempt < 2; attempt++) {
    if (!spool->run) {
      g_autofree char *stem = ds_result_stem (planes->meta);
      g_autofree char *name = g_strdup_printf ("run-%s.h5", stem + strlen ("set-"));
      g_autofree char *path = g_build_filename (spool->dir, name, NULL);
      spool->run = ds_hdf5_run_open (path, planes, error);
      if (!spool->run)
        return FALSE;
      g_autofree char *partial = g_path_get_basename (ds_hdf5_run_partial_path (spool->run));
      spool->run_entry = entry_new (partial, TRUE, ds_hdf5_run_bytes (spool->run));
      g_queue_push_tail (&spool->entries, spool->run_entry);
      add_bytes (spool, (gint64) spool->run_entry->bytes);
      g_mutex_lock (&spool->lock);
      spool->stats.run_open = TRUE;
      g_mutex_unlock (&spool->lock);
    }
    GError *local = NULL;
    gboolean ok = ds_hdf5_run_append (spool->run, planes, &local);
    guint64 now = ds_hdf5_run_bytes (spool->run);
    add_bytes (spool, (gint64) now - (gint64) spool->run_entry->bytes);
    spool->run_entry->bytes = now;
    if (ok)
      return TRUE;
    /* A run file HDF5 could not close after a failed write takes nothing more: it stays as
     * .partial (readable up to its last complete set) and the next set starts another run. */
    if (ds_hdf5_run_broken (spool->run)) {
      ds_hdf5_run_abandon (spool->run);
      spool->run = NULL;
      spool->run_entry = NULL;
      g_mutex_lock (&spool->lock);
      spool->stats.run_open = FALSE;
      g_mutex_unlock (&spool->lock);
    }
    /* A result of another shape starts a new run file; anything else is an error. */
    gboolean reshape = attempt == 0 && g_error_matches (local, DS_OUTPUT_ERROR, DS_OUTPUT_ERROR_INVALID);
    if (!reshape) {
      g_propagate_error (error, local);
      return FALSE;
    }
    g_error_free (local);
    close_run (spool);
  }
  return FALSE;
}

static void
record (DsSpool *spool, Job *job)
{
  g_autoptr (GError) error = NULL;
  guint kinds = spool->kinds & ~DS_FILES_HDF5_RUN;
  gboolean to_run = (spool->kinds & DS_FILES_HDF5_RUN) && job->in_run;
  if ((spool->kinds & DS_FILES_HDF5_RUN) && !job->in_run)
    kinds |= DS_FILES_HDF5; /* a capture outside a run gets a file of its own */
  if (!job->in_run)
    close_run (spool);
  /* The run file and the set's own files fail apart: a set the run file could not take (the
   * run records it as missing, with the reason) may still be recorded whole on its own. */
  gboolean ok = TRUE;
  if (to_run && !append_to_run (spool, &job->planes, &error)) {
    g_prefix_error (&error, "set %" G_GUINT64_FORMAT ": ", ds_result_set_id (job->result));
    set_error (spool, error);
    g_clear_error (&error);
    ok = FALSE;
  }
  if (kinds) {
    g_autofree char *stem = ds_result_stem (job->planes.meta);
    if (ds_result_write_files (&job->planes, spool->dir, stem, kinds, NULL, &error)) {
      SpoolEntry *e = entry_new (stem, FALSE, stem_bytes (spool->dir, stem));
      g_queue_push_tail (&spool->entries, e);
      add_bytes (spool, (gint64) e->bytes);
    } else {
      g_prefix_error (&error, "set %" G_GUINT64_FORMAT ": ", ds_result_set_id (job->result));
      set_error (spool, error);
      ok = FALSE;
    }
  }
  if (ok) {
    g_mutex_lock (&spool->lock);
    spool->stats.sets_written++;
    g_mutex_unlock (&spool->lock);
  }
  evict (spool);
}

static void
job_free (Job *job)
{
  if (job->result)
    ds_result_unref (job->result);
  if (job->planes.meta)
    json_node_unref (job->planes.meta);
  g_free (job);
}

static gpointer
writer_main (gpointer data)
{
  DsSpool *spool = data;
  for (;;) {
    Job *job = g_async_queue_pop (spool->jobs);
    JobKind kind = job->kind;
    if (kind == JOB_RECORD)
      record (spool, job);
    else if (kind == JOB_END_RUN || kind == JOB_QUIT)
      close_run (spool);
    g_mutex_lock (&spool->lock);
    if (kind == JOB_RECORD)
      spool->stats.pending--;
    if (kind == JOB_FLUSH)
      *job->done = TRUE;
    g_cond_broadcast (&spool->cond);
    g_mutex_unlock (&spool->lock);
    job_free (job);
    if (kind == JOB_QUIT)
      return NULL;
  }
}

/* ---- main thread ---- */

DsSpool *
ds_spool_new (const char *dir, guint64 max_bytes, guint kinds, guint max_pending, GError **error)
{
  if (g_mkdir_with_parents (dir, 0750) != 0) {
    int e = errno;
    g_set_error (error, G_FILE_ERROR, g_file_error_from_errno (e), "spool %s: %s", dir, g_strerror (e));
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
  spool->kinds = kinds;
  spool->max_pending = MAX (1, max_pending);
  g_queue_init (&spool->entries);
  g_mutex_init (&spool->lock);
  g_cond_init (&spool->cond);
  take_stock (spool, d);
  spool->jobs = g_async_queue_new ();
  spool->thread = g_thread_new ("spool", writer_main, spool);
  return spool;
}

static void
push (DsSpool *spool, JobKind kind, gboolean *done)
{
  Job *job = g_new0 (Job, 1);
  job->kind = kind;
  job->done = done;
  g_async_queue_push (spool->jobs, job);
}

void
ds_spool_flush (DsSpool *spool)
{
  gboolean done = FALSE;
  g_mutex_lock (&spool->lock);
  push (spool, JOB_FLUSH, &done);
  while (!done)
    g_cond_wait (&spool->cond, &spool->lock);
  g_mutex_unlock (&spool->lock);
}

void
ds_spool_free (DsSpool *spool)
{
  if (!spool)
    return;
  push (spool, JOB_QUIT, NULL);
  g_thread_join (spool->thread);
  g_async_queue_unref (spool->jobs);
  g_queue_clear_full (&spool->entries, entry_free);
  g_mutex_clear (&spool->lock);
  g_cond_clear (&spool->cond);
  g_free (spool->dir);
  g_free (spool);
}

gboolean
ds_spool_record (DsSpool *spool, DsResult *result, gboolean in_run)
{
  g_mutex_lock (&spool->lock);
  gboolean room = spool->stats.pending < spool->max_pending;
  if (room)
    spool->stats.pending++;
  else
    spool->stats.dropped++;
  g_mutex_unlock (&spool->lock);
  if (!room)
    return FALSE;
  Job *job = g_new0 (Job, 1);
  job->kind = JOB_RECORD;
  job->result = ds_result_ref (result);
  /* The metadata is built here, on the main thread; the writer gets its own copy. */
  ds_result_to_output (result, &job->planes);
  job->in_run = in_run;
  g_async_queue_push (spool->jobs, job);
  return TRUE;
}

void
ds_spool_end_run (DsSpool *spool)
{
  push (spool, JOB_END_RUN, NULL);
}

void
ds_spool_get_stats (DsSpool *spool, DsSpoolStats *stats)
{
  g_mutex_lock (&spool->lock);
  *stats = spool->stats;
  g_mutex_unlock (&spool->lock);
}
