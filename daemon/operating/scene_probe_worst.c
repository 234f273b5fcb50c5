/* The scene at the lower end of the direct light's interval, or with the leak at what the coarsest
 * period keeps (scene_probe.h: ds_scene_probe_worst_case ()). Pure function, any thread. */
#include "daemon/operating/scene_probe.h"

/* The upper end where the coarsest period bounds the leak (scene_probe_hidden.h): Ld as read, the
 * leak at every harmonic and period at hidden_leak (a kernel of width 0 keeps every harmonic). */
static gboolean
hidden_worst_case (const DsSceneProbe *p, DsSceneProbe *worst)
{
  if (!p->narrow_unresolved || !(p->hidden_leak > 0) || (p->ld_interval && p->ld_unbounded))
    return FALSE;
  *worst = *p;
  worst->leak_per_px = 0;
  worst->leak_measured = TRUE;
  worst->narrow_fraction = p->hidden_leak;
  worst->narrow_kernel_px = 0;
  worst->narrow_form = DS_PROBE_KERNEL_POWER;
  worst->narrow_shape = 1;
  worst->leak_bounded = TRUE;
  worst->leak_max = MAX (p->leak_max, p->hidden_leak);
  return TRUE;
}

gboolean
ds_scene_probe_worst_case (const DsSceneProbe *p, DsSceneProbe *worst)
{
  if (hidden_worst_case (p, worst) && !(p->ld_interval && p->ld_lower < p->ld_mean))
    return TRUE;
  if (!p->narrow_unresolved || !p->ld_interval || p->ld_unbounded || !(p->ld_lower < p->ld_mean) ||
      !(p->ld_lower > 0) || !(p->worst_kernel_px > 0))
    return FALSE;
  *worst = *p;
  double total = p->ld_mean + p->lg_mean;
  worst->ld_mean = p->ld_lower;
  worst->lg_mean = total - p->ld_lower;
  worst->leak_per_px = 0;
  worst->leak_measured = TRUE;
  worst->narrow_fraction = worst->lg_mean / worst->ld_mean;
  worst->narrow_kernel_px = p->worst_kernel_px;
  worst->narrow_form = DS_PROBE_KERNEL_POWER;
  worst->narrow_shape = 0.5;
  worst->leak_max = worst->lg_mean / worst->ld_mean; /* its kernel's MTF <= 1 keeps it there anyway */
  return TRUE;
}
