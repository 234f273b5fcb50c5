#include "daemon/ctl/ctl_progress.h"

#include <math.h>
#include <stdio.h>
#include <unistd.h>

struct DsCtlProgress {
  char *label, *unit;
  guint total, done;
  double total_weight, done_weight;
  gint64 started_us, last_line_us;
  gboolean quiet, tty, line_open;
};

/* Lines in a log: often enough to show life, rarely enough to stay readable. */
#define LOG_INTERVAL_US (10 * G_USEC_PER_SEC)

DsCtlProgress *
ds_ctl_progress_new (const char *label, const char *unit, guint total_items, double total_weight,
                     gboolean quiet)
{
  DsCtlProgress *p = g_new0 (DsCtlProgress, 1);
  p->label = g_strdup (label);
  p->unit = g_strdup (unit);
  p->total = total_items;
  p->total_weight = total_weight;
  p->quiet = quiet;
  p->tty = isatty (STDERR_FILENO);
  p->started_us = g_get_monotonic_time ();
  return p;
}

char *
ds_ctl_format_duration (double s)
{
  if (!isfinite (s) || s < 0)
    return g_strdup ("unknown");
  guint64 t = (guint64) llround (s);
  if (t >= 3600)
    return g_strdup_printf ("%" G_GUINT64_FORMAT " h %02" G_GUINT64_FORMAT " min", t / 3600, t % 3600 / 60);
  if (t >= 60)
    return g_strdup_printf ("%" G_GUINT64_FORMAT " min %02" G_GUINT64_FORMAT " s", t / 60, t % 60);
  return g_strdup_printf ("%" G_GUINT64_FORMAT " s", t);
}

void
ds_ctl_progress_advance (DsCtlProgress *p, double weight, const char *extra)
{
  p->done++;
  p->done_weight += weight;
  if (p->quiet)
    return;
  gint64 now = g_get_monotonic_time ();
  gboolean last = p->done >= p->total;
  if (!p->tty && !last && p->last_line_us && now - p->last_line_us < LOG_INTERVAL_US)
    return;
  p->last_line_us = now;
  double elapsed = (double) (now - p->started_us) / 1e6;
  double left = p->done_weight > 0 ? elapsed * (p->total_weight - p->done_weight) / p->done_weight : NAN;
  g_autofree char *left_text = last ? g_strdup ("done") : ds_ctl_format_duration (left);
  double pct = p->total_weight > 0 ? 100.0 * p->done_weight / p->total_weight : 0;
  fprintf (stderr, "%s%s: %u/%u %s (%.0f%%), %s%s%s%s%s", p->tty ? "\r\033[K" : "", p->label, p->done,
           p->total, p->unit, pct, last ? "" : "time left ", left_text, extra ? ", " : "",
           extra ? extra : "", p->tty ? "" : "\n");
  p->line_open = p->tty;
  fflush (stderr);
}

void
ds_ctl_progress_free (DsCtlProgress *p)
{
  if (!p)
    return;
  if (p->line_open)
    fputc ('\n', stderr);
  g_free (p->label);
  g_free (p->unit);
  g_free (p);
}
