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
#include "daemon/operating/film_bound.h"
#include "daemon/operating/scene_probe_loss.h"
#include "probe_rig.h"

#define FILM_MEDIUM                                                                                         \
  "[medium]\nthickness-mm=0.778364\nmua=0.00500796\nmus=0.348032\ng=0.927405\nn=1.41235\n"                 \
  "photons=100000\nseed=286599\n\n"

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
    FILM_SCENE (FILM_MEDIUM);
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

/* One automatic capture on the calibrated simulated rig (as `descatterctl validate` runs it): the
 * choice for `target` (0: the most accurate point within a long budget), run, its achieved
 * error the relative RMSE against the renderer's direct light. */
static void
request (const char *text, const char *name, double target, DsValidateScene *vs, DsValidateOutcome *o)
{
  g_autoptr (GError) error = NULL;
  g_autoptr (DsSimRig) rig = probe_rig_new_probed (text, name, vs);
  DsOperatingModel model;
  ds_operating_model_init (&model);
  DsRigTiming timing;
  ds_rig_timing_init (&timing);
  g_autoptr (DsErrorModel) errors = ds_error_model_new (&vs->probe, &vs->params);
  g_assert_true (ds_validate_request (rig, vs, errors, &model, &timing, target, target > 0 ? 0 : 1e6, 3, o, &error));
  g_assert_no_error (error);
  g_test_message ("%s, target %.4g: %s%s N=%u M=%u, predicted %.4f to %.4f, achieved %.4f%s; %s", name, target,
                  o->refused ? "refused " : "", ds_estimator_name (o->point.estimator), o->point.phases,
                  o->point.averages, o->point.predicted_error, o->point.predicted_error_upper, o->achieved,
                  o->point.target_may_be_missed ? " (may be missed)" : "", vs->probe.loss.bound_note);
}

/* The film's upper end holds what the film achieves, with the lens's cone the scene declares:
 * its light in the cone passes for direct light, which the lower end cannot see. The upper end
 * rests on g <= DS_FILM_MAX_G (the film's 0.93 is below) and the loss's upper confidence, so it is
 * above the achieved error, but within a few times it: single scattering at g = 0.95 puts at most
 * 1.3 times the film's share in the cone. */
static void
test_film_upper_end (void)
{
  static const char text[] = FILM_SCENE (FILM_MEDIUM);
  DsValidateScene vs;
  DsValidateOutcome o;
  request (text, "film", 0, &vs, &o);
  g_assert_true (vs.probe.loss.unexplained);
  g_assert_true (vs.probe.loss.bounded);
  g_assert_false (o.refused);
  g_assert_true (o.point.lower_bound);
  g_assert_true (o.point.upper_bounded);
  g_assert_cmpfloat (o.point.predicted_error, <=, o.achieved);
  g_assert_cmpfloat (o.achieved, <=, o.point.predicted_error_upper);
  g_assert_cmpfloat (o.point.predicted_error_upper, <=, 6 * o.achieved);
  double lower = o.point.predicted_error, upper = o.point.predicted_error_upper;
  ds_validate_outcome_clear (&o);
  /* The decision on the interval: a target the upper end meets is accepted without the flag; one
   * between the ends is run on the margin with it. */
  DsValidateScene vs2;
  request (text, "film", 1.05 * upper, &vs2, &o);
  g_assert_false (o.refused);
  g_assert_false (o.point.target_may_be_missed);
  g_assert_cmpfloat (o.point.predicted_error_upper, <=, 1.05 * upper);
  ds_validate_outcome_clear (&o);
  request (text, "film", sqrt (lower * upper), &vs2, &o);
  g_assert_false (o.refused);
  g_assert_true (o.point.target_may_be_missed);
  ds_validate_outcome_clear (&o);
}

/* An absorbing slab that loses the film's light into the lens: flagged the same way, and the upper
 * end, a film's, still holds its achieved error. The frames cannot tell the two apart: the probe
 * reads the same transmittance and predicts the same lower end for both, while the film's light in
 * the cone gives it an error many times the absorber's. No prediction from these frames is within
 * a factor 1.5 of both, and a target between the two errors is met by one and missed by the
 * other: the limit docs/accuracy.md states for thin forward-peaked films. */
static void
test_absorber_upper_end (void)
{
  static const char film[] = FILM_SCENE (FILM_MEDIUM);
  double n = 1.41235, d = 0.778364;
  double mua = -log (truth_transmittance (film) / ds_probe_fresnel_transmittance (n)) / d;
  g_autofree char *medium = g_strdup_printf ("[medium]\nthickness-mm=%.6f\nmua=%.6f\nmus=0.0001\ng=0.927405\n"
                                             "n=%.5f\nphotons=100000\nseed=286599\n\n",
                                             d, mua, n);
  g_autofree char *text = g_strdup_printf (FILM_SCENE ("%s"), medium);
  g_assert_cmpfloat_with_epsilon (truth_transmittance (text), truth_transmittance (film), 0.01);
  DsValidateScene vs;
  DsValidateOutcome o;
  request (text, "absorber", 0, &vs, &o);
  g_assert_true (vs.probe.loss.unexplained);
  g_assert_false (o.refused);
  g_assert_true (o.point.upper_bounded);
  g_assert_cmpfloat (o.achieved, <=, o.point.predicted_error_upper);

  DsValidateScene vs_film;
  DsValidateOutcome o_film;
  request (film, "film", 0, &vs_film, &o_film);
  g_test_message ("transmittance: absorber %.4f, film %.4f (sigma %.3f)", vs.probe.loss.transmittance,
                  vs_film.probe.loss.transmittance, vs.probe.loss.sigma);
  g_assert_cmpfloat (fabs (vs.probe.loss.transmittance - vs_film.probe.loss.transmittance), <=,
                     vs.probe.loss.sigma * vs.probe.loss.transmittance);
  g_assert_cmpfloat (fabs (log (o.point.predicted_error / o_film.point.predicted_error)), <=, log (1.2));
  g_assert_cmpfloat (o_film.achieved, >, 1.5 * 1.5 * 4 * o.achieved);
  ds_validate_outcome_clear (&o_film);
  ds_validate_outcome_clear (&o);
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  g_test_add_func ("/probe-film/film-flagged", test_film_flagged);
  g_test_add_func ("/probe-film/clear-not-flagged", test_clear_not_flagged);
  g_test_add_func ("/probe-film/film-upper-end", test_film_upper_end);
  g_test_add_func ("/probe-film/absorber-upper-end", test_absorber_upper_end);
  return g_test_run ();
}
