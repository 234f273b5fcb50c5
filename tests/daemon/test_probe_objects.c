/* What objects in front of the stripes do to the probe (daemon/operating/scene_probe.h), against
 * the simulator's truth (its sensor's gain) for pilot frames rendered as `descatterctl validate`
 * takes them (daemon/ctl/sim_rig.c). */
#include <glib.h>
#include <math.h>

#include "daemon/ctl/sim_rig.h"
#include "daemon/ctl/validate.h"
#include "daemon/operating/stripe_model.h"

static void
probe_scene (const char *text, const char *name, DsValidateScene *vs, double *leak_truth, double *gain_truth)
{
  g_autoptr (GError) error = NULL;
  g_autoptr (DsSimRig) rig = ds_sim_rig_new_from_data (text, name, &error);
  g_assert_no_error (error);
  DsValidateOptions opt = { .calibrated = TRUE, .seed = 1 };
  g_assert_true (ds_validate_probe (rig, &opt, vs, &error));
  g_assert_no_error (error);
  DsRendererScattering sc;
  *leak_truth = ds_renderer_scattering (ds_sim_rig_renderer (rig), &sc) && sc.ballistic > 0
                  ? sc.modulated * sc.held * sc.scattered_in_cone / sc.ballistic
                  : 0.0;
  /* The pilot's gain is 0 dB: a frame's shot noise is the system gain in DN^2 per DN. */
  *gain_truth = ds_scene_system_gain (ds_sim_rig_scene (rig));
}

/* Generated scene 11-6: two opaque rectangles over a fifth of the frame and a grid, a 10-bit
 * sensor whose pilot frames clip over most of the lit field: what the noise is read on is mostly
 * the objects' shadows, with soft edges along y. The probe read the shot noise at 0.41 of the
 * sensor's gain (the predictions x1.6 low). It must be within 10 % of the simulator's gain. */
static void
test_shot_noise_under_objects (void)
{
  static const char text[] =
    "[scene]\nname=shadows\n\n"
    "[sensor]\nwidth=256\nheight=192\nbit-depth=10\npixel-pitch-um=5.22727\nquantum-efficiency=0.493543\n"
    "system-gain=0.0458107\nread-noise-e=13.6892\ndark-current-e-per-s=33.2621\nfull-well-e=21529\n"
    "exposure-us=146029\n\n"
    "[illuminator]\npattern=sine\nperiod-px=23.75\nblack-level=0.149753\nedge-blur-px=0.70305\nirradiance=1\n\n"
    "[medium]\nthickness-mm=3.29756\nmua=0.124595\nmus=0.146268\ng=0.407141\nn=1.37241\n"
    "photons=100000\nseed=210488\n\n"
    "[camera]\nmagnification=0.180217\nacceptance-half-angle-deg=15.3243\n\n"
    "[object.o0]\nshape=rect\nposition=76;4\nsize=101;77\ndepth-mm=0.0853433\ntransmittance=0\n\n"
    "[object.o1]\nshape=rect\nposition=92;11\nsize=127;70\ndepth-mm=1.681\ntransmittance=0\n\n"
    "[object.o2]\nshape=grid\npitch=64\nline-width=9\ndepth-mm=0.304467\ntransmittance=0.62093\n";
  DsValidateScene vs;
  double truth, gain;
  probe_scene (text, "shadows", &vs, &truth, &gain);
  g_test_message ("shadows: shot noise %.5f DN^2 per DN, the sensor's %.5f", vs.probe.noise_gain, gain);
  g_assert_cmpfloat (fabs (vs.probe.noise_gain / gain - 1), <, 0.10);
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  g_test_add_func ("/probe-objects/shot-noise-under-objects", test_shot_noise_under_objects);
  return g_test_run ();
}
