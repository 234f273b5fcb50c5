#include "daemon/operating/scene_probe_hidden.h"

#include <math.h>
#include <string.h>

void
ds_probe_hidden_light (const DsProbeEquation *eq, guint n_eq, const DsStripeModel *g, double sigma, guint width,
                       double ld, double total, double ld_uncertainty, double leak_fit, DsProbeHiddenLight *out)
{
  memset (out, 0, sizeof *out);
  out->leak_fit = leak_fit;
  const DsProbeEquation *c = NULL;
  for (guint i = 0; i < n_eq; i++)
    if (eq[i].n == 1 && (!c || eq[i].period > c->period))
      c = &eq[i];
  if (!c || !(ld > 0) || !(total > 0) || !(c->period > 1.01 * g->period_px))
    return;
  double gc = ds_probe_model_gain (g, c->period, sigma, c->offset, width, 1);
  if (!(gc > 0))
    return;
  out->coarse_px = c->period;
  out->lg = (total - ld) / ld;
  out->kept = (c->amplitude / gc - ld) / ld;
  out->lg_sigma = sqrt (ld_uncertainty * ld_uncertainty + DS_PROBE_PAIR_SCATTER * DS_PROBE_PAIR_SCATTER);
  out->suspect = out->lg > DS_PROBE_HIDDEN_Z * out->lg_sigma && out->kept >= DS_PROBE_HIDDEN_KEPT * out->lg &&
                 out->kept > DS_PROBE_HIDDEN_FACTOR * MAX (leak_fit, 0.0);
  if (!out->suspect)
    return;
  out->kept = MIN (out->kept, out->lg);
  g_snprintf (out->note, sizeof out->note,
              "the mean's scattered light (%.1f %% of Ld, %.1f sigma) is kept by the stripes at %g px (%.1f %% of Ld) "
              "and the fit reads a leak of %.1f %% at %g px: the leak there can be up to %.1f %%, so the prediction is a "
              "lower bound whose upper end takes that",
              100 * out->lg, out->lg / out->lg_sigma, c->period, 100 * out->kept, 100 * leak_fit, g->period_px,
              100 * out->kept);
}
