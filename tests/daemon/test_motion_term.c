/* The motion term of the operating point (daemon/operating/motion_term.h) against a closed form
 * and the simulator:
 *   - a dark bar with sharp edges, moving d px over a set of many evenly spaced frames: each
 *     edge's band of width d departs from the middle by 1/4 on average, so
 *     term^2 = kappa * rows * 2 * d / 4 / sum T^2;
 *   - the study's moving disc (tests/daemon/study-speed.scene) rendered and separated on
 *     noise-free frames at their times (ds_sim_rig_separate_at, the simulator's truth at the
 *     set's middle): the systematic error sine (on sine stripes) and max/min (on square ones)
 *     achieve against the term predicted from the still scene, within a factor 1.5 (the
 *     criterion docs/accuracy.md validates every prediction of the operating point on);
 *   - a declared speed adds in quadrature; motion seen with no speed declared, or an estimator
 *     without a model, marks the point a lower bound. */
#include <math.h>
#include <string.h>

#include "daemon/ctl/sim_rig.h"
#include "daemon/operating/motion_term.h"
#include "proc/metrics.h"

static void
test_bar_closed_form (void)
{
  const guint w = 240, h = 6, bar_x = 60, bar_w = 60;
  g_autoptr (GError) error = NULL;
  g_autoptr (DsImage) t = ds_image_new (DS_SAMPLE_F32, w, h, &error);
  double light = 0;
  for (guint y = 0; y < h; y++)
    for (guint x = 0; x < w; x++) {
      float v = x >= bar_x && x < bar_x + bar_w ? 0.0f : 1.0f;
      ((float *) ds_image_row (t, y))[x] = v;
      light += v * v;
    }
  const guint n = 401;
  double times[401];
  for (guint k = 0; k < n; k++)
    times[k] = 0.002 + 0.1 * k / (n - 1); /* 100 ms */
  const double speeds[] = { 200.0, 400.0 }; /* 20 and 40 px over the set */
  for (guint i = 0; i < G_N_ELEMENTS (speeds); i++) {
    double d = speeds[i] * 0.1;
    for (DsEstimator est = DS_ESTIMATOR_MAXMIN; est <= DS_ESTIMATOR_SINE; est++) {
      double term = 0;
      g_assert_true (ds_motion_term (t, speeds[i], times, n, est, &term, &error));
      g_assert_no_error (error);
      double expect = sqrt (ds_motion_kappa (est) * h * 2 * d / 4 / light);
      g_test_message ("%s, %g px: term %.4f, closed form %.4f", ds_estimator_name (est), d, term, expect);
      /* The bar's edge, linear over the pixel between its two levels, departs a little less than
       * a sharp one (a fraction of a pixel against d/4 per edge). */
      g_assert_cmpfloat (fabs (term / expect - 1), <, 0.02);
    }
  }
  g_assert_cmpfloat (fabs (ds_motion_kappa (DS_ESTIMATOR_SINE) - 4 * (1.0 / 12 + 1 / (2 * G_PI * G_PI))), <, 1e-12);
  g_assert_cmpfloat (ds_motion_kappa (DS_ESTIMATOR_MAXMIN), ==, (3.0 / 8) / (1.0 / 4));
  g_assert_true (isnan (ds_motion_kappa (DS_ESTIMATOR_ROBUST)));
  /* A still scene has no motion term. */
  double still = 1;
  g_assert_true (ds_motion_term (t, 0, times, n, DS_ESTIMATOR_SINE, &still, &error));
  g_assert_cmpfloat (still, ==, 0);
  double bad;
  g_assert_false (ds_motion_term (t, NAN, times, n, DS_ESTIMATOR_SINE, &bad, NULL));
}

/* The systematic transmissive error a set on noise-free frames at their times achieves against
 * the truth at the set's middle. */
static double
achieved (const DsSimRig *rig, DsEstimator est, guint n, const double *times, double exposure)
{
  const DsScene *scene = ds_sim_rig_scene (rig);
  DsSeparationParams p;
  ds_separation_params_init (&p, n);
  p.estimator = est;
  p.pattern = ds_scene_pattern_is_sine (scene) ? DS_PATTERN_SINE : DS_PATTERN_SQUARE;
  p.duty = ds_scene_duty (scene);
  p.system_gain = ds_scene_system_gain (scene);
  p.read_noise_dn = ds_scene_read_noise_dn (scene);
  p.geometry.period_px = ds_scene_period_px (scene);
  p.geometry.pixel_aperture = 1;
  g_autoptr (GError) error = NULL;
  DsSeparation *sep = NULL;
  g_assert_true (ds_sim_rig_separate_at (rig, &p, 1, 1, exposure, 0, TRUE, times, &sep, NULL, &error));
  g_assert_no_error (error);
  DsImage *tt = NULL, *tg = NULL;
  g_assert_true (ds_renderer_truth_at (ds_sim_rig_renderer (rig), exposure, 0, (times[0] + times[n - 1]) / 2, &tt,
                                       &tg, &error));
  g_autoptr (DsImage) truth_t = tt;
  g_autoptr (DsImage) truth_g = tg;
  DsErrorStats st;
  g_assert_true (ds_metrics_error (sep->transmissive, truth_t, sep->mask, DS_MASK_SATURATED | DS_MASK_NONFINITE,
                                   &st, &error));
  ds_separation_free (sep);
  return st.relative_rmse;
}

