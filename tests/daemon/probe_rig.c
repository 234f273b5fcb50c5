#include "probe_rig.h"

#include "daemon/ctl/sim_rig.h"

DsSimRig *
probe_rig_new_probed (const char *text, const char *name, DsValidateScene *vs)
{
  g_autoptr (GError) error = NULL;
  DsSimRig *rig = ds_sim_rig_new_from_data (text, name, &error);
  g_assert_no_error (error);
  DsValidateOptions opt = { .calibrated = TRUE, .seed = 1 };
  g_assert_true (ds_validate_probe (rig, &opt, vs, &error));
  g_assert_no_error (error);
  return rig;
}

void
probe_rig_probe_scene (const char *text, const char *name, DsValidateScene *vs, double *leak_truth,
                       double *gain_truth)
{
  g_autoptr (DsSimRig) rig = probe_rig_new_probed (text, name, vs);
  DsRendererScattering sc;
  *leak_truth = ds_renderer_scattering (ds_sim_rig_renderer (rig), &sc) && sc.ballistic > 0
                  ? sc.modulated * sc.held * sc.scattered_in_cone / sc.ballistic
                  : 0.0;
  if (gain_truth)
    *gain_truth = ds_scene_system_gain (ds_sim_rig_scene (rig));
}
