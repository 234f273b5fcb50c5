#include "period_check.h"

#include <math.h>

static DsRegion
resolved (const DsImage *frame, const DsRegion *region)
{
  DsRegion r = region ? *region : (DsRegion) { 0, 0, 0, 0 };
  if (r.width == 0)
    r.width = frame->width - r.x;
  if (r.height == 0)
    r.height = frame->height - r.y;
  return r;
}

/* Phase at period p over columns [x, x + w) of r's rows, and where the fitted columns centre. */
static gboolean
phase_at (const DsImage *frame, const DsRegion *r, guint x, guint w, double p, double *phase, double *centre)
{
  DsRegion half = { x, r->y, w, r->height };
  DsStripePhase sp;
  if (!ds_stripe_phase_measure (frame, p, &half, &sp, NULL) || !sp.reliable)
    return FALSE;
  *phase = sp.phase;
  *centre = x + sp.columns_used / 2.0;
  return TRUE;
}

double
period_check_measure (const DsImage *frame, const DsRegion *region)
{
  DsRegion r = resolved (frame, region);
  double best = 0, best_amplitude = 0;
  for (double p = 2.5; p <= r.width / 3.0; p *= 1.002) {
    DsStripePhase sp;
    if (ds_stripe_phase_measure (frame, p, &r, &sp, NULL) && sp.reliable && sp.amplitude > best_amplitude) {
      best_amplitude = sp.amplitude;
      best = p;
    }
  }
  if (best == 0)
    return 0;
  guint half = r.width / 2;
  for (guint i = 0; i < 3; i++) {
    double pl, pr, xl, xr;
    if (!phase_at (frame, &r, r.x, half, best, &pl, &xl) || !phase_at (frame, &r, r.x + half, half, best, &pr, &xr))
      return 0;
    best = 1.0 / (1.0 / best - ds_stripe_phase_diff (pr, pl) / (xr - xl));
  }
  return best;
}

void
period_check_frames (DsIlluminator *ill, DsCamera *cam, const DsStripePattern *pattern, const DsRegion *region,
                     double rel_tol)
{
  g_autoptr (GError) error = NULL;
  gboolean loaded = ill->ops->set_pattern (ill->backend, pattern, &error);
  g_assert_no_error (error);
  g_assert_true (loaded);
  double phase0 = NAN;
  for (guint k = 0; k < pattern->n_phases; k++) {
    /* Deadlines for a loaded machine, not the devices': labsim renders a new period's light
     * before its frame (waiting up to 10 s for it). */
    gboolean lit = ill->ops->set_phase (ill->backend, k, 10000, &error);
    g_assert_no_error (error);
    g_assert_true (lit);
    cam->ops->flush (cam->backend);
    gboolean triggered = cam->ops->trigger (cam->backend, &error);
    g_assert_no_error (error);
    g_assert_true (triggered);
    g_autoptr (DsFrame) f = cam->ops->grab (cam->backend, 20000, &error);
    g_assert_no_error (error);
    double measured = period_check_measure (f->image, region);
    DsStripePhase sp;
    g_assert_true (ds_stripe_phase_measure (f->image, pattern->period_px, region, &sp, &error));
    g_assert_no_error (error);
    if (k == 0)
      phase0 = sp.phase;
    double rel = ds_stripe_phase_diff (sp.phase, phase0);
    double want = ds_stripe_phase_diff ((double) k / pattern->n_phases, 0);
    g_test_message ("period %.2f px, phase %u: measured period %.3f px, phase %.3f from phase 0 (expected %.3f)",
                    pattern->period_px, k, measured, rel, want);
    g_assert_cmpfloat (fabs (measured / pattern->period_px - 1), <, rel_tol);
    g_assert_cmpfloat (fabs (ds_stripe_phase_diff (rel, want)), <, 0.5 / pattern->n_phases);
  }
}
