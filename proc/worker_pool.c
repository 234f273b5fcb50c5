/* Row-band worker pool (see worker_pool.h). One job at a time; a generation counter tells the
 * workers that a new job is posted, a count of finished bands tells the caller when to return. */
#include "proc/worker_pool.h"

struct DsWorkerPool {
  GMutex lock;
  GCond posted;     /* a new job (or quit) */
  GCond finished;   /* a band finished */
  GThread **workers;
  guint threads;    /* the caller's included */
  guint64 generation;
  gboolean quit;
  /* the job being run */
  DsRowJob job;
  gpointer data;
  guint n_rows, bands;
  guint done;
};

typedef struct {
  DsWorkerPool *pool;
  guint index;
} WorkerArg;

void
ds_worker_pool_band (guint n_rows, guint threads, guint t, guint *y0, guint *y1)
{
  /* Bands differ by at most one row; 64-bit products cannot overflow for 2^32 rows. */
  *y0 = (guint) ((guint64) n_rows * t / threads);
  *y1 = (guint) ((guint64) n_rows * (t + 1) / threads);
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
    if (index >= pool->bands)
      continue; /* fewer rows than threads: this one sits the job out */
    DsRowJob job = pool->job;
    gpointer data = pool->data;
    guint y0, y1;
    ds_worker_pool_band (pool->n_rows, pool->bands, index, &y0, &y1);
    g_mutex_unlock (&pool->lock);
    job (data, y0, y1, index);
    g_mutex_lock (&pool->lock);
    pool->done++;
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
  g_mutex_lock (&pool->lock);
  pool->job = job;
  pool->data = data;
  pool->n_rows = n_rows;
  pool->bands = bands;
  pool->done = 0;
  pool->generation++;
  g_cond_broadcast (&pool->posted);
  g_mutex_unlock (&pool->lock);

  guint y0, y1;
  ds_worker_pool_band (n_rows, bands, 0, &y0, &y1);
  job (data, y0, y1, 0);

  g_mutex_lock (&pool->lock);
  while (pool->done < bands - 1)
    g_cond_wait (&pool->finished, &pool->lock);
  g_mutex_unlock (&pool->lock);
}
