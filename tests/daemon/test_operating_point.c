/* The automatic operating point's choice rules, its refusal with what would reach the target,
 * its record in the result metadata, and the model file format. The predictions themselves are
 * tested in test_error_model.c; here a hand-made probe stands for the pilot frames. */
#include <glib/gstdio.h>
#include <math.h>
#include <string.h>

#include "daemon/operating/operating_point.h"
#include "daemon/operating/stripe_model.h"
#include "report_json.h"

static DsSeparationParams params; /* square stripes, duty 1/2, no black level */

static DsSceneProbe
probe_of (double ld, double lg, double read_dn, double leak_per_px)
{
  DsSceneProbe p = { 0 };
  p.geometry = (DsStripeModel){ DS_PATTERN_SQUARE, 12, 0.5, 0, 0.3, 0 };
  p.blur.source = DS_BLUR_CALIBRATED;
  p.exposure_us = 2000;
  p.light.ld_mean = ld;
  p.light.ld_spread = 1.1;
  p.light.lg_mean = lg;
  p.leak.per_px = leak_per_px;
  p.leak.measured = TRUE;
  g_strlcpy (p.leak.note, "measured", sizeof p.leak.note);
  p.noise.var0 = read_dn * read_dn;
  p.noise.gain = 0.25;
  p.noise.dark_dn = 20;
  p.clip.saturation_dn = 4095;
  p.clip.bright_dn = 1000;
  p.width = 256;
  p.height = 192;
  return p;
}

/* With a target: the fastest candidate meeting it; nothing faster meets it (checked against
 * every candidate). Budget only: the most accurate within it. */
static void
test_choice (void)
{
  DsOperatingModel m;
  ds_operating_model_init (&m);
  m.n_phases = 5; /* 2, 3, 4, 6, 8: keeps the exhaustive check short */
  DsRigTiming t;
  ds_rig_timing_init (&t);
  DsSceneProbe p = probe_of (400, 800, 3, 0);
  g_autoptr (DsErrorModel) em = ds_error_model_new (&p, &params);
  DsOperatingPoint op;
  g_autoptr (GError) error = NULL;
  g_assert_true (ds_operating_point_choose (&m, em, &p, &t, 256, 192, 0.02, 0, &op, &error));
  g_assert_no_error (error);
  g_assert_cmpfloat (op.predicted_error, <=, 0.02);
  g_assert_false (op.lower_bound);
  double max_e = ds_scene_probe_max_exposure (&p);
  const DsEstimator est[] = { DS_ESTIMATOR_MAXMIN, DS_ESTIMATOR_SINE, DS_ESTIMATOR_ROBUST };
  for (guint e = 0; e < 3; e++)
    for (guint i = 0; i < m.n_phases; i++)
      for (guint j = 0; j < m.n_averages; j++)
        for (guint k = 0; k < m.n_exposure_factors; k++) {
          double exposure = p.exposure_us * m.exposure_factors[k];
          if (exposure > max_e)
            continue;
          DsErrorParts parts;
          if (!ds_error_model_predict (em, est[e], m.phases[i], m.averages[j], m.exposure_factors[k], 0, &parts, NULL))
            continue;
          double ms = ds_rig_timing_set_ms (&t, 256, 192, m.phases[i], m.averages[j], exposure, TRUE);
          if (parts.total <= 0.02)
            g_assert_cmpfloat (ms, >=, op.predicted_time_ms);
        }
  /* The exposure never exceeds what keeps the brightest pixels below the clip level. */
  g_assert_cmpfloat (op.exposure_us, <=, max_e);
  /* Budget only: the most accurate within it. */
  double budget = op.predicted_time_ms;
  DsOperatingPoint b;
  g_assert_true (ds_operating_point_choose (&m, em, &p, &t, 256, 192, 0, budget, &b, &error));
  g_assert_cmpfloat (b.predicted_time_ms, <=, budget);
  g_assert_cmpfloat (b.predicted_error, <=, op.predicted_error);
  /* The scale multiplies every prediction. */
  m.scale = 2;
  g_assert_true (ds_operating_point_choose (&m, em, &p, &t, 256, 192, 0, budget, &b, &error));
  g_assert_cmpfloat_with_epsilon (b.predicted_error, 2 * b.parts.total, 1e-12);
}

