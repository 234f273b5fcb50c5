/* CPU time per thread of a process, from the scheduler's own accounting
 * (/proc/PID/task/TID/schedstat: nanoseconds on a CPU), grouped by thread name: where the CPU of
 * a rate benchmark goes, per frame, in figures that a busy machine does not falsify as it
 * falsifies rates (a thread's CPU per frame changes little with the queue for the CPU).
 * Threads that end between two readings lose what they used since the first. */
#pragma once
#include <glib.h>
#include <sys/types.h>

G_BEGIN_DECLS

#define THREAD_CPU_MAX_GROUPS 24

typedef struct {
  char name[16];       /* the thread's name (comm), e.g. "fold", "ds-rows" */
  double ns;           /* CPU used by the threads of that name */
  double runs;         /* times they were put on a CPU (schedstat's third field): wake-ups
                        * and preemptions */
} ThreadCpuGroup;

typedef struct {
  ThreadCpuGroup g[THREAD_CPU_MAX_GROUPS];
  guint n;
} ThreadCpuTotals;

typedef struct ThreadCpu ThreadCpu;

/* Every thread of process pid (0: this process) now; NULL when the process is gone. */
ThreadCpu *thread_cpu_read (pid_t pid);
void thread_cpu_free (ThreadCpu *snap);
G_DEFINE_AUTOPTR_CLEANUP_FUNC (ThreadCpu, thread_cpu_free)

/* Adds to acc what each thread of `after` used since `before` (a thread new in `after` from 0),
 * by thread name. Either may be NULL (nothing is added). */
void thread_cpu_add_delta (ThreadCpuTotals *acc, const ThreadCpu *before, const ThreadCpu *after);
/* Adds ns and runs to the group `name`. */
void thread_cpu_totals_add (ThreadCpuTotals *acc, const char *name, double ns, double runs);
void thread_cpu_totals_merge (ThreadCpuTotals *acc, const ThreadCpuTotals *more);
double thread_cpu_totals_sum (const ThreadCpuTotals *t);
/* "name 0.123/4.0, name 0.045/1.0, ... (total 0.321)": ms and runs on a CPU per unit, largest
 * first, groups under 0.005 ms per unit left out of the list (not of the total). */
char *thread_cpu_totals_format (const ThreadCpuTotals *t, double units);
/* One line per group, "TAG NS RUNS NAME\n", for handing totals from a child process to its parent;
 * parse adds the lines of that tag back (other lines are skipped). */
char *thread_cpu_totals_serialize (const ThreadCpuTotals *t, const char *tag);
void thread_cpu_totals_parse (ThreadCpuTotals *t, const char *text, const char *tag);

G_END_DECLS
