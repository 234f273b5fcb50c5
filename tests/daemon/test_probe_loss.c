/* The light a scene loses against the open field (daemon/operating/scene_probe_loss.h): pilot
 * frames in closed form, square stripes whose every pixel is the stripes' Fourier series times the
 * light that crosses the scene, T L0 (L0 the open field's lit level, T the transmittance into the
 * lens), opaque objects over some rows (they darken pixels and move no harmonic's shape), and
 * Gaussian noise of a shot-noise model. Independent expectations: the transmittance the frames
 * were made with; two faces of index 1.6 pass (1 - R) / (1 + R) = 0.899 with R = (0.6 / 2.6)^2,
 * so a loss of that size is no sign of a medium; a loss well beyond it while the stripes keep all
 * the light that arrives makes the prediction a lower bound that says so, and a target then may be
 * missed; scattered light the probe sees itself (wide, keeping no stripes) is no such case. */
#include <json-glib/json-glib.h>
#include <math.h>
#include <string.h>

#include "daemon/operating/error_model.h"
#include "daemon/operating/film_bound.h"
#include "daemon/operating/operating_point.h"
#include "daemon/operating/scene_probe.h"
#include "daemon/operating/scene_probe_loss.h"
#include "pilot_pairs.h"
#include "report_json.h"

#define W 240
#define H 100
#define PERIOD 16.0
#define DUTY 0.5
#define BLUR 0.6
#define OPEN_DN 400.0
#define DARK_DN 20.0

typedef struct {
  double transmittance;  /* of the light that keeps the stripes, over the open field */
  double wide;           /* scattered light keeping no stripes, over the open field */
  guint object_rows;     /* rows 0.. of an opaque object */
} Scene;

static DsImage *
frame (const Scene *s, double period, double shift, gboolean on, GRand *r)
{
  DsImage *f = ds_image_new (DS_SAMPLE_F32, W, H, NULL);
  double ld = OPEN_DN * s->transmittance, profile[W];
  for (guint x = 0; x < W; x++) {
    double v = on ? (ld + OPEN_DN * s->wide) * DUTY : 0;
    for (guint n = 1; on && n < 300; n++) {
      double k = G_PI * n / period;
      double c = 2 / (n * G_PI) * sin (n * G_PI * DUTY) * exp (-2 * k * k * BLUR * BLUR) * sin (k) / k;
      v += ld * c * cos (2 * G_PI * n * (x / period - shift));
    }
    profile[x] = v;
  }
  for (guint y = 0; y < H; y++) {
    float *row = ds_image_row (f, y);
    for (guint x = 0; x < W; x++) {
      double v = y < s->object_rows ? 0 : profile[x], sd = sqrt (4.0 + 0.25 * v);
      double u1 = 1 - g_rand_double (r), u2 = g_rand_double (r);
      row[x] = (float) (DARK_DN + v + sd * sqrt (-2 * log (u1)) * cos (2 * G_PI * u2));
    }
  }
  return f;
}

static DsImage *
pilot_frame (gconstpointer s, double q, double shift, gboolean on, GRand *r)
{
  return frame (s, q, shift, on, r);
}

/* Probes the scene from pairs at P, 2P and the finer periods, the open field given (or 0), the
 * lens's acceptance half-angle given (or 0). */
static void
probe_lens (const Scene *s, double open_dn, double cone_deg, DsSceneProbe *p)
{
  DsProbeFrames base = { .exposure_us = 1000, .geometry = { DS_PATTERN_SQUARE, PERIOD, DUTY, 0, 0 },
                         .blur_known = TRUE, .calibrated_blur_px = BLUR, .open_field_dn = open_dn,
                         .acceptance_half_angle_deg = cone_deg };
  pilot_pairs_probe (pilot_frame, s, &base, BLUR, 7, p);
}

static void
probe (const Scene *s, double open_dn, DsSceneProbe *p)
{
  probe_lens (s, open_dn, 0, p);
}

/* The point the daemon chooses (default model and timing, 4-phase error model) for a target (0:
 * none) within a budget; its report's lower_bound_reasons joined into *reasons. */
