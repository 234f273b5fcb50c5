/* The scene at the lower end of the direct light's interval, or with the leak at what the coarsest
 * period keeps (scene_probe.h: ds_scene_probe_worst_case ()). Pure function, any thread. */
#include "daemon/operating/scene_probe.h"

/* The upper end where the coarsest period bounds the leak (scene_probe_hidden.h): Ld as read, the
 * leak at every harmonic and period at narrow.hidden_leak (a kernel of width 0 keeps every harmonic). */
static gboolean
hidden_worst_case (const DsSceneProbe *p, DsSceneProbe *worst)
{
  if (!p->narrow.unresolved || !(p->narrow.hidden_leak > 0) || (p->interval.set && p->interval.unbounded))
    return FALSE;
  *worst = *p;
  worst->leak.per_px = 0;
  worst->leak.measured = TRUE;
  worst->narrow.fraction = p->narrow.hidden_leak;
  worst->narrow.kernel_px = 0;
  worst->narrow.form = DS_PROBE_KERNEL_POWER;
  worst->narrow.shape = 1;
  worst->leak.bounded = TRUE;
  worst->leak.max = MAX (p->leak.max, p->narrow.hidden_leak);
  return TRUE;
}

gboolean
ds_scene_probe_worst_case (const DsSceneProbe *p, DsSceneProbe *worst)
{
  if (hidden_worst_case (p, worst) && !(p->interval.set && p->interval.ld_lower < p->light.ld_mean))
    return TRUE;
  if (!p->narrow.unresolved || !p->interval.set || p->interval.unbounded || !(p->interval.ld_lower < p->light.ld_mean) ||
      !(p->interval.ld_lower > 0) || !(p->interval.worst_kernel_px > 0))
    return FALSE;
  *worst = *p;
  double total = p->light.ld_mean + p->light.lg_mean;
  worst->light.ld_mean = p->interval.ld_lower;
  worst->light.lg_mean = total - p->interval.ld_lower;
  worst->leak.per_px = 0;
  worst->leak.measured = TRUE;
  worst->narrow.fraction = worst->light.lg_mean / worst->light.ld_mean;
  worst->narrow.kernel_px = p->interval.worst_kernel_px;
  worst->narrow.form = DS_PROBE_KERNEL_POWER;
  worst->narrow.shape = 0.5;
  worst->leak.max = worst->light.lg_mean / worst->light.ld_mean; /* its kernel's MTF <= 1 keeps it there anyway */
  return TRUE;
}
