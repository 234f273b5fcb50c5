/* The light lost against the open field (daemon/operating/scene_probe_loss.h) on frames the
 * simulator renders, probed as `descatterctl validate` probes them on a rig calibrated on the
 * clear reference (the open field measured by the calibrator from that reference's frames).
 * Independent expectations: the renderer's own transmittance into the lens (its direct light
 * plus the scattered light in the acceptance cone, shares of the incident light; 1 without a
 * medium), and the physics the stage rests on: a thin forward-peaked film that scatters a fifth of
 * the light keeps the stripes at every period the pilot draws, so its loss is the only trace and
 * the prediction must be a lower bound; a clear scene with opaque objects is not one for this. */
#include <glib.h>
#include <math.h>
#include <string.h>

#include "daemon/ctl/sim_rig.h"
#include "daemon/ctl/validate.h"
#include "probe_rig.h"

#define FILM_SCENE(medium)                                                                                    \
  "[scene]\nname=film\n\n"                                                                                    \
  "[sensor]\nwidth=256\nheight=192\nbit-depth=8\npixel-pitch-um=5.92572\nquantum-efficiency=0.441411\n"      \
  "system-gain=0.0235907\nread-noise-e=12.0979\ndark-current-e-per-s=6.051\nfull-well-e=11124.2\n"           \
  "exposure-us=2160\n\n"                                                                                      \
  "[illuminator]\npattern=square\nperiod-px=15.75\nduty=0.537079\nedge-blur-px=1.28036\nirradiance=1\n\n"     \
  medium                                                                                                      \
  "[camera]\nmagnification=0.0566021\nacceptance-half-angle-deg=7.65407\n\n"                                  \
  "[object.o0]\nshape=rect\nposition=101;10\nsize=77;90\ntransmittance=0\n"

/* The renderer's transmittance into the lens: 1 without a medium. */
static double
truth_transmittance (const char *text)
{
  g_autoptr (GError) error = NULL;
  g_autoptr (DsSimRig) rig = ds_sim_rig_new_from_data (text, "truth", &error);
  g_assert_no_error (error);
  DsRendererScattering sc;
  if (!ds_renderer_scattering (ds_sim_rig_renderer (rig), &sc))
    return 1.0;
  return sc.ballistic + sc.scattered_in_cone * sc.held;
}

static void
test_film_flagged (void)
{
  static const char text[] =
    FILM_SCENE ("[medium]\nthickness-mm=0.778364\nmua=0.00500796\nmus=0.348032\ng=0.927405\nn=1.41235\n"
                "photons=100000\nseed=286599\n\n");
  DsValidateScene vs;
  double leak_truth;
  probe_rig_probe_scene (text, "film", &vs, &leak_truth, NULL);
  double t = truth_transmittance (text);
  g_test_message ("film: transmittance %.4f (truth %.4f), floor %.4f; %s", vs.probe.loss.transmittance, t,
                  vs.probe.loss.floor, vs.probe.loss.note);
  g_assert_true (vs.probe.loss.known);
  g_assert_cmpfloat_with_epsilon (vs.probe.loss.transmittance, t, 0.03);
  g_assert_true (vs.probe.loss.unexplained);
  g_assert_nonnull (strstr (vs.probe.loss.note, "lower bound"));
}

static void
test_clear_not_flagged (void)
{
  static const char text[] = FILM_SCENE ("");
  DsValidateScene vs;
  double leak_truth;
  probe_rig_probe_scene (text, "clear", &vs, &leak_truth, NULL);
  g_test_message ("clear: transmittance %.4f (truth 1); %s", vs.probe.loss.transmittance, vs.probe.loss.note);
  g_assert_cmpfloat (truth_transmittance (text), ==, 1.0);
  g_assert_true (vs.probe.loss.known);
  g_assert_cmpfloat_with_epsilon (vs.probe.loss.transmittance, 1.0, 0.03);
  g_assert_false (vs.probe.loss.unexplained);
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  g_test_add_func ("/probe-film/film-flagged", test_film_flagged);
  g_test_add_func ("/probe-film/clear-not-flagged", test_clear_not_flagged);
  return g_test_run ();
}