/* A target the rig cannot reach is refused with the best reachable error and what would reach
 * it: a larger budget when time is the limit, a finer period when the scattered stripes are. */
static void
test_refusal (void)
{
  DsOperatingModel m;
  ds_operating_model_init (&m);
  DsRigTiming t;
  ds_rig_timing_init (&t);
  DsSceneProbe p = probe_of (400, 800, 3, 0);
  g_autoptr (DsErrorModel) em = ds_error_model_new (&p, &params);
  DsOperatingPoint op;
  g_autoptr (GError) error = NULL;
  g_assert_false (ds_operating_point_choose (&m, em, &p, &t, 256, 192, 0.01, 20, &op, &error));
  g_test_message ("%s", error->message);
  g_assert_nonnull (strstr (error->message, "the best reachable is"));
  g_assert_nonnull (strstr (error->message, "A time budget of"));
  g_clear_error (&error);
  /* Scattered light keeps 27 % of the stripes at 12 px, 11 % at 6 px, 5 % at 3 px: no amount of
   * time helps, a finer period does. */
  DsSceneProbe leaky = probe_of (400, 2000, 3, 0.02);
  g_autoptr (DsErrorModel) em2 = ds_error_model_new (&leaky, &params);
  g_assert_false (ds_operating_point_choose (&m, em2, &leaky, &t, 256, 192, 0.15, 0, &op, &error));
  g_assert_nonnull (strstr (error->message, "A stripe period of"));
  g_assert_null (strstr (error->message, "A time budget of"));
  g_clear_error (&error);
  /* Not measured: the prediction is a lower bound, and the refusal says why. */
  leaky.leak.measured = FALSE;
  g_strlcpy (leaky.leak.note, "not measured (the illuminator cannot change its period)", sizeof leaky.leak.note);
  g_autoptr (DsErrorModel) em3 = ds_error_model_new (&leaky, &params);
  g_assert_true (ds_operating_point_choose (&m, em3, &leaky, &t, 256, 192, 0.15, 0, &op, &error));
  g_assert_true (op.lower_bound);
}

/* The most accurate candidate within a budget (0: none) by brute force over every candidate the
 * model holds, as the chooser must find it on the margin. */
static double
most_accurate (const DsOperatingModel *m, DsErrorModel *em, const DsSceneProbe *p, const DsRigTiming *t,
               double budget)
{
  const DsEstimator est[] = { DS_ESTIMATOR_MAXMIN, DS_ESTIMATOR_SINE, DS_ESTIMATOR_ROBUST };
  double best = INFINITY, max_e = ds_scene_probe_max_exposure (p);
  for (guint e = 0; e < 3; e++)
    for (guint i = 0; i < m->n_phases; i++)
      for (guint j = 0; j < m->n_averages; j++)
        for (guint k = 0; k < m->n_exposure_factors; k++) {
          double exposure = p->exposure_us * m->exposure_factors[k];
          DsErrorParts parts;
          if (exposure > max_e * (1 + 1e-9) ||
              (budget > 0 && ds_rig_timing_set_ms (t, 256, 192, m->phases[i], m->averages[j], exposure, TRUE) > budget) ||
              !ds_error_model_predict (em, est[e], m->phases[i], m->averages[j], m->exposure_factors[k], 0, &parts, NULL))
            continue;
          best = MIN (best, m->scale * parts.total);
        }
  return best;
}

/* A target no candidate is predicted to meet, but within the most accurate one's uncertainty
 * (one standard uncertainty: the model's leave-one-out spread and the probe's own): that point is
 * run and the result says the target may be missed; beyond the uncertainty it is refused as
 * before; a target the prediction meets is chosen as before, unflagged. */