static void
choose (const DsSceneProbe *p, double target, DsOperatingPoint *op, char **reasons)
{
  DsOperatingModel m;
  ds_operating_model_init (&m);
  DsRigTiming timing;
  ds_rig_timing_init (&timing);
  DsSeparationParams params;
  ds_separation_params_init (&params, 4);
  g_autoptr (DsErrorModel) em = ds_error_model_new (p, &params);
  g_autoptr (GError) error = NULL;
  gboolean ok = ds_operating_point_choose (&m, em, p, &timing, W, H, target, 200, op, &error);
  g_assert_no_error (error);
  g_assert_true (ok);
  DsOperatingReport r = { .time_budget_ms = 200, .target_error = target, .probe = *p, .point = *op };
  g_autoptr (JsonNode) root = report_json (&r);
  JsonObject *o = json_node_get_object (root);
  g_assert_cmpint (json_object_get_boolean_member (o, "lower_bound"), ==, op->lower_bound);
  JsonArray *why = json_object_get_array_member (o, "lower_bound_reasons");
  GString *all = g_string_new (NULL);
  for (guint i = 0; i < json_array_get_length (why); i++)
    g_string_append_printf (all, "%s\n", json_array_get_string_element (why, i));
  *reasons = g_string_free (all, FALSE);
}

/* Probes a scene whose stripes keep `t` of the open field, `wide` arriving as scattered light that
 * keeps no stripes, `rows` rows behind an opaque object, the open field known: the stage must read
 * the transmittance t + wide within 2 %. */
static void
probe_measured (double t, double wide, guint rows, DsSceneProbe *p)
{
  Scene s = { .transmittance = t, .wide = wide, .object_rows = rows };
  probe (&s, OPEN_DN, p);
  g_assert_true (p->loss.known);
  g_assert_cmpfloat_with_epsilon (p->loss.transmittance, t + wide, 0.02);
}

/* probe_measured (t, 0, rows), whose loss must be flagged as asked, and the point chosen without a
 * target: its lower_bound_reasons, joined. */
static char *
chosen_reasons (double t, guint rows, gboolean flagged, DsSceneProbe *p, DsOperatingPoint *op)
{
  probe_measured (t, 0, rows, p);
  g_assert_cmpint (p->loss.unexplained, ==, flagged);
  char *reasons = NULL;
  choose (p, 0, op, &reasons);
  return reasons;
}

static void
test_fresnel (void)
{
  double r = (0.6 / 2.6) * (0.6 / 2.6);
  g_assert_cmpfloat_with_epsilon (ds_probe_fresnel_transmittance (1.6), (1 - r) / (1 + r), 1e-12);
  g_assert_cmpfloat_with_epsilon (ds_probe_fresnel_transmittance (1.0), 1.0, 1e-12);
}

/* The whole open field arrives, 40 % of the rows behind an opaque object: measured at 1, no flag. */
static void
test_clear_with_objects (void)
{
  DsSceneProbe p;
  DsOperatingPoint op;
  g_autofree char *reasons = chosen_reasons (1, 40, FALSE, &p, &op);
  g_assert_null (strstr (reasons, "open field"));
}

/* A Fresnel-sized loss (two faces of index 1.6): measured, no flag. */
static void
test_fresnel_loss (void)
{
  DsSceneProbe p;
  probe_measured (ds_probe_fresnel_transmittance (1.6), 0, 20, &p);
  g_assert_false (p.loss.unexplained);
}

/* 75 % of the open field, the stripes keep all of it: a lower bound that names the loss, no upper
 * end, and a reachable target may be missed. */
static void
test_loss_flagged (void)
{
  DsSceneProbe p;
  DsOperatingPoint op;
  g_autofree char *reasons = chosen_reasons (0.75, 40, TRUE, &p, &op);
  g_assert_true (op.lower_bound);
  g_assert_true (isinf (op.predicted_error_upper));
  g_assert_nonnull (strstr (reasons, "of the open field's light"));
  DsOperatingPoint aimed;
  g_autofree char *aimed_reasons = NULL;
  choose (&p, 0.5, &aimed, &aimed_reasons);
  g_assert_true (aimed.target_may_be_missed);
  g_assert_nonnull (strstr (aimed.target_note, "open field"));
  g_assert_false (p.loss.bounded);
  g_assert_nonnull (strstr (aimed.target_note, "acceptance angle is not known"));
}

