/* The row worker pool (proc/worker_pool.h): every row runs exactly once, on a thread index the
 * pool has, with at most the threads asked for; and a thread that stalls holds up only the few
 * rows it claimed (a chunk), because the others take the rest. The last is what fixed halves
 * could not do: with the old pool (one band per thread) the stalled worker held half the rows,
 * and the test fails. */
#include <glib.h>

#include "proc/worker_pool.h"

typedef struct {
  guint n_rows;
  gint *runs;          /* per row: times run (atomic) */
  guint *thread_of;    /* per row: the thread that ran it */
  guint max_thread_seen;
  gint caller_rows;    /* rows run by the caller (atomic) */
  /* the stall test */
  gboolean stall_worker;
  gint worker_calls;   /* atomic */
  guint stalled_rows;  /* rows of the chunk the worker stalled on */
  gint saw_rest_done;  /* atomic: the stalled worker saw every other row done by the caller */
  GMutex lock;
  GCond cond;
} Rows;

static void
row_job (gpointer data, guint y0, guint y1, guint thread)
{
  Rows *r = data;
  g_assert_cmpuint (y0, <, y1);
  g_assert_cmpuint (y1, <=, r->n_rows);
  gboolean first_worker_call = thread != 0 && r->stall_worker && g_atomic_int_add (&r->worker_calls, 1) == 0;
  if (thread == 0 && r->stall_worker && g_atomic_int_get (&r->caller_rows) == 0) {
    /* The caller's first chunk: wait until the worker stalls on one of its own, so that every
     * run tests the stall (else the caller may take every chunk before the worker wakes). */
    gint64 until = g_get_monotonic_time () + 20 * G_TIME_SPAN_SECOND;
    g_mutex_lock (&r->lock);
    while (g_atomic_int_get (&r->worker_calls) == 0)
      if (!g_cond_wait_until (&r->cond, &r->lock, until))
        break;
    g_mutex_unlock (&r->lock);
  }
  if (first_worker_call) {
    /* Hold this chunk until the caller has run every row outside it. 20 s guards against a
     * pool that would wait for this thread instead: the test then fails, not hangs. */
    gint64 until = g_get_monotonic_time () + 20 * G_TIME_SPAN_SECOND;
    guint mine = y1 - y0;
    g_mutex_lock (&r->lock);
    r->stalled_rows = mine;
    g_cond_broadcast (&r->cond);
    while ((guint) g_atomic_int_get (&r->caller_rows) < r->n_rows - mine)
      if (!g_cond_wait_until (&r->cond, &r->lock, until))
        break;
    g_atomic_int_set (&r->saw_rest_done, (guint) g_atomic_int_get (&r->caller_rows) == r->n_rows - mine);
    g_mutex_unlock (&r->lock);
  }
  for (guint y = y0; y < y1; y++) {
    g_atomic_int_inc (&r->runs[y]);
    r->thread_of[y] = thread;
  }
  g_mutex_lock (&r->lock);
  r->max_thread_seen = MAX (r->max_thread_seen, thread);
  if (thread == 0) {
    g_atomic_int_add (&r->caller_rows, (gint) (y1 - y0));
    g_cond_broadcast (&r->cond);
  }
  g_mutex_unlock (&r->lock);
}

static void
rows_init (Rows *r, guint n_rows)
{
  *r = (Rows) { .n_rows = n_rows };
  r->runs = g_new0 (gint, n_rows);
  r->thread_of = g_new0 (guint, n_rows);
  g_mutex_init (&r->lock);
  g_cond_init (&r->cond);
}

static void
rows_clear (Rows *r)
{
  g_free (r->runs);
  g_free (r->thread_of);
  g_mutex_clear (&r->lock);
  g_cond_clear (&r->cond);
}

static void
test_every_row_once (void)
{
  const guint pool_threads[] = { 1, 2, 3, 5 };
  const guint rows[] = { 1, 2, 7, 64, 1000, 1024 };
  for (guint p = 0; p < G_N_ELEMENTS (pool_threads); p++) {
    g_autoptr (DsWorkerPool) pool = ds_worker_pool_new (pool_threads[p]);
    g_assert_cmpuint (ds_worker_pool_threads (pool), ==, pool_threads[p]);
    for (guint i = 0; i < G_N_ELEMENTS (rows); i++)
      for (guint max = 0; max <= 2; max++) {
        /* Many jobs in a row: a late worker must never run a finished job's rows. */
        for (guint rep = 0; rep < 20; rep++) {
          Rows r;
          rows_init (&r, rows[i]);
          ds_worker_pool_run_on (pool, max, rows[i], row_job, &r);
          guint limit = max ? MIN (max, pool_threads[p]) : pool_threads[p];
          for (guint y = 0; y < rows[i]; y++) {
            g_assert_cmpint (r.runs[y], ==, 1);
            g_assert_cmpuint (r.thread_of[y], <, limit);
          }
          g_assert_cmpuint (r.max_thread_seen, <, limit);
          rows_clear (&r);
        }
      }
  }
  /* No pool: the caller alone, all rows in one call. */
  Rows r;
  rows_init (&r, 33);
  ds_worker_pool_run (NULL, 33, row_job, &r);
  for (guint y = 0; y < 33; y++)
    g_assert_cmpint (r.runs[y], ==, 1);
  g_assert_cmpint (r.caller_rows, ==, 33);
  rows_clear (&r);
}

static void
test_late_worker_does_not_hold_up (void)
{
  g_autoptr (DsWorkerPool) pool = ds_worker_pool_new (2);
  guint n = 1024;
  g_assert_cmpuint (ds_worker_pool_chunk_rows (n, 2), <, n / 2);
  for (guint rep = 0; rep < 20; rep++) {
    Rows r;
    rows_init (&r, n);
    r.stall_worker = TRUE;
    ds_worker_pool_run (pool, n, row_job, &r);
    for (guint y = 0; y < n; y++)
      g_assert_cmpint (r.runs[y], ==, 1);
    /* The worker stalled on one chunk, an eighth of its share at most, while the caller ran
     * every other row; nothing was left for the worker after it. */
    g_assert_cmpint (r.worker_calls, ==, 1);
    g_assert_cmpuint (r.stalled_rows, <=, n / 2 / 8);
    g_assert_true (r.saw_rest_done);
    g_assert_cmpint (r.caller_rows, ==, (gint) (n - r.stalled_rows));
    rows_clear (&r);
  }
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  g_test_add_func ("/worker-pool/every-row-once", test_every_row_once);
  g_test_add_func ("/worker-pool/late-worker-does-not-hold-up", test_late_worker_does_not_hold_up);
  return g_test_run ();
}