static void
test_margin (void)
{
  DsOperatingModel m;
  ds_operating_model_init (&m);
  m.n_phases = 5;
  m.scale_spread = 0.2;
  DsRigTiming t;
  ds_rig_timing_init (&t);
  DsSceneProbe p = probe_of (400, 800, 3, 0);
  g_autoptr (DsErrorModel) em = ds_error_model_new (&p, &params);
  double best = most_accurate (&m, em, &p, &t, 0);
  g_assert_true (isfinite (best));
  g_autoptr (GError) error = NULL;
  DsOperatingPoint op;
  /* 10 % under the best prediction: inside exp (-0.2) = 0.82. */
  g_assert_true (ds_operating_point_choose (&m, em, &p, &t, 256, 192, 0.9 * best, 0, &op, &error));
  g_assert_no_error (error);
  g_assert_true (op.target_may_be_missed);
  g_assert_cmpfloat_with_epsilon (op.predicted_error, best, 1e-12 * best);
  g_assert_cmpfloat (op.uncertainty, >=, 0.2);
  g_assert_nonnull (strstr (op.target_note, "is predicted to reach"));
  g_assert_nonnull (strstr (op.target_note, "the target may be missed"));
  g_assert_true (op.undetermined);
  g_test_message ("%s", op.target_note);
  /* 25 % under it: beyond one standard uncertainty, refused with the optimistic end named. */
  g_assert_false (ds_operating_point_choose (&m, em, &p, &t, 256, 192, 0.75 * best, 0, &op, &error));
  g_assert_nonnull (strstr (error->message, "even its lower end's optimistic end"));
  g_clear_error (&error);
  /* Without a spread the same 10 % is refused: the probe's own uncertainty here is well under it. */
  m.scale_spread = 0;
  g_assert_false (ds_operating_point_choose (&m, em, &p, &t, 256, 192, 0.9 * best, 0, &op, &error));
  g_clear_error (&error);
  /* A target the best prediction meets: chosen as before (the fastest meeting it), not flagged. */
  m.scale_spread = 0.2;
  g_assert_true (ds_operating_point_choose (&m, em, &p, &t, 256, 192, 1.5 * best, 0, &op, &error));
  g_assert_false (op.target_may_be_missed);
  g_assert_cmpfloat (op.predicted_error, <=, 1.5 * best);
  g_assert_cmpstr (op.target_note, ==, "");
  /* With a budget the margin is the most accurate point within it. */
  double budget = 40, in_budget = most_accurate (&m, em, &p, &t, budget);
  g_assert_cmpfloat (in_budget, >, best);
  g_assert_true (ds_operating_point_choose (&m, em, &p, &t, 256, 192, 0.95 * in_budget, budget, &op, &error));
  g_assert_true (op.target_may_be_missed);
  g_assert_cmpfloat (op.predicted_time_ms, <=, budget);
  g_assert_cmpfloat_with_epsilon (op.predicted_error, in_budget, 1e-12 * in_budget);
  /* A target no point reaches at any time, with a budget: refused naming the most accurate point
   * within the budget (it named the fastest candidate, the first to "meet" an infinite target). */
  g_assert_false (ds_operating_point_choose (&m, em, &p, &t, 256, 192, 0.5 * best, budget, &op, &error));
  g_assert_cmpfloat_with_epsilon (op.predicted_error, in_budget, 1e-12 * in_budget);
  g_autofree char *named = g_strdup_printf ("the best reachable is %.4f", in_budget);
  g_assert_nonnull (strstr (error->message, named));
  g_clear_error (&error);
}

/* The probe's part of the uncertainty against the error model itself: Ld moved by its uncertainty
 * moves the prediction by the uncertainty's Ld term within [1/2, 1] of it (the noise over Ld falls
 * as Ld^-1/2 where shot noise of the direct light dominates, as Ld^-1 where read noise or the
 * scattered light's does; the sampling part does not move). */
