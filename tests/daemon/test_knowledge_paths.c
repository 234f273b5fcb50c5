/* One knowledge path (daemon/operating/pattern_knowledge.h): a simulated rig that knows its
 * illuminator's geometry (descatterd --sim --scene) against the same rig calibrated on a clear
 * reference (`descatterctl calibrate`, its lines pasted), on generated scenes at a reduced size.
 *
 * Independent expectations:
 *  - the record built from the scene's geometry is what proc's calibrator measures on frames the
 *    renderer draws of the clear reference (another implementation, from pixels);
 *  - each request's prediction is compared with the error the chosen (or, refused, the named)
 *    point achieves against the simulator's truth: the simulated path's must be at least as close
 *    as the calibrated one's, within a factor KNOWLEDGE_TOLERANCE (the calibration's own noise
 *    moves a prediction by a few %), and a decision that differs must be the right one.
 * Prints the predicted and achieved errors of both paths per scene and request. */
#include <glib.h>
#include <math.h>
#include <string.h>

#include "daemon/ctl/scene_gen.h"
#include "daemon/ctl/sim_rig.h"
#include "daemon/ctl/validate.h"

#define KNOWLEDGE_SEED 36
#define KNOWLEDGE_SCENES 5
#define KNOWLEDGE_TOLERANCE 1.25

static const double targets[] = { 0.1, 0.25 };

/* A generated scene at 64 x 48 px; every other one with sine stripes (the generator draws mostly
 * square ones), so both patterns' records are checked. */
static char *
reduced_scene (guint index)
{
  g_autoptr (GError) error = NULL;
  g_autofree char *text = ds_scene_generate (KNOWLEDGE_SEED, index, 1, &error);
  g_assert_no_error (error);
  g_autoptr (GKeyFile) kf = g_key_file_new ();
  g_assert_true (g_key_file_load_from_data (kf, text, (gsize) -1, G_KEY_FILE_NONE, &error));
  g_key_file_set_integer (kf, "sensor", "width", 64);
  g_key_file_set_integer (kf, "sensor", "height", 48);
  if (index % 2 == 1) {
    g_key_file_set_string (kf, "illuminator", "pattern", "sine");
    double p = g_key_file_get_double (kf, "illuminator", "period-px", NULL);
    g_key_file_set_double (kf, "illuminator", "period-px", MAX (p, 5.0));
  }
  return g_key_file_to_data (kf, NULL, NULL);
}

static const char *
decision (const DsValidateOutcome *o)
{
  return o->refused ? "refused" : o->point.undetermined ? "undetermined" : "accepted";
}

/* The decision is vindicated by what its point achieves: a refusal by a miss, an acceptance by a
 * hit within the factor validation allows. An undetermined run claims neither. */
static gboolean
decision_right (const DsValidateOutcome *o)
{
  if (o->refused)
    return o->achieved > o->target_error;
  if (o->point.undetermined)
    return TRUE;
  return o->achieved <= 1.5 * o->target_error;
}

static double
log_miss (const DsValidateOutcome *o)
{
  return fabs (log (o->achieved / o->point.predicted_error));
}

static void
test_paths (void)
{
  DsOperatingModel model;
  ds_operating_model_init (&model);
  DsRigTiming timing;
  ds_rig_timing_init (&timing);
  guint compared = 0, scenes = 0;
  for (guint i = 0; i < KNOWLEDGE_SCENES; i++) {
    g_autofree char *text = reduced_scene (i);
    g_autofree char *name = g_strdup_printf ("generated %d/%u", KNOWLEDGE_SEED, i);
    g_autoptr (GError) error = NULL;
    g_autoptr (DsSimRig) rig = ds_sim_rig_new_from_data (text, name, &error);
    g_assert_no_error (error);
    DsValidateScene vs[2];
    gboolean probed[2];
    char *failure[2] = { NULL, NULL }; /* g_autofree would free only the first */
    for (guint way = 0; way < 2; way++) {
      DsValidateOptions o = { .calibrated = way == 0, .simulated = way == 1, .seed = 1 };
      g_autoptr (GError) local = NULL;
      probed[way] = ds_validate_probe (rig, &o, &vs[way], &local);
      if (!probed[way])
        failure[way] = g_strdup (local->message);
    }
    /* The pilot frames are the same frames both ways: both measure or neither. */
    g_assert_cmpint (probed[0], ==, probed[1]);
    if (!probed[0])
      g_print ("%s: pilot refused both ways: %s\n", name, failure[1]);
    g_free (failure[0]);
    g_free (failure[1]);
    if (!probed[0])
      continue;
    scenes++;
    const DsCalibration *cal = &vs[0].calibration, *sim = &vs[1].calibration;
    g_print ("%s: %s stripes P %.2f: harmonic gain calibrated %.4f, simulated %.4f; black level %.4f, %.4f\n", name,
             sim->pattern == DS_PATTERN_SINE ? "sine" : "square", sim->period_px, cal->harmonic_gain,
             sim->harmonic_gain, cal->black_level, sim->black_level);
    /* The record against the calibrator's measurement on the rendered reference. */
    if (!cal->scatter.scattering) {
      g_assert_cmpfloat (fabs (sim->harmonic_gain / cal->harmonic_gain - 1), <, 0.03);
      g_assert_cmpfloat (fabs (sim->black_level - cal->black_level), <, 0.02);
    }
    g_autoptr (DsErrorModel) em_cal = ds_error_model_new (&vs[0].probe, &vs[0].params);
    g_autoptr (DsErrorModel) em_sim = ds_error_model_new (&vs[1].probe, &vs[1].params);
    for (guint t = 0; t < G_N_ELEMENTS (targets); t++) {
      DsValidateOutcome o[2];
      DsErrorModel *em[2] = { em_cal, em_sim };
      for (guint way = 0; way < 2; way++) {
        g_assert_true (ds_validate_request (rig, &vs[way], em[way], &model, &timing, targets[t], 0, 7 + t, &o[way], &error));
        g_assert_no_error (error);
      }
      for (guint way = 0; way < 2; way++)
        g_print ("  target %.2f %-10s %-12s %s N=%u M=%u predicted %.4f (upper %.4f) achieved %.4f\n", targets[t],
                 way == 0 ? "calibrated" : "simulated", decision (&o[way]), ds_estimator_name (o[way].point.estimator),
                 o[way].point.phases, o[way].point.averages, o[way].point.predicted_error,
                 o[way].point.predicted_error_upper, o[way].achieved);
      if (isfinite (o[0].point.predicted_error) && isfinite (o[1].point.predicted_error)) {
        g_assert_cmpfloat (log_miss (&o[1]), <=, log_miss (&o[0]) + log (KNOWLEDGE_TOLERANCE));
        compared++;
      }
      if (strcmp (decision (&o[0]), decision (&o[1])) != 0)
        g_assert_true (decision_right (&o[1]));
      for (guint way = 0; way < 2; way++)
        ds_validate_outcome_clear (&o[way]);
    }
  }
  /* Scenes whose pilot is refused compare nothing: at least four must compare. */
  g_assert_cmpuint (scenes, >=, 4);
  g_assert_cmpuint (compared, >=, 4 * G_N_ELEMENTS (targets));
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  g_test_add_func ("/knowledge/simulated-against-calibrated", test_paths);
  return g_test_run ();
}
