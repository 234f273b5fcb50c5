/* A small pool of worker threads that split per-pixel work by rows.
 *
 * The owner (one thread: the one that calls ds_worker_pool_run) hands out one job at a time;
 * rows 0..n_rows-1 are cut into one contiguous band per thread, the caller's own thread takes
 * the first band, and ds_worker_pool_run returns when every band is done. The bands depend
 * only on n_rows and the thread count, never on timing, so a job whose rows are independent
 * gives bit-identical results with any number of threads.
 *
 * Workers sleep on a condition variable between jobs (no spinning: the machine's cores are
 * shared with acquisition and the socket server). ds_worker_pool_run blocks the caller until
 * the job is done; it is not reentrant. Creating a pool never fails for lack of threads: if
 * the system refuses one, the pool keeps the threads it got (at least the caller's). */
#pragma once
#include <glib.h>

G_BEGIN_DECLS

typedef struct DsWorkerPool DsWorkerPool;

/* Processes rows [y0, y1) on the thread with index `thread` (0 = the caller's,
 * < ds_worker_pool_threads): the index selects per-thread scratch memory. */
typedef void (*DsRowJob) (gpointer data, guint y0, guint y1, guint thread);

/* threads >= 1 in total, the caller's included (threads - 1 are started). */
DsWorkerPool *ds_worker_pool_new (guint threads);
void ds_worker_pool_free (DsWorkerPool *pool);
G_DEFINE_AUTOPTR_CLEANUP_FUNC (DsWorkerPool, ds_worker_pool_free)

guint ds_worker_pool_threads (const DsWorkerPool *pool);

/* Runs job over n_rows rows and returns when all are done. pool NULL: the caller's thread
 * does all the rows. Bands are never empty: fewer rows than threads use fewer threads. */
void ds_worker_pool_run (DsWorkerPool *pool, guint n_rows, DsRowJob job, gpointer data);
/* As ds_worker_pool_run on at most max_threads of the pool's threads (0: all), the caller's
 * included: 1 runs every row on the caller's thread and wakes no worker. */
void ds_worker_pool_run_on (DsWorkerPool *pool, guint max_threads, guint n_rows, DsRowJob job,
                            gpointer data);

/* The band of thread t out of `threads` over n_rows rows: [*y0, *y1), possibly empty. */
void ds_worker_pool_band (guint n_rows, guint threads, guint t, guint *y0, guint *y1);

G_END_DECLS