static void
test_uncertainty_ld (void)
{
  DsOperatingModel m;
  ds_operating_model_init (&m);
  const double u_ld = 0.1;
  const struct {
    double ld, lg, read_dn;
  } scenes[] = { { 400, 800, 3 }, { 3000, 0, 1 }, { 200, 50, 12 } };
  for (guint i = 0; i < G_N_ELEMENTS (scenes); i++) {
    DsSceneProbe p = probe_of (scenes[i].ld, scenes[i].lg, scenes[i].read_dn, 0);
    p.light.ld_uncertainty = u_ld;
    DsSceneProbe q = p;
    q.light.ld_mean *= 1 + u_ld;
    g_autoptr (DsErrorModel) ep = ds_error_model_new (&p, &params);
    g_autoptr (DsErrorModel) eq = ds_error_model_new (&q, &params);
    DsErrorParts a, b;
    g_assert_true (ds_error_model_predict (ep, DS_ESTIMATOR_SINE, 8, 1, 1, 0, &a, NULL));
    g_assert_true (ds_error_model_predict (eq, DS_ESTIMATOR_SINE, 8, 1, 1, 0, &b, NULL));
    double moved = log (a.total / b.total);
    /* The Ld term alone: the uncertainty without it (the noise estimate's term) taken out in quadrature. */
    double with = ds_operating_point_uncertainty (&m, &p, &a, 0);
    p.light.ld_uncertainty = 0;
    double without = ds_operating_point_uncertainty (&m, &p, &a, 0);
    double term = sqrt (with * with - without * without);
    g_test_message ("Ld %g Lg %g read %g: prediction %.5f -> %.5f (%.4f), Ld term %.4f", scenes[i].ld, scenes[i].lg,
                    scenes[i].read_dn, a.total, b.total, moved, term);
    /* log (1.1) = 0.953 x 0.1, and Ld^-1/2 at the least (0.48; the synthetic sets' own noise moves it by a few %) */
    g_assert_cmpfloat (moved, <=, 1.02 * term);
    g_assert_cmpfloat (moved, >=, 0.4 * term);
  }
  /* Scattered stripes: the pilot measures the modulated light Ld (1 + L), so Ld read higher by u
   * leaves a leak L' = (1 + L)/(1 + u) - 1. sine on sine stripes, with the harmonic gain the
   * pixels see, reads the modulated light: its noise-free error is L, and it moves by
   * ln (L / L') ~ (1 + L)/L u: 0.115 for L = 0.1, u = 0.01, eleven times Ld's own move (noise is
   * small here). At twice the pilot's period the leak is (1 + L)^2 - 1 (an exponential kernel
   * tail), and the move is that leak's. */
  const double L = 0.1, u = 0.01, P = 12;
  for (guint k = 1; k <= 2; k++) {
    double period = k * P, leak = pow (1 + L, k) - 1;
    DsSceneProbe p = probe_of (3000, 3000, 1, log1p (L) / P);
    p.geometry.kind = DS_PATTERN_SINE;
    DsSeparationParams sp;
    ds_separation_params_init (&sp, 8);
    sp.pattern = DS_PATTERN_SINE;
    sp.duty = 0.5;
    DsStripeModel at_period = p.geometry; /* the pixels' gain at the period the sets run at */
    at_period.period_px = period;
    sp.harmonic_gain = ds_stripe_harmonic (&at_period, 1);
    p.light.ld_uncertainty = u;
    DsSceneProbe q = p;
    q.light.ld_mean *= 1 + u;
    q.leak.per_px = log1p ((1 + leak) / (1 + u) - 1) / period;
    g_assert_cmpfloat_with_epsilon (ds_scene_probe_leak (&p, period, 1), leak, 1e-12);
    g_autoptr (DsErrorModel) ep = ds_error_model_new (&p, &sp);
    g_autoptr (DsErrorModel) eq = ds_error_model_new (&q, &sp);
    DsErrorParts a, b;
    g_assert_true (ds_error_model_predict (ep, DS_ESTIMATOR_SINE, 8, 1, 1, period, &a, NULL));
    g_assert_true (ds_error_model_predict (eq, DS_ESTIMATOR_SINE, 8, 1, 1, period, &b, NULL));
    g_assert_cmpfloat_with_epsilon (a.systematic, leak, 0.01 * leak);
    double closed = log (leak / ((1 + leak) / (1 + u) - 1)), moved = log (a.systematic / b.systematic);
    double with = ds_operating_point_uncertainty (&m, &p, &a, period);
    p.light.ld_uncertainty = 0;
    double without = ds_operating_point_uncertainty (&m, &p, &a, period);
    double term = sqrt (with * with - without * without);
    g_test_message ("leak %g at %g px: prediction %.5f -> %.5f (%.4f, closed form %.4f), Ld term %.4f", leak, period,
                    a.total, b.total, moved, closed, term);
    g_assert_cmpfloat (closed, >, 5 * u);
    g_assert_cmpfloat (fabs (moved / closed - 1), <, 0.1);
    g_assert_cmpfloat (fabs (term / closed - 1), <, 0.1);
  }
  /* A leak far smaller than Ld's uncertainty (1e-4 against 1 %) may be none, and the stripes'
   * part then vanishes: the prediction falls at most to the error without it, here the sampling
   * error alone (noise-free parts: 0.05 with 0.04 of stripes over 0.03 of sampling), by
   * ln (0.05 / 0.03), not by (1 + L)/L times 1 %, a hundredfold. */
  {
    DsSceneProbe p = probe_of (3000, 0, 1, log1p (1e-4) / P);
    p.light.ld_uncertainty = u;
    DsErrorParts parts = { .total = 0.05, .systematic = 0.05, .sampling = 0.03, .scattered_stripes = 0.04 };
    DsOperatingModel exact = m;
    exact.scale_spread = 0;
    g_assert_cmpfloat_with_epsilon (ds_operating_point_uncertainty (&exact, &p, &parts, 0), log (0.05 / 0.03), 1e-9);
    /* A fitted leak of none, or below none (the fit's noise), says no more: the same bound, never a
     * negative or undefined term. */
    for (int sign = 0; sign >= -1; sign--) {
      p.leak.per_px = sign * log1p (1e-4) / P;
      double u0 = ds_operating_point_uncertainty (&exact, &p, &parts, 0);
      g_assert_true (isfinite (u0));
      g_assert_cmpfloat_with_epsilon (u0, log (0.05 / 0.03), 1e-9);
    }
  }
  /* The spread adds in quadrature. */
  DsSceneProbe p = probe_of (400, 800, 3, 0);
  DsErrorParts noise_free = { .total = 0.05, .sampling = 0.05, .systematic = 0.05 };
  m.scale_spread = 0.15;
  p.light.ld_uncertainty = 0.3;
  g_assert_cmpfloat_with_epsilon (ds_operating_point_uncertainty (&m, &p, &noise_free, 0), 0.15, 1e-12);
}

