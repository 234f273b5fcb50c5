/* The operating-point model against its closed form, the choice rules, and its file format. */
#include <glib/gstdio.h>
#include <math.h>
#include <string.h>

#include "daemon/operating/operating_point.h"

static const DsModelRow rows[] = {
  /* scene, estimator, N, M, a, b, S, f, base exposure */
  { "clear", DS_ESTIMATOR_MAXMIN, 4, 1, 4e-4, 1e-6, 2000, 0.8, 1000 },
  { "clear", DS_ESTIMATOR_MAXMIN, 8, 1, 3e-4, 4e-6, 2000, 0.8, 1000 },
  { "clear", DS_ESTIMATOR_MAXMIN, 8, 4, 1e-4, 4e-6, 2000, 0.8, 1000 },
  { "dense", DS_ESTIMATOR_MAXMIN, 4, 1, 9e-2, 1e-3, 3000, 0.05, 1000 },
  { "dense", DS_ESTIMATOR_MAXMIN, 8, 1, 6e-2, 2e-3, 3000, 0.05, 1000 },
  { "dense", DS_ESTIMATOR_MAXMIN, 8, 4, 2e-2, 2e-3, 3000, 0.05, 1000 },
};

/* The prediction is the documented formula: the row of the scene closest in direct fraction,
 * its noise part scaled by (f_s^2 S_s) / (f^2 S(E)) and the safety factor applied. */
static void
test_prediction_closed_form (void)
{
  g_autoptr (DsOperatingModel) m = ds_operating_model_new (rows, G_N_ELEMENTS (rows), 1.5);
  DsSceneStats st = { .signal_dn = 1000, .direct_fraction = 0.6, .exposure_us = 500 };
  double p = ds_operating_model_predict (m, &st, DS_ESTIMATOR_MAXMIN, 8, 4, 2000);
  double signal = 1000 * 2000.0 / 500.0;
  double expect = 1.5 * sqrt (1e-4 * (0.8 * 0.8 * 2000) / (0.6 * 0.6 * signal) + 4e-6);
  g_assert_cmpfloat_with_epsilon (p, expect, 1e-12);
  /* A scene with little direct light takes the dense scene's systematic part. */
  DsSceneStats dense = { .signal_dn = 3000, .direct_fraction = 0.04, .exposure_us = 1000 };
  p = ds_operating_model_predict (m, &dense, DS_ESTIMATOR_MAXMIN, 4, 1, 1000);
  expect = 1.5 * sqrt (9e-2 * (0.05 * 0.05 * 3000) / (0.04 * 0.04 * 3000) + 1e-3);
  g_assert_cmpfloat_with_epsilon (p, expect, 1e-12);
  /* A configuration not in the model cannot be predicted. */
  g_assert_true (isinf (ds_operating_model_predict (m, &st, DS_ESTIMATOR_SINE, 8, 1, 1000)));
}

/* With a target: the fastest configuration that meets it; with only a budget: the most
 * accurate within it; neither possible: an error that says what is achievable. */
static void
test_choice (void)
{
  g_autoptr (DsOperatingModel) m = ds_operating_model_new (rows, G_N_ELEMENTS (rows), 1.0);
  DsRigTiming t;
  ds_rig_timing_init (&t);
  DsSceneStats st = { .signal_dn = 2000, .direct_fraction = 0.8, .exposure_us = 1000 };
  DsOperatingPoint p;
  g_autoptr (GError) error = NULL;
  g_assert_true (ds_operating_point_choose (m, &st, &t, 256, 192, 4000, 0.02, 0, &p, &error));
  g_assert_cmpfloat (p.predicted_error, <=, 0.02);
  /* Nothing faster meets the target: check every configuration and exposure exhaustively. */
  const double factors[] = { 0.5, 1, 2, 4 };
  for (guint i = 0; i < 3; i++)
    for (guint k = 0; k < 4; k++) {
      double e = MIN (1000 * factors[k], 4000);
      double err = ds_operating_model_predict (m, &st, rows[i].estimator, rows[i].phases, rows[i].averages, e);
      double ms = ds_rig_timing_set_ms (&t, 256, 192, rows[i].phases, rows[i].averages, e, TRUE);
      if (err <= 0.02)
        g_assert_cmpfloat (ms, >=, p.predicted_time_ms);
    }
  /* Budget only: the most accurate within it. */
  double budget = ds_rig_timing_set_ms (&t, 256, 192, 8, 1, 4000, TRUE);
  g_assert_true (ds_operating_point_choose (m, &st, &t, 256, 192, 4000, 0, budget, &p, &error));
  g_assert_cmpfloat (p.predicted_time_ms, <=, budget);
  g_assert_cmpuint (p.averages, ==, 1); /* M = 4 does not fit */
  /* Impossible: the message names the best achievable error. */
  g_assert_false (ds_operating_point_choose (m, &st, &t, 256, 192, 4000, 1e-5, budget, &p, &error));
  g_assert_nonnull (strstr (error->message, "best within the budget"));
}