/* The study's scene with its stripes as given: sine for the sine estimator, square (duty 1/2)
 * for max/min, the stripes each kappa was derived on. */
static DsSimRig *
speed_scene (gboolean square)
{
  g_autofree char *text = NULL;
  g_assert_true (g_file_get_contents (DS_SPEED_SCENE, &text, NULL, NULL));
  g_autoptr (GString) t = g_string_new (text);
  if (square)
    g_assert_cmpuint (g_string_replace (t, "pattern = sine", "pattern = square", 1), ==, 1);
  g_autoptr (GError) error = NULL;
  DsSimRig *rig = ds_sim_rig_new_from_data (t->str, "study-speed.scene", &error);
  g_assert_no_error (error);
  return rig;
}

static void
test_against_the_simulator (void)
{
  g_autoptr (GError) error = NULL;
  DsRigTiming timing;
  ds_rig_timing_init (&timing);
  const struct {
    double speed;
    guint n;
  } cases[] = { { 100, 4 }, { 100, 8 }, { 100, 16 }, { 400, 6 }, { 400, 8 }, { 400, 16 } };
  for (DsEstimator est = DS_ESTIMATOR_MAXMIN; est <= DS_ESTIMATOR_SINE; est++) {
    g_autoptr (DsSimRig) still = speed_scene (est == DS_ESTIMATOR_MAXMIN);
    const DsScene *scene = ds_sim_rig_scene (still);
    guint w = ds_scene_width (scene), h = ds_scene_height (scene);
    double exposure = ds_scene_default_exposure_us (scene);
    DsImage *tt = NULL, *tg = NULL;
    g_assert_true (ds_renderer_truth (ds_sim_rig_renderer (still), exposure, 0, &tt, &tg, &error));
    g_autoptr (DsImage) pilot = tt; /* the scene as a still pilot sees it */
    g_autoptr (DsImage) pilot_g = tg;
    for (guint i = 0; i < G_N_ELEMENTS (cases); i++) {
      g_autoptr (DsSimRig) rig = ds_sim_rig_with_speed (still, cases[i].speed, "fish", &error);
      g_assert_no_error (error);
      double times[64];
      ds_motion_frame_times (&timing, w, h, cases[i].n, 1, exposure, times);
      double term = 0;
      g_assert_true (ds_motion_term (pilot, cases[i].speed, times, cases[i].n, est, &term, &error));
      double still_err = achieved (still, est, cases[i].n, times, exposure);
      double moving_err = achieved (rig, est, cases[i].n, times, exposure);
      /* What motion added, in quadrature to the still set's own systematic error (0 here: sine
       * on sine stripes and max/min on square ones with a N >= 1 are exact). */
      g_assert_cmpfloat (still_err, <, 1e-3);
      double added = sqrt (MAX (0.0, moving_err * moving_err - still_err * still_err));
      g_test_message ("%s %g px/s N %u: predicted %.4f, achieved %.4f (ratio %.2f)", ds_estimator_name (est),
                      cases[i].speed, cases[i].n, term, added, term / added);
      g_assert_cmpfloat (term, <, 1.5 * added);
      g_assert_cmpfloat (term, >, added / 1.5);
    }
  }
}

/* The table (whole-pixel shifts kept, the interpolation's departure in closed form between them)
 * against ds_motion_term's pixel-by-pixel sums: the same numbers, at fractional, negative and
 * border-crossing shifts, on an image with edges, ramps and texture. With noise and its variance,
 * the noise's expectation is taken out: the term of a noisy image lands on the clean image's. */
