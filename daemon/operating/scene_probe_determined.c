/* Whether the narrow kernel term measures a kernel (scene_probe_determined.h). */
#include "daemon/operating/scene_probe_determined.h"

#include <math.h>

static gboolean
usable (const DsProbeEquation *e)
{
  return e->amplitude > 0 && e->n > 0 && e->period > 0;
}

guint
ds_probe_distinct_points (const DsProbeEquation *eq, guint n_eq)
{
  guint distinct = 0;
  for (guint i = 0; i < n_eq; i++) {
    if (!usable (&eq[i]))
      continue;
    double x = eq[i].period / eq[i].n;
    gboolean seen = FALSE;
    for (guint j = 0; j < i && !seen; j++)
      seen = usable (&eq[j]) && fabs (eq[j].period / eq[j].n - x) <= 1e-3 * x;
    distinct += !seen;
  }
  return distinct;
}

double
ds_probe_residual_rms (const DsProbeEquation *eq, guint n_eq, double chi2)
{
  double sum_w = 0;
  for (guint i = 0; i < n_eq; i++) {
    if (!usable (&eq[i]))
      continue;
    double rel = eq[i].sigma / eq[i].amplitude;
    sum_w += 1 / (rel * rel + DS_PROBE_TRANSFER_FLOOR * DS_PROBE_TRANSFER_FLOOR);
  }
  return sum_w > 0 && chi2 >= 0 ? sqrt (chi2 / sum_w) : INFINITY;
}

gboolean
ds_probe_narrow_measured (const DsProbeEquation *eq, guint n_eq, double chi2, char *note, gsize note_size)
{
  guint points = ds_probe_distinct_points (eq, n_eq);
  if (points > DS_PROBE_NARROW_PARAMETERS)
    return TRUE;
  double rms = ds_probe_residual_rms (eq, n_eq, chi2);
  if (rms <= DS_PROBE_NARROW_PASS_RMS)
    return TRUE;
  if (note && note_size)
    g_snprintf (note, note_size,
                " (a narrow kernel not taken: its %d parameters on %u harmonics miss them by %.2f %% RMS, more than "
                "%.1f %%, and no kernel's transfer falls with the period)",
                DS_PROBE_NARROW_PARAMETERS, points, 100 * rms, 100 * DS_PROBE_NARROW_PASS_RMS);
  return FALSE;
}