/* Scene statistics from one frame of known Ld, Lg: square stripes duty 1/2 (m = 1/2,
 * h = 2/pi), frame = Ld p(x) + Lg/2 + dark. */
static void
test_scene_stats (void)
{
  const double ld = 300, lg = 900, dark = 20;
  const guint w = 128, h = 8;
  g_autoptr (DsImage) f = ds_image_new (DS_SAMPLE_F32, w, h, NULL);
  for (guint y = 0; y < h; y++) {
    float *r = ds_image_row (f, y);
    for (guint x = 0; x < w; x++) {
      double u = (x + 0.5) / 16.0;
      u -= floor (u + 0.5);
      r[x] = (float) (ld * (fabs (u) < 0.25) + lg * 0.5 + dark);
    }
  }
  DsSceneStats st;
  g_autoptr (GError) error = NULL;
  g_assert_true (ds_scene_stats_from_frame (f, dark, 16.0, 0.5, 2.0 / G_PI, 1000, &st, &error));
  g_assert_no_error (error);
  /* Pixel-sampled square wave: the first harmonic of 8 lit of 16 samples is
   * sin(pi/2)/(16 sin(pi/16)) * 2 ... within 2 % of the continuous 2/pi. */
  g_assert_cmpfloat (fabs (st.signal_dn - (ld + lg)) / (ld + lg), <, 0.02);
  g_assert_cmpfloat (fabs (st.direct_fraction - ld / (ld + lg)) / (ld / (ld + lg)), <, 0.02);
}

static void
test_file_round_trip_and_errors (void)
{
  g_autofree char *dir = g_dir_make_tmp ("opmodel-XXXXXX", NULL);
  g_autofree char *path = g_build_filename (dir, "model.csv", NULL);
  g_autoptr (GError) error = NULL;
  g_assert_true (ds_operating_model_write (rows, G_N_ELEMENTS (rows), 1.25, path, &error));
  g_autoptr (DsOperatingModel) m = ds_operating_model_load (path, &error);
  g_assert_no_error (error);
  g_assert_cmpfloat (ds_operating_model_safety (m), ==, 1.25);
  DsSceneStats st = { .signal_dn = 2000, .direct_fraction = 0.8, .exposure_us = 1000 };
  g_autoptr (DsOperatingModel) ref = ds_operating_model_new (rows, G_N_ELEMENTS (rows), 1.25);
  g_assert_cmpfloat (ds_operating_model_predict (m, &st, DS_ESTIMATOR_MAXMIN, 8, 4, 1000), ==,
                     ds_operating_model_predict (ref, &st, DS_ESTIMATOR_MAXMIN, 8, 4, 1000));
  /* A damaged row is refused with its line number. */
  g_assert_true (g_file_set_contents (path,
                                      "# safety=1\nscene,estimator,phases,averages,a,b,signal_dn,direct_fraction,base_exposure_us\n"
                                      "x,maxmin,8,1,0.1,0.1,100,0.5,1000\nx,maxmin,1,1,0.1,0.1,100,0.5,1000\n",
                                      -1, NULL));
  g_clear_error (&error);
  g_assert_null (ds_operating_model_load (path, &error));
  g_assert_nonnull (strstr (error->message, ":4:"));
  g_unlink (path);
  g_rmdir (dir);
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  g_test_add_func ("/operating-point/prediction", test_prediction_closed_form);
  g_test_add_func ("/operating-point/choice", test_choice);
  g_test_add_func ("/operating-point/scene-stats", test_scene_stats);
  g_test_add_func ("/operating-point/file", test_file_round_trip_and_errors);
  return g_test_run ();
}