static void
test_table (void)
{
  const guint w = 97, h = 300; /* more rows than the table keeps: it samples them */
  g_autoptr (GError) error = NULL;
  g_autoptr (DsImage) t = ds_image_new (DS_SAMPLE_F32, w, h, &error);
  g_autoptr (DsImage) noisy = ds_image_new (DS_SAMPLE_F32, w, h, &error);
  g_autoptr (DsImage) var = ds_image_new (DS_SAMPLE_F32, w, h, &error);
  g_autoptr (GRand) rng = g_rand_new_with_seed (7);
  const double sigma = 0.2;
  for (guint y = 0; y < h; y++) {
    float *row = ds_image_row (t, y), *nr = ds_image_row (noisy, y), *vr = ds_image_row (var, y);
    for (guint x = 0; x < w; x++) {
      /* The same along y (so that sampled rows stand for all), a bar, a ramp and a sine along x. */
      double v = 1.0 + 0.3 * sin (x * 0.7);
      if (x >= 20 && x < 35)
        v = 0.1;
      if (x >= 60 && x < 80)
        v *= (x - 60) / 20.0;
      row[x] = (float) v;
      /* Box-Muller */
      double u1 = g_rand_double_range (rng, 1e-12, 1), u2 = g_rand_double (rng);
      nr[x] = (float) (v + sigma * sqrt (-2 * log (u1)) * cos (2 * G_PI * u2));
      vr[x] = (float) (sigma * sigma);
    }
  }
  g_autoptr (DsMotionTable) table = ds_motion_table_new (t, NULL, &error);
  g_assert_no_error (error);
  const double speeds[] = { 3.7, 41.3, 250, 1e4 }; /* the last crosses the whole width */
  const guint ns[] = { 2, 5, 16 };
  for (guint i = 0; i < G_N_ELEMENTS (speeds); i++)
    for (guint j = 0; j < G_N_ELEMENTS (ns); j++) {
      double times[16];
      for (guint k = 0; k < ns[j]; k++)
        times[k] = 0.013 + 0.0071 * k + 0.002 * (k % 3); /* uneven, as M frames per phase are */
      for (DsEstimator est = DS_ESTIMATOR_MAXMIN; est <= DS_ESTIMATOR_SINE; est++) {
        double direct = 0;
        g_assert_true (ds_motion_term (t, speeds[i], times, ns[j], est, &direct, &error));
        double tabled = ds_motion_table_term (table, speeds[i], times, ns[j], est);
        g_assert_cmpfloat (fabs (tabled - direct), <=, 1e-9 + 1e-6 * direct);
      }
      g_assert_true (isnan (ds_motion_table_term (table, speeds[i], times, ns[j], DS_ESTIMATOR_ROBUST)));
    }
  g_autoptr (DsMotionTable) with_noise = ds_motion_table_new (noisy, var, &error);
  g_assert_no_error (error);
  g_autoptr (DsMotionTable) ignoring = ds_motion_table_new (noisy, NULL, &error);
  const double times[] = { 0, 0.01, 0.02, 0.03, 0.04, 0.05 };
  double clean = 0;
  g_assert_true (ds_motion_term (t, 100, times, 6, DS_ESTIMATOR_SINE, &clean, &error));
  double taken_out = ds_motion_table_term (with_noise, 100, times, 6, DS_ESTIMATOR_SINE);
  double left_in = ds_motion_table_term (ignoring, 100, times, 6, DS_ESTIMATOR_SINE);
  g_test_message ("clean %.4f, noise taken out %.4f, noise left in %.4f", clean, taken_out, left_in);
  /* 256 rows of 97 px: the noise's own scatter is a few % of the departure. */
  g_assert_cmpfloat (fabs (taken_out / clean - 1), <, 0.05);
  g_assert_cmpfloat (left_in / clean - 1, >, 0.2);
  /* Refusals: no light, a noise variance of another size. */
  g_autoptr (DsImage) dark = ds_image_new (DS_SAMPLE_F32, w, 4, &error);
  memset (dark->data, 0, dark->stride * 4);
  g_assert_null (ds_motion_table_new (dark, NULL, &error));
  g_assert_error (error, G_IO_ERROR, G_IO_ERROR_INVALID_ARGUMENT);
  g_clear_error (&error);
  g_assert_null (ds_motion_table_new (t, dark, &error));
  g_assert_error (error, G_IO_ERROR, G_IO_ERROR_INVALID_ARGUMENT);
}

static void
test_apply (void)
{
  DsOperatingPoint p = { .predicted_error = 0.03, .predicted_error_upper = 0.04 };
  const char *why = NULL;
  g_assert_false (ds_motion_apply (&p, 100, 0.04, 0, &why));
  g_assert_null (why);
  g_assert_cmpfloat (fabs (p.predicted_error - 0.05), <, 1e-12);
  g_assert_cmpfloat (fabs (p.predicted_error_upper - sqrt (0.04 * 0.04 * 2)), <, 1e-12);
  g_assert_false (p.lower_bound);
  DsOperatingPoint q = { .predicted_error = 0.03, .predicted_error_upper = 0.04 };
  g_assert_false (ds_motion_apply (&q, NAN, NAN, 0, &why)); /* no speed, no motion seen: a still scene */
  g_assert_false (q.lower_bound);
  g_assert_true (ds_motion_apply (&q, NAN, NAN, 12, &why)); /* motion seen, no speed declared */
  g_assert_true (q.lower_bound);
  g_assert_nonnull (strstr (why, "no speed declared"));
  /* A lower bound for motion has nothing above it. */
  g_assert_true (isinf (q.predicted_error_upper) && !q.upper_bounded);
  g_assert_cmpfloat (q.predicted_error, ==, 0.03);
  DsOperatingPoint r = { .predicted_error = 0.03, .predicted_error_upper = 0.04 };
  g_assert_true (ds_motion_apply (&r, 50, NAN, 0, &why)); /* robust: no model */
  g_assert_true (r.lower_bound);
  g_assert_nonnull (strstr (why, "no model"));
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  g_test_add_func ("/motion-term/bar-closed-form", test_bar_closed_form);
  g_test_add_func ("/motion-term/against-the-simulator", test_against_the_simulator);
  g_test_add_func ("/motion-term/table", test_table);
  g_test_add_func ("/motion-term/apply", test_apply);
  return g_test_run ();
}