/* The single-scattering film bias (film_bound.h) written out: faces of index 1.3, cone narrowed
 * by refraction, g = 0.95, at a transmittance t. */
static double
film_bias (double t, double cone_deg)
{
  double r = (0.3 / 2.3) * (0.3 / 2.3), tp = t * (1 + r) / (1 - r);
  double f = ds_film_cone_fraction (0.95, asin (sin (cone_deg * G_PI / 180) / 1.3));
  double s_in = f * (1 - tp) / (1 - f);
  return s_in / (tp - s_in);
}

/* The same loss with the lens's cone known (5 degrees): an upper end, the film's bias at the
 * loss's upper confidence (the 3 % calibration allowance twice, and the frames' noise) added; a
 * target it meets is accepted without the flag, one between the ends runs with it. */
static void
test_loss_bounded (void)
{
  Scene s = { .transmittance = 0.75, .object_rows = 40 };
  DsSceneProbe p;
  probe_lens (&s, OPEN_DN, 5, &p);
  g_assert_true (p.loss.unexplained);
  g_assert_true (p.loss.bounded);
  double t = p.loss.transmittance;
  g_assert_cmpfloat (p.loss.bias_upper, >=, film_bias (t * (1 - 2 * 0.03), 5));
  g_assert_cmpfloat (p.loss.bias_upper, <=, film_bias (t * (1 - 2 * 0.035), 5));
  DsOperatingPoint op;
  g_autofree char *reasons = NULL;
  choose (&p, 0, &op, &reasons);
  g_assert_true (op.lower_bound);
  g_assert_true (op.upper_bounded);
  g_assert_cmpfloat (op.predicted_error_upper, >=, op.predicted_error + p.loss.bias_upper - 1e-12);
  DsOperatingPoint met;
  g_autofree char *met_reasons = NULL;
  choose (&p, 1.2 * op.predicted_error_upper, &met, &met_reasons);
  g_assert_false (met.target_may_be_missed);
  g_assert_cmpfloat (met.predicted_error_upper, <=, 1.2 * op.predicted_error_upper);
  DsOperatingPoint between;
  g_autofree char *between_reasons = NULL;
  choose (&p, 0.5 * p.loss.bias_upper, &between, &between_reasons);
  g_assert_true (between.target_may_be_missed);
  g_assert_nonnull (strstr (between.target_note, "Henyey-Greenstein"));
}

/* Half the open field keeps the stripes and 30 % arrives as scattered light that keeps none: the
 * probe sees the scattered light itself, no flag. */
static void
test_seen_scatter_not_flagged (void)
{
  DsSceneProbe p;
  probe_measured (0.5, 0.3, 0, &p);
  g_assert_false (p.loss.unexplained);
}

/* No open field given (an old configuration): not measured, nothing changes. */
static void
test_not_known (void)
{
  Scene s = { .transmittance = 0.6 };
  DsSceneProbe p;
  probe (&s, 0, &p);
  g_assert_false (p.loss.known);
  g_assert_false (p.loss.unexplained);
  g_assert_nonnull (strstr (p.loss.note, "not measured"));
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  g_test_add_func ("/probe-loss/fresnel", test_fresnel);
  g_test_add_func ("/probe-loss/clear-with-objects", test_clear_with_objects);
  g_test_add_func ("/probe-loss/fresnel-loss", test_fresnel_loss);
  g_test_add_func ("/probe-loss/loss-flagged", test_loss_flagged);
  g_test_add_func ("/probe-loss/loss-bounded", test_loss_bounded);
  g_test_add_func ("/probe-loss/seen-scatter", test_seen_scatter_not_flagged);
  g_test_add_func ("/probe-loss/not-known", test_not_known);
  return g_test_run ();
}