static void
test_report_json (void)
{
  DsOperatingReport r = { .target_error = 0.05, .scale = 1.2, .pilot_frames = 5, .pilot_ms = 30 };
  r.probe = probe_of (400, 800, 3, 0.01);
  r.probe.leak.measured = FALSE;
  g_strlcpy (r.probe.leak.note, "not measured (no second period)", sizeof r.probe.leak.note);
  r.point = (DsOperatingPoint){ .estimator = DS_ESTIMATOR_SINE, .phases = 8, .averages = 2, .exposure_us = 4000,
                                .period_px = 12, .predicted_error = 0.048, .predicted_time_ms = 90,
                                .lower_bound = TRUE,
                                .parts = { .total = 0.04, .noise = 0.03, .systematic = 0.0265, .sampling = 0.0265 } };
  g_autoptr (JsonNode) root = report_json (&r);
  JsonObject *o = json_node_get_object (root);
  g_assert_cmpfloat (json_object_get_double_member (o, "predicted_error"), ==, 0.048);
  g_assert_true (json_object_get_boolean_member (o, "lower_bound"));
  /* A lower bound the pilot does not bound from above: no upper end, not one equal to the
   * prediction (which would read as an error known exactly). */
  g_assert_true (json_object_get_null_member (o, "predicted_error_upper"));
  g_assert_false (json_object_get_boolean_member (o, "target_may_be_missed"));
  g_assert_cmpstr (json_object_get_string_member (o, "target_note"), ==, "");
  JsonArray *contains = json_object_get_array_member (o, "contains");
  gboolean has_noise = FALSE, has_leak = FALSE;
  for (guint i = 0; i < json_array_get_length (contains); i++) {
    has_noise |= strcmp (json_array_get_string_element (contains, i), "noise") == 0;
    has_leak |= strcmp (json_array_get_string_element (contains, i), "scattered_stripes") == 0;
  }
  g_assert_true (has_noise);
  g_assert_false (has_leak);
  JsonArray *why = json_object_get_array_member (o, "lower_bound_reasons");
  g_assert_cmpuint (json_array_get_length (why), ==, 1);
  g_assert_nonnull (strstr (json_array_get_string_element (why, 0), "no second period"));
  g_assert_cmpfloat (json_object_get_double_member (json_object_get_object_member (o, "parts"), "noise"), ==, 0.03);
  /* The probe measured the blur: no assumption listed; the pattern check's, when it made one. */
  g_assert_cmpuint (json_array_get_length (json_object_get_array_member (o, "assumptions")), ==, 0);
  g_strlcpy (r.pattern_assumption, "off-stripe level taken as scattered light", sizeof r.pattern_assumption);
  g_autoptr (JsonNode) root2 = report_json (&r);
  JsonArray *assumed = json_object_get_array_member (json_node_get_object (root2), "assumptions");
  g_assert_cmpuint (json_array_get_length (assumed), ==, 1);
  g_assert_cmpstr (json_array_get_string_element (assumed, 0), ==, "off-stripe level taken as scattered light");
  /* Not a lower bound: the upper end is the prediction; chosen on the margin: said so. */
  r.point.lower_bound = FALSE;
  r.point.upper_bounded = TRUE;
  r.point.predicted_error_upper = 0.048;
  r.point.uncertainty = 0.19;
  r.point.target_may_be_missed = TRUE;
  g_strlcpy (r.point.target_note, "no operating point is predicted to reach", sizeof r.point.target_note);
  g_autoptr (JsonNode) root3 = report_json (&r);
  JsonObject *o3 = json_node_get_object (root3);
  g_assert_cmpfloat (json_object_get_double_member (o3, "predicted_error_upper"), ==, 0.048);
  g_assert_cmpfloat (json_object_get_double_member (o3, "predicted_error_uncertainty"), ==, 0.19);
  g_assert_true (json_object_get_boolean_member (o3, "target_may_be_missed"));
  g_assert_cmpstr (json_object_get_string_member (o3, "target_note"), ==, "no operating point is predicted to reach");
}

