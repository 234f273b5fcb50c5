#include "pilot_pairs.h"

guint
pilot_pairs_probe (PilotFrameFunc frame, gconstpointer scene, const DsProbeFrames *base, double blur_px,
                   guint32 seed, DsSceneProbe *p)
{
  double period = base->geometry.period_px;
  g_autoptr (GRand) r = g_rand_new_with_seed (seed);
  DsImage *owned[5 + 2 * DS_PROBE_FINER_MAX] = { NULL };
  guint n = 0;
  owned[n++] = frame (scene, period, 0, FALSE, r);
  owned[n++] = frame (scene, period, 0.1, TRUE, r);
  owned[n++] = frame (scene, period, 0.6, TRUE, r);
  owned[n++] = frame (scene, 2 * period, 0.2, TRUE, r);
  owned[n++] = frame (scene, 2 * period, 0.7, TRUE, r);
  DsProbeFrames fr = *base;
  fr.dark = owned[0];
  fr.lit[0] = owned[1];
  fr.lit[1] = owned[2];
  fr.coarse[0] = owned[3];
  fr.coarse[1] = owned[4];
  double q[DS_PROBE_FINER_MAX];
  guint nq = ds_scene_probe_finer_periods (period, blur_px, q);
  for (guint i = 0; i < nq; i++) {
    owned[n++] = frame (scene, q[i], 0.3, TRUE, r);
    owned[n++] = frame (scene, q[i], 0.8, TRUE, r);
    fr.finer[i] = (DsProbePair){ .frame = { owned[n - 2], owned[n - 1] }, .period_px = q[i] };
  }
  fr.n_finer = nq;
  g_autoptr (GError) error = NULL;
  gboolean ok = ds_scene_probe_measure (&fr, p, &error);
  g_assert_no_error (error);
  g_assert_true (ok);
  for (guint i = 0; i < n; i++)
    ds_image_free (owned[i]);
  return nq;
}
