/* Phase order of a set from the stripes measured in its frames (phase_order.h). */
#include <math.h>

#include "proc/phase_order.h"
#include "proc/proc_error.h"
#include "proc/stripe_phase.h"

DsPhaseOrderVerdict
ds_phase_order_check (DsPhaseOrderFrame *fr, guint n, guint n_phases, double tol, gboolean offset_known,
                      double *offset)
{
  double step = 1.0 / n_phases;
  guint measured = 0;
  for (guint i = 0; i < n; i++) {
    fr[i].found = -1;
    fr[i].residual = NAN;
    measured += fr[i].measured;
  }
  if (measured == 0) {
    if (!offset_known)
      *offset = NAN;
    return DS_PHASE_ORDER_UNKNOWN;
  }
  if (!offset_known) {
    /* The candidate offset (one per measured frame) that most frames agree with; on a tie the
     * one they agree with most closely. Then the mean residual of those frames refines it. */
    guint best_count = 0;
    double best_spread = INFINITY, best = 0;
    for (guint i = 0; i < n; i++) {
      if (!fr[i].measured)
        continue;
      double cand = fr[i].phase - fr[i].given * step;
      guint count = 0;
      double spread = 0;
      for (guint j = 0; j < n; j++) {
        if (!fr[j].measured)
          continue;
        double r = ds_stripe_phase_diff (fr[j].phase - fr[j].given * step, cand);
        if (fabs (r) <= tol) {
          count++;
          spread += fabs (r);
        }
      }
      if (count > best_count || (count == best_count && spread < best_spread)) {
        best_count = count;
        best_spread = spread;
        best = cand;
      }
    }
    double sum = 0;
    guint used = 0;
    for (guint j = 0; j < n; j++)
      if (fr[j].measured) {
        double r = ds_stripe_phase_diff (fr[j].phase - fr[j].given * step, best);
        if (fabs (r) <= tol) {
          sum += r;
          used++;
        }
      }
    best += used ? sum / used : 0;
    *offset = best - floor (best);
  }
  gboolean between = FALSE, moved = FALSE;
  g_autofree guint *count = g_new0 (guint, n_phases);
  for (guint i = 0; i < n; i++) {
    guint effective = fr[i].given;
    if (fr[i].measured) {
      double x = ds_stripe_phase_diff (fr[i].phase, *offset); /* [-1/2, 1/2) cycles */
      double k = round (x / step);
      fr[i].residual = x - k * step;
      if (fabs (fr[i].residual) <= tol) {
        long kk = ((long) k % (long) n_phases + (long) n_phases) % (long) n_phases;
        fr[i].found = (int) kk;
        effective = (guint) kk;
      } else {
        between = TRUE;
      }
    }
    moved |= effective != fr[i].given;
    count[effective]++;
  }
  if (between)
    return DS_PHASE_ORDER_BROKEN;
  for (guint k = 0; k < n_phases; k++)
    if (count[k] == 0)
      return DS_PHASE_ORDER_BROKEN;
  return moved ? DS_PHASE_ORDER_REORDERED : DS_PHASE_ORDER_OK;
}