static void
test_model_file (void)
{
  g_autofree char *dir = g_dir_make_tmp ("opmodel-XXXXXX", NULL);
  g_autofree char *path = g_build_filename (dir, "operating-model.conf", NULL);
  DsOperatingModel m;
  ds_operating_model_init (&m);
  m.scale = 1.25;
  m.scale_spread = 0.1875;
  m.n_averages = 2;
  g_strlcpy (m.fitted_on, "a;b", sizeof m.fitted_on);
  g_autoptr (GError) error = NULL;
  g_assert_true (ds_operating_model_write (&m, path, &error));
  g_autoptr (DsOperatingModel) back = ds_operating_model_load (path, &error);
  g_assert_no_error (error);
  g_assert_cmpfloat (back->scale, ==, 1.25);
  g_assert_cmpfloat (back->scale_spread, ==, 0.1875);
  g_assert_cmpuint (back->n_averages, ==, 2);
  g_assert_cmpuint (back->n_phases, ==, m.n_phases);
  g_assert_cmpstr (back->fitted_on, ==, "a;b");
  /* Damaged files are refused with the file and the key. */
  const struct {
    const char *text, *expect;
  } bad[] = {
    { "[operating-model]\nscale=0.3\n", "scale" },
    { "[operating-model]\nscale-spread=-0.1\n", "scale-spread: a number in [0, 1]" },
    { "[operating-model]\nphases=1;4\n", "phases: 1 is outside" },
    { "[operating-model]\nexposure-factors=1;-2\n", "exposure-factors" },
    { "[operating-model]\nspeed=3\n", "unknown key speed" },
    { "# descatter operating model (descatterctl study); safety=1.1\nscene,estimator\n", "" },
  };
  for (guint i = 0; i < G_N_ELEMENTS (bad); i++) {
    g_assert_true (g_file_set_contents (path, bad[i].text, -1, NULL));
    g_clear_error (&error);
    g_assert_null (ds_operating_model_load (path, &error));
    g_assert_nonnull (error);
    g_assert_nonnull (strstr (error->message, bad[i].expect));
    g_assert_nonnull (strstr (error->message, path));
  }
  g_unlink (path);
  g_rmdir (dir);
}

