#include "thread_cpu.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef struct {
  long tid;
  char name[16];
  double ns, runs;
} Entry;

struct ThreadCpu {
  GArray *threads; /* Entry */
};

static gboolean
read_thread (const char *dir, const char *tid, Entry *e)
{
  g_autofree char *sched_path = g_build_filename (dir, tid, "schedstat", NULL);
  g_autofree char *comm_path = g_build_filename (dir, tid, "comm", NULL);
  g_autofree char *sched = NULL, *comm = NULL;
  if (!g_file_get_contents (sched_path, &sched, NULL, NULL) ||
      !g_file_get_contents (comm_path, &comm, NULL, NULL))
    return FALSE;
  /* schedstat: time on a CPU (ns), time waiting for one (ns), time slices run. */
  e->tid = atol (tid);
  char *end = NULL;
  e->ns = g_ascii_strtod (sched, &end);
  g_ascii_strtod (end, &end);
  e->runs = g_ascii_strtod (end, NULL);
  g_strchomp (comm);
  g_strlcpy (e->name, comm, sizeof e->name);
  return TRUE;
}

ThreadCpu *
thread_cpu_read (pid_t pid)
{
  g_autofree char *dir = pid ? g_strdup_printf ("/proc/%d/task", (int) pid) : g_strdup ("/proc/self/task");
  g_autoptr (GDir) d = g_dir_open (dir, 0, NULL);
  if (!d)
    return NULL;
  ThreadCpu *snap = g_new0 (ThreadCpu, 1);
  snap->threads = g_array_new (FALSE, FALSE, sizeof (Entry));
  const char *tid;
  while ((tid = g_dir_read_name (d))) {
    Entry e;
    if (read_thread (dir, tid, &e))
      g_array_append_val (snap->threads, e);
  }
  return snap;
}

void
thread_cpu_free (ThreadCpu *snap)
{
  if (!snap)
    return;
  g_array_unref (snap->threads);
  g_free (snap);
}

void
thread_cpu_totals_add (ThreadCpuTotals *acc, const char *name, double ns, double runs)
{
  for (guint i = 0; i < acc->n; i++)
    if (strcmp (acc->g[i].name, name) == 0) {
      acc->g[i].ns += ns;
      acc->g[i].runs += runs;
      return;
    }
  if (acc->n == THREAD_CPU_MAX_GROUPS)
    return;
  g_strlcpy (acc->g[acc->n].name, name, sizeof acc->g[acc->n].name);
  acc->g[acc->n].ns = ns;
  acc->g[acc->n++].runs = runs;
}

void
thread_cpu_add_delta (ThreadCpuTotals *acc, const ThreadCpu *before, const ThreadCpu *after)
{
  if (!before || !after)
    return;
  for (guint i = 0; i < after->threads->len; i++) {
    const Entry *a = &g_array_index (after->threads, Entry, i);
    double start = 0, start_runs = 0;
    for (guint j = 0; j < before->threads->len; j++) {
      const Entry *b = &g_array_index (before->threads, Entry, j);
      if (b->tid == a->tid) {
        start = b->ns;
        start_runs = b->runs;
        break;
      }
    }
    thread_cpu_totals_add (acc, a->name, MAX (a->ns - start, 0.0), MAX (a->runs - start_runs, 0.0));
  }
}

void
thread_cpu_totals_merge (ThreadCpuTotals *acc, const ThreadCpuTotals *more)
{
  for (guint i = 0; i < more->n; i++)
    thread_cpu_totals_add (acc, more->g[i].name, more->g[i].ns, more->g[i].runs);
}

double
thread_cpu_totals_sum (const ThreadCpuTotals *t)
{
  double s = 0;
  for (guint i = 0; i < t->n; i++)
    s += t->g[i].ns;
  return s;
}

static int
by_ns_desc (const void *a, const void *b)
{
  double x = ((const ThreadCpuGroup *) a)->ns, y = ((const ThreadCpuGroup *) b)->ns;
  return (x < y) - (x > y);
}

char *
thread_cpu_totals_format (const ThreadCpuTotals *t, double units)
{
  ThreadCpuTotals sorted = *t;
  qsort (sorted.g, sorted.n, sizeof sorted.g[0], by_ns_desc);
  GString *s = g_string_new (NULL);
  for (guint i = 0; i < sorted.n; i++) {
    double ms = sorted.g[i].ns / 1e6 / units;
    if (ms < 0.005)
      continue;
    g_string_append_printf (s, "%s%s %.3f/%.1f", s->len ? ", " : "", sorted.g[i].name, ms,
                            sorted.g[i].runs / units);
  }
  g_string_append_printf (s, "%s(total %.3f)", s->len ? " " : "", thread_cpu_totals_sum (t) / 1e6 / units);
  return g_string_free (s, FALSE);
}

char *
thread_cpu_totals_serialize (const ThreadCpuTotals *t, const char *tag)
{
  GString *s = g_string_new (NULL);
  for (guint i = 0; i < t->n; i++) {
    /* Thread names may hold spaces: the number comes first. */
    g_string_append_printf (s, "%s %.0f %.0f %s\n", tag, t->g[i].ns, t->g[i].runs, t->g[i].name);
  }
  return g_string_free (s, FALSE);
}

void
thread_cpu_totals_parse (ThreadCpuTotals *t, const char *text, const char *tag)
{
  gsize tl = strlen (tag);
  g_auto (GStrv) lines = g_strsplit (text, "\n", -1);
  for (guint i = 0; lines[i]; i++) {
    if (strncmp (lines[i], tag, tl) != 0 || lines[i][tl] != ' ')
      continue;
    const char *num = lines[i] + tl + 1;
    char *end = NULL, *end2 = NULL;
    double ns = g_ascii_strtod (num, &end);
    if (end == num || *end != ' ' || !(ns >= 0))
      continue;
    double runs = g_ascii_strtod (end + 1, &end2);
    if (end2 == end + 1 || *end2 != ' ' || !(runs >= 0))
      continue;
    thread_cpu_totals_add (t, end2 + 1, ns, runs);
  }
}
