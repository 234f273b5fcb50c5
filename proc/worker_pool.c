/* Row worker pool (see worker_pool.h). One job at a time; a generation counter tells the
 * workers that a new job is posted. Rows are claimed a chunk at a time from an atomic cursor;
 * the caller returns once the cursor passed the last row and no worker is inside the job. */
#include "proc/worker_pool.h"

struct DsWorkerPool {
  GMutex lock;
  GCond posted;     /* a new job (or quit) */
  GCond finished;   /* a worker left the job */
  GThread **workers;
  guint threads;    /* the caller's included */
  guint64 generation;
  gboolean quit;
  /* the job being run */
  DsRowJob job;
  gpointer data;
  guint n_rows, bands, chunk;
  gsize next_row;   /* the first row not claimed yet (atomic; 64 bits: claims never wrap) */
  guint inside;     /* workers that took this job and have not left it */
};

typedef struct {
  DsWorkerPool *pool;
  guint index;
} WorkerArg;

guint
ds_worker_pool_chunk_rows (guint n_rows, guint threads)
{
  return MAX (1u, n_rows / (MAX (threads, 1u) * 8u));
}

/* Claims and runs chunks until none is left. Any thread, the caller's included. */
static void
run_chunks (DsWorkerPool *pool, DsRowJob job, gpointer data, guint n_rows, guint chunk, guint index)
{
  for (;;) {
    gsize y0 = __atomic_fetch_add (&pool->next_row, (gsize) chunk, __ATOMIC_RELAXED);
    if (y0 >= n_rows)
      return;
    job (data, (guint) y0, (guint) MIN (y0 + chunk, (gsize) n_rows), index);
  }
}

static gpointer
worker_main (gpointer p)
{
  WorkerArg *arg = p;
  DsWorkerPool *pool = arg->pool;
  guint index = arg->index;
  g_free (arg);
  guint64 seen = 0;
  g_mutex_lock (&pool->lock);
  for (;;) {
    while (!pool->quit && pool->generation == seen)
      g_cond_wait (&pool->posted, &pool->lock);
    if (pool->quit)
      break;
    seen = pool->generation;
    /* Fewer threads asked for than the pool has: this one sits the job out. Every row already
     * claimed: the caller may be returning, and nothing is left to take. */
    if (index >= pool->bands || __atomic_load_n (&pool->next_row, __ATOMIC_RELAXED) >= pool->n_rows)
      continue;
    /* Entered under the lock: the caller, which checks `inside` under it, waits for this
     * thread before it returns (and before it posts another job that reuses the cursor). */
    pool->inside++;
    DsRowJob job = pool->job;
    gpointer data = pool->data;
    guint n_rows = pool->n_rows, chunk = pool->chunk;
    g_mutex_unlock (&pool->lock);
    run_chunks (pool, job, data, n_rows, chunk, index);
    g_mutex_lock (&pool->lock);
    pool->inside--;
    g_cond_signal (&pool->finished);
  }
  g_mutex_unlock (&pool->lock);
  return NULL;
}

DsWorkerPool *
ds_worker_pool_new (guint threads)
{
  DsWorkerPool *pool = g_new0 (DsWorkerPool, 1);
  g_mutex_init (&pool->lock);
  g_cond_init (&pool->posted);
  g_cond_init (&pool->finished);
  threads = MAX (threads, 1u);
  pool->workers = g_new0 (GThread *, threads);
  pool->threads = 1;
  for (guint i = 1; i < threads; i++) {
    WorkerArg *arg = g_new (WorkerArg, 1);
    arg->pool = pool;
    arg->index = i;
    GThread *t = g_thread_try_new ("ds-rows", worker_main, arg, NULL);
    if (!t) {
      g_free (arg);
      break;
    }
    pool->workers[i] = t;
    pool->threads++;
  }
  return pool;
}

void
ds_worker_pool_free (DsWorkerPool *pool)
{
  if (!pool)
    return;
  g_mutex_lock (&pool->lock);
  pool->quit = TRUE;
  g_cond_broadcast (&pool->posted);
  g_mutex_unlock (&pool->lock);
  for (guint i = 1; i < pool->threads; i++)
    g_thread_join (pool->workers[i]);
  g_free (pool->workers);
  g_mutex_clear (&pool->lock);
  g_cond_clear (&pool->posted);
  g_cond_clear (&pool->finished);
  g_free (pool);
}

guint
ds_worker_pool_threads (const DsWorkerPool *pool)
{
  return pool ? pool->threads : 1;
}

void
ds_worker_pool_run (DsWorkerPool *pool, guint n_rows, DsRowJob job, gpointer data)
{
  ds_worker_pool_run_on (pool, 0, n_rows, job, data);
}

void
ds_worker_pool_run_on (DsWorkerPool *pool, guint max_threads, guint n_rows, DsRowJob job,
                       gpointer data)
{
  if (n_rows == 0)
    return;
  guint bands = pool ? MIN (pool->threads, n_rows) : 1;
  if (max_threads)
    bands = MIN (bands, max_threads);
  if (bands <= 1) {
    job (data, 0, n_rows, 0);
    return;
  }
  guint chunk = ds_worker_pool_chunk_rows (n_rows, bands);
  g_mutex_lock (&pool->lock);
  pool->job = job;
  pool->data = data;
  pool->n_rows = n_rows;
  pool->bands = bands;
  pool->chunk = chunk;
  __atomic_store_n (&pool->next_row, 0, __ATOMIC_RELAXED);
  pool->generation++;
  g_cond_broadcast (&pool->posted);
  g_mutex_unlock (&pool->lock);

  run_chunks (pool, job, data, n_rows, chunk, 0);

  /* Every row is claimed; the ones workers claimed are done when they left. The mutex orders
   * their writes before the caller's return. */
  g_mutex_lock (&pool->lock);
  while (pool->inside > 0)
    g_cond_wait (&pool->finished, &pool->lock);
  g_mutex_unlock (&pool->lock);
}