/* An interval from a term nobody measured (the blur of sine stripes at 5 px, neither calibrated
 * nor fitted: error_model.h): a target between the interval's ends is neither accepted nor
 * refused but run as undetermined, with the interval named; a target below every point's lower end
 * (over its uncertainty) is refused; one above the upper end is accepted. The ends in closed form:
 * the sine estimator on a pixel-integrating sensor reads Ld low by 1 - sinc (1/P) sharp, by
 * 1 - sinc (1/P) exp (-2 pi^2 s^2 / P^2) at the assumed blur s = P/8 (0.065 and 0.313 at 5 px). */
static void
test_interval_decision (void)
{
  DsOperatingModel m;
  ds_operating_model_init (&m);
  DsRigTiming t;
  ds_rig_timing_init (&t);
  DsSceneProbe p = probe_of (2000, 0, 3, 0);
  p.geometry = (DsStripeModel){ DS_PATTERN_SINE, 5, 0.5, 0, 0, 0 };
  p.blur.source = DS_BLUR_ASSUMED_SHARP;
  DsSeparationParams sine = params;
  sine.pattern = DS_PATTERN_SINE;
  g_autoptr (DsErrorModel) em = ds_error_model_new (&p, &sine);
  const double P = 5, sinc = sin (G_PI / P) / (G_PI / P), s = P / 8;
  double lower = 1 - sinc, upper = 1 - sinc * exp (-2 * G_PI * G_PI * s * s / (P * P));
  g_autoptr (GError) error = NULL;
  DsOperatingPoint op;
  /* Between the ends: run, undetermined, the interval in the note. */
  g_assert_true (ds_operating_point_choose (&m, em, &p, &t, 256, 192, 0.25, 0, &op, &error));
  g_assert_no_error (error);
  g_test_message ("%s", op.target_note);
  g_assert_true (op.undetermined);
  g_assert_true (op.target_may_be_missed);
  g_assert_cmpfloat (m.scale * op.predicted_error, <=, 1.1 * lower);
  g_assert_cmpfloat (op.predicted_error_upper, >, 0.25);
  g_assert_cmpfloat (op.predicted_error_upper, <=, 1.1 * m.scale * upper);
  g_assert_nonnull (strstr (op.target_note, "undetermined"));
  g_assert_nonnull (strstr (op.target_note, "blur is not known"));
  /* Below every lower end: refused. */
  g_assert_false (ds_operating_point_choose (&m, em, &p, &t, 256, 192, 0.5 * lower, 0, &op, &error));
  g_assert_nonnull (strstr (error->message, "even its lower end"));
  g_clear_error (&error);
  /* Above the upper end: accepted, not flagged. */
  g_assert_true (ds_operating_point_choose (&m, em, &p, &t, 256, 192, 1.2 * upper, 0, &op, &error));
  g_assert_false (op.undetermined);
  g_assert_false (op.target_may_be_missed);
  g_assert_cmpfloat (op.predicted_error_upper, <=, 1.2 * upper);
}

/* The points the choice compares are those a request can name (error_model.h): on square
 * stripes, maxmin and robust only with aN >= 1 and (1 - a)N >= 1, sine with N >= 3, the closed
 * form written here. At duty 0.396 maxmin N = 2 (aN = 0.79) is refused even though its synthetic
 * set, which knows the period, separates the pixels fully lit in one phase; so it is never chosen
 * nor named as the best reachable point, whatever the request. */
static gboolean
request_rule (DsEstimator e, guint n, double a)
{
  if (e == DS_ESTIMATOR_SINE)
    return n >= 3;
  return a * n >= 1 - 1e-9 && (1 - a) * n >= 1 - 1e-9;
}

