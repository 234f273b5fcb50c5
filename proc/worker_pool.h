/* A small pool of worker threads that split per-pixel work by rows.
 *
 * The owner (one thread: the one that calls ds_worker_pool_run) hands out one job at a time.
 * Its rows are handed out in chunks of consecutive rows to whichever thread asks next, the
 * caller's own thread included, and ds_worker_pool_run returns when every row is done. A thread
 * that is late (woken late, or sharing its core) thus takes fewer rows instead of holding the
 * others up: with one fixed band per thread, the job's end waits for the slowest band, and a
 * thread that wakes late or shares its core with the camera delays the whole job by its own
 * delay. Which thread runs a row
 * depends on timing, but every row runs exactly once: a job whose rows are independent (any
 * per-thread total exact, as integer counts are) gives bit-identical results with any number
 * of threads.
 *
 * Workers sleep on a condition variable between jobs (no spinning: the machine's cores are
 * shared with acquisition and the socket server); the caller never waits for a worker that has
 * not started on the job (its rows are taken by the others). ds_worker_pool_run blocks the
 * caller until the job is done; it is not reentrant. Creating a pool never fails for lack of
 * threads: if the system refuses one, the pool keeps the threads it got (at least the
 * caller's). */
#pragma once
#include <glib.h>

G_BEGIN_DECLS

typedef struct DsWorkerPool DsWorkerPool;

/* Processes rows [y0, y1) on the thread with index `thread` (0 = the caller's,
 * < ds_worker_pool_threads): the index selects per-thread scratch memory. Called once per
 * chunk, so several times per thread and job, never for the same row twice. */
typedef void (*DsRowJob) (gpointer data, guint y0, guint y1, guint thread);

/* threads >= 1 in total, the caller's included (threads - 1 are started). */
DsWorkerPool *ds_worker_pool_new (guint threads);
void ds_worker_pool_free (DsWorkerPool *pool);
G_DEFINE_AUTOPTR_CLEANUP_FUNC (DsWorkerPool, ds_worker_pool_free)

guint ds_worker_pool_threads (const DsWorkerPool *pool);

/* Runs job over n_rows rows and returns when all are done. pool NULL: the caller's thread
 * does all the rows, in one call. Chunks are never empty. */
void ds_worker_pool_run (DsWorkerPool *pool, guint n_rows, DsRowJob job, gpointer data);
/* As ds_worker_pool_run on at most max_threads of the pool's threads (0: all), the caller's
 * included: 1 runs every row on the caller's thread, in one call, and wakes no worker. */
void ds_worker_pool_run_on (DsWorkerPool *pool, guint max_threads, guint n_rows, DsRowJob job,
                            gpointer data);

/* The rows per chunk when `threads` threads share n_rows rows: about eight chunks per thread,
 * so that a late thread costs at most about an eighth of its share. */
guint ds_worker_pool_chunk_rows (guint n_rows, guint threads);

G_END_DECLS