static void
test_request_rule (void)
{
  const double duties[] = { 0.2, 0.396, 0.5, 0.73 };
  const DsEstimator est[] = { DS_ESTIMATOR_MAXMIN, DS_ESTIMATOR_SINE, DS_ESTIMATOR_ROBUST };
  for (guint d = 0; d < G_N_ELEMENTS (duties); d++) {
    DsSceneProbe p = probe_of (400, 800, 3, 0);
    p.geometry.duty = duties[d];
    p.geometry.period_px = 10;
    DsSeparationParams sp = params;
    sp.duty = duties[d];
    sp.geometry.period_px = 10;
    sp.geometry.pixel_aperture = 1;
    g_autoptr (DsErrorModel) em = ds_error_model_new (&p, &sp);
    for (guint e = 0; e < 3; e++)
      for (guint n = 2; n <= 8; n++) {
        g_autoptr (GError) error = NULL;
        gboolean ok = ds_error_model_request_accepts (em, est[e], n, &error);
        g_assert_cmpint (ok, ==, request_rule (est[e], n, duties[d]));
        g_assert_true (ok == (error == NULL));
      }
  }
  /* The choice at duty 0.396 over N = 2, 3, 4 (M = 1, the pilot's exposure): what it chooses for a
   * budget, and the best point a refusal names, both pass the rule. */
  DsOperatingModel m;
  ds_operating_model_init (&m);
  m.n_phases = 3;
  m.phases[0] = 2, m.phases[1] = 3, m.phases[2] = 4;
  m.n_averages = 1;
  m.averages[0] = 1;
  m.n_exposure_factors = 1;
  m.exposure_factors[0] = 1;
  DsRigTiming t;
  ds_rig_timing_init (&t);
  DsSceneProbe p = probe_of (400, 800, 3, 0);
  p.geometry.duty = 0.396;
  p.geometry.period_px = 10;
  p.geometry.blur_px = 0.05;
  DsSeparationParams sp = params;
  sp.duty = 0.396;
  sp.geometry.period_px = 10;
  sp.geometry.pixel_aperture = 1;
  g_autoptr (DsErrorModel) em = ds_error_model_new (&p, &sp);
  /* The synthetic set alone would take maxmin N = 2. */
  DsErrorParts parts;
  g_assert_true (ds_error_model_predict (em, DS_ESTIMATOR_MAXMIN, 2, 1, 1, 0, &parts, NULL));
  DsOperatingPoint op;
  g_autoptr (GError) error = NULL;
  g_assert_true (ds_operating_point_choose (&m, em, &p, &t, 256, 192, 0, 1e6, &op, &error));
  g_assert_true (request_rule (op.estimator, op.phases, 0.396));
  double fastest = ds_rig_timing_set_ms (&t, 256, 192, 2, 1, p.exposure_us, TRUE);
  /* A budget only N = 2 fits: nothing a request can name fits it. */
  g_assert_false (ds_operating_point_choose (&m, em, &p, &t, 256, 192, 0, fastest * 1.01, &op, &error));
  g_test_message ("%s", error->message);
  g_clear_error (&error);
  g_assert_false (ds_operating_point_choose (&m, em, &p, &t, 256, 192, 1e-6, 0, &op, &error));
  g_assert_nonnull (strstr (error->message, "the best reachable is"));
  g_assert_true (request_rule (op.estimator, op.phases, 0.396));
  g_assert_null (strstr (error->message, "maxmin, N=2,"));
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  ds_separation_params_init (&params, 4);
  g_test_add_func ("/operating-point/choice", test_choice);
  g_test_add_func ("/operating-point/refusal", test_refusal);
  g_test_add_func ("/operating-point/margin", test_margin);
  g_test_add_func ("/operating-point/interval-decision", test_interval_decision);
  g_test_add_func ("/operating-point/uncertainty-ld", test_uncertainty_ld);
  g_test_add_func ("/operating-point/report-json", test_report_json);
  g_test_add_func ("/operating-point/model-file", test_model_file);
  g_test_add_func ("/operating-point/request-rule", test_request_rule);
  return g_test_run ();
}
