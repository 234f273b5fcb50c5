/* The sampling precondition of maxmin and robust (aN >= 1 and (1 - a)N >= 1 with the pixel
 * aperture and the edge blur), robust's windows from the geometry, and the predicted
 * systematic errors; checked against separations of frames rendered here by numerical
 * integration of the blurred stripes over each pixel (not the library's closed form). */
#include <glib.h>
#include <math.h>
#include <string.h>

#include "proc/proc_error.h"
#include "proc/separation.h"

typedef struct {
  double period, duty, black, blur, aperture, offset; /* offset in cycles */
  gboolean sine;
} Stripes;

/* Lit fraction at the point x for phase k of n: the square (or sine) pattern with Gaussian
 * edges, from erfc at a point. */
static double
point_value (const Stripes *s, double x, guint k, guint n)
{
  double centre0 = (s->offset + (double) k / n) * s->period;
  if (s->sine) {
    double g = exp (-2 * G_PI * G_PI * s->blur * s->blur / (s->period * s->period));
    return 0.5 * (1 + g * cos (2 * G_PI * (x - centre0) / s->period));
  }
  double half = 0.5 * s->duty * s->period, v = 0;
  long j0 = lround ((x - centre0) / s->period);
  for (long j = j0 - 3; j <= j0 + 3; j++) {
    double c = centre0 + j * s->period;
    if (s->blur <= 0)
      v += fabs (x - c) < half ? 1 : 0;
    else
      v += 0.5 * erfc (-(x - c + half) / (s->blur * G_SQRT2)) - 0.5 * erfc (-(x - c - half) / (s->blur * G_SQRT2));
  }
  return v;
}

/* Pixel x (centre at x) integrating over its aperture: midpoint rule, `points` points. */
static double
pixel_value (const Stripes *s, guint x, guint k, guint n, int points)
{
  if (s->aperture <= 0)
    return point_value (s, x, k, n);
  double sum = 0;
  for (int i = 0; i < points; i++)
    sum += point_value (s, x - 0.5 * s->aperture + (i + 0.5) * s->aperture / points, k, n);
  return sum / points;
}

/* The N phases of one row of w pixels, Ld = 1000, Lg = lg: n x w values. */
static double *
render_row (const Stripes *s, guint n, guint w, double lg, int points)
{
  double m = s->sine ? s->black + (1 - s->black) * 0.5 : s->duty + s->black * (1 - s->duty);
  double *v = g_new (double, (gsize) n * w);
  for (guint k = 0; k < n; k++)
    for (guint x = 0; x < w; x++)
      v[(gsize) k * w + x] = 1000 * (s->black + (1 - s->black) * pixel_value (s, x, k, n, points)) + lg * m;
  return v;
}

/* Rendered rows (two identical rows per frame) through the separation, float frames. */
static DsSeparation *
separate_values (const DsSeparationParams *p, const double *v, guint w, GError **error)
{
  guint n = p->n_phases;
  g_autoptr (DsPhaseSet) set = ds_phase_set_new (p, w, 2, error);
  if (!set)
    return NULL;
  for (guint k = 0; k < n; k++) {
    g_autoptr (DsImage) f = ds_image_new (DS_SAMPLE_F32, w, 2, NULL);
    for (guint x = 0; x < w; x++)
      ((float *) ds_image_row (f, 0))[x] = ((float *) ds_image_row (f, 1))[x] = (float) v[(gsize) k * w + x];
    if (!ds_phase_set_accumulate (set, k, f, error))
      return NULL;
  }
  return ds_phase_set_finalize (set, error);
}

/* One row of w pixels, Ld = 1000, Lg = lg, float frames; the result of the separation. */
static DsSeparation *
separate_row (const DsSeparationParams *p, const Stripes *s, guint w, double lg, GError **error)
{
  g_autofree double *v = render_row (s, p->n_phases, w, lg, 400);
  return separate_values (p, v, w, error);
}

static void
params_for (DsSeparationParams *p, guint n, DsEstimator e, const Stripes *s, gboolean geometry)
{
  ds_separation_params_init (p, n);
  p->estimator = e;
  p->pattern = s->sine ? DS_PATTERN_SINE : DS_PATTERN_SQUARE;
  p->duty = s->duty;
  p->black_level = s->black;
  if (geometry) {
    p->geometry.period_px = s->period;
    p->geometry.edge_blur_px = s->blur;
    p->geometry.edge_blur_known = TRUE;
    p->geometry.pixel_aperture = s->aperture;
  }
}

/* Without a period only aN >= 1 and (1 - a)N >= 1 can be checked: refused below, for maxmin and
 * robust only, by validate and by ds_phase_set_new, with the numbers in the message. */
static void
test_point_condition (void)
{
  const struct {
    guint n;
    double a;
    DsEstimator e;
    gboolean ok;
  } cases[] = {
    { 3, 0.3, DS_ESTIMATOR_MAXMIN, FALSE }, /* aN = 0.9: the scene */
    { 3, 0.3, DS_ESTIMATOR_ROBUST, FALSE },
    { 3, 0.3, DS_ESTIMATOR_SINE, TRUE },
    { 4, 0.3, DS_ESTIMATOR_MAXMIN, TRUE },  /* 1.2 */
    { 3, 0.75, DS_ESTIMATOR_MAXMIN, FALSE }, /* (1 - a)N = 0.75 */
    { 2, 0.5, DS_ESTIMATOR_MAXMIN, TRUE },  /* exactly 1 */
    { 8, 0.1, DS_ESTIMATOR_MAXMIN, FALSE },
  };
  for (guint i = 0; i < G_N_ELEMENTS (cases); i++) {
    DsSeparationParams p;
    ds_separation_params_init (&p, cases[i].n);
    p.duty = cases[i].a;
    p.estimator = cases[i].e;
    g_autoptr (GError) error = NULL;
    DsSamplingCheck check;
    gboolean ok = ds_separation_check_sampling (&p, &check, &error);
    g_assert_cmpint (ok, ==, cases[i].ok);
    g_assert_cmpint (ds_separation_params_validate (&p, NULL), ==, cases[i].ok);
    g_assert_cmpfloat_with_epsilon (check.lit_phases, cases[i].a * cases[i].n, 1e-12);
    g_assert_true (isnan (check.affected_fraction));
    if (!ok) {
      g_assert_error (error, DS_PROC_ERROR, DS_PROC_ERROR_PRECONDITION);
      g_autofree char *lit = g_strdup_printf ("aN = %.3g", cases[i].a * cases[i].n);
      g_assert_nonnull (strstr (error->message, lit));
      g_assert_cmpstr (check.refusal, ==, error->message);
      g_clear_error (&error);
      g_assert_null (ds_phase_set_new (&p, 8, 8, &error));
      g_assert_error (error, DS_PROC_ERROR, DS_PROC_ERROR_PRECONDITION);
    } else {
      g_assert_cmpstr (check.refusal, ==, "");
    }
  }
}

/* The case: robust at N = 32, P = 12, sigma = 0.5 underestimates Ld by about 7 % with a
 * one-phase margin (its windows reach the blurred edges) where maxmin is exact; with the
 * geometry its windows stay on the flat parts and it is exact too. */
static void
test_robust_margin_from_geometry (void)
{
  Stripes s = { .period = 12, .duty = 0.5, .blur = 0.5, .aperture = 1 };
  const guint w = 120, n = 32;
  double err[3];
  for (guint c = 0; c < 3; c++) {
    DsSeparationParams p;
    params_for (&p, n, c == 0 ? DS_ESTIMATOR_MAXMIN : DS_ESTIMATOR_ROBUST, &s, c == 2);
    g_autoptr (GError) error = NULL;
    g_autoptr (DsSeparation) sep = separate_row (&p, &s, w, 500, &error);
    g_assert_no_error (error);
    double sum = 0;
    for (guint x = 0; x < w; x++)
      sum += ((float *) ds_image_row (sep->transmissive, 0))[x] / 1000 - 1;
    err[c] = sum / w;
    if (c == 2) {
      DsSamplingCheck check;
      g_assert_true (ds_separation_check_sampling (&p, &check, NULL));
      g_assert_cmpuint (check.robust_lit_window, ==, 6); /* floor ((1/2 - 3.576/12) 32) */
      g_assert_cmpfloat (check.affected_fraction, ==, 0);
      g_assert_cmpuint (sep->meta.flagged[6], ==, 0);
    }
  }
  g_test_message ("mean Ld error: maxmin %.4f, robust one-phase margin %.4f, robust from geometry %.4f",
                  err[0], err[1], err[2]);
  g_assert_cmpfloat (fabs (err[0]), <, 2e-3);
  g_assert_cmpfloat (err[1], <, -0.05);
  g_assert_cmpfloat (err[1], >, -0.09);
  g_assert_cmpfloat (fabs (err[2]), <, 2e-3);
}

/* Noise-free blurred square stripes, whose exact answer is the rendered Ld and Lg: with the
 * period and the blur known, robust's windows stay on the flat parts at every N, so its error
 * does not grow with N (the edge is fixed in pixels, a phase step is P/N). With the blur
 * unknown it keeps a one-phase margin: at small N that is as good, at large N the windows
 * reach into the edges and Ld reads low, more so as N grows. Every pixel is checked, on a
 * period that is not a whole number of pixels (every position in the period is visited). */
static void
test_robust_margin_over_n (void)
{
  const guint ns[] = { 6, 8, 16, 32, 64 };
  const guint w = 173; /* ten periods of the second case, 14.7 of the first */
  for (guint c = 0; c < 2; c++) {
    Stripes s = c == 0 ? (Stripes){ .period = 11.8, .duty = 0.5, .blur = 0.5, .aperture = 1, .offset = 0.17 }
                       : (Stripes){ .period = 17.3, .duty = 0.35, .black = 0.05, .blur = 0.4, .aperture = 1, .offset = 0.6 };
    double unknown_at_8 = 0;
    for (guint i = 0; i < G_N_ELEMENTS (ns); i++) {
      double worst[2] = { 0, 0 }, mean_unknown = 0;
      /* 100 points per pixel: the midpoint rule is then within 1e-5 of the integral here. */
      g_autofree double *values = render_row (&s, ns[i], w, 500, 100);
      for (guint known = 0; known < 2; known++) {
        DsSeparationParams p;
        params_for (&p, ns[i], DS_ESTIMATOR_ROBUST, &s, TRUE);
        p.geometry.edge_blur_known = known;
        p.geometry.edge_blur_px = known ? s.blur : 0;
        g_autoptr (GError) error = NULL;
        g_autoptr (DsSeparation) sep = separate_values (&p, values, w, &error);
        g_assert_no_error (error);
        for (guint x = 0; x < w; x++) {
          double ld = ((float *) ds_image_row (sep->transmissive, 0))[x] / 1000 - 1;
          double lg = ((float *) ds_image_row (sep->scattered, 0))[x] / 500 - 1;
          worst[known] = MAX (worst[known], MAX (fabs (ld), fabs (lg)));
          if (!known)
            mean_unknown += ld / w;
        }
      }
      g_test_message ("P %.1f a %.2f sigma %.1f N %2u: worst |error| blur known %.4f, unknown %.4f (mean Ld %+.4f)",
                      s.period, s.duty, s.blur, ns[i], worst[1], worst[0], mean_unknown);
      /* Each window sample is at least z = 2.576 sigma inside its edge: off by at most
       * Phi(-z) = 0.005 of the step per level. */
      g_assert_cmpfloat (worst[1], <, 0.012);
      if (ns[i] == 8)
        unknown_at_8 = mean_unknown;
      if (ns[i] >= 32)
        g_assert_cmpfloat (mean_unknown, <, MIN (-0.01, unknown_at_8 - 0.01));
    }
  }
}

/* aN = 1 at N = 4, a = 1/4, P = 16: point pixels are each lit once, but a 1-pixel aperture
 * needs (a - 1/P) N = 0.75 phases: a quarter of the positions are never fully lit. They are
 * flagged, with the phase offset given or measured on the first frame, and exactly the
 * flagged pixels are off by more than the tolerance. */
static void
test_undersampled_flags (void)
{
  Stripes s = { .period = 16, .duty = 0.25, .aperture = 1, .offset = 0.3 };
  const guint w = 160, n = 4;
  for (guint known = 0; known < 2; known++) {
    DsSeparationParams p;
    params_for (&p, n, DS_ESTIMATOR_MAXMIN, &s, TRUE);
    p.geometry.phase_offset_known = known;
    p.geometry.phase_offset_cycles = s.offset;
    DsSamplingCheck check;
    g_assert_true (ds_separation_check_sampling (&p, &check, NULL));
    g_assert_true (check.applies);
    g_assert_cmpfloat_with_epsilon (check.lit_phases, 0.75, 1e-12);
    /* a pixel is fully lit when its 1-px aperture lies in the 4-px stripe: 3 px of the 4-px
     * phase step; a quarter of the positions miss it (the tolerance widens that a little) */
    g_assert_cmpfloat (fabs (check.affected_fraction - 0.25), <, 0.02);
    g_autoptr (GError) error = NULL;
    g_autoptr (DsSeparation) sep = separate_row (&p, &s, w, 300, &error);
    g_assert_no_error (error);
    g_assert_cmpfloat (fabs (sep->meta.phase_offset_cycles - s.offset), <, 1e-3);
    guint flagged = 0;
    for (guint x = 0; x < w; x++) {
      double ld = ((float *) ds_image_row (sep->transmissive, 0))[x] / 1000;
      gboolean under = (((guint8 *) ds_image_row (sep->mask, 0))[x] & DS_MASK_UNDERSAMPLED) != 0;
      flagged += under;
      if (under)
        g_assert_cmpfloat (ld, <, 1 - DS_SAMPLING_TOLERANCE);
      else
        g_assert_cmpfloat (fabs (ld - 1), <=, 2 * DS_SAMPLING_TOLERANCE);
    }
    g_assert_cmpuint (flagged, ==, sep->meta.flagged[6] / 2);
    g_assert_cmpuint (flagged, >=, w / 5);
    g_assert_cmpuint (flagged, <=, w / 3);
  }
}

/* Every position undersampled (blur wider than the stripes allow at N = 2): refused, with the
 * geometry in the message. */
static void
test_refused_everywhere (void)
{
  Stripes s = { .period = 8, .duty = 0.5, .blur = 2, .aperture = 1 };
  DsSeparationParams p;
  params_for (&p, 2, DS_ESTIMATOR_MAXMIN, &s, TRUE);
  DsSamplingCheck check;
  g_autoptr (GError) error = NULL;
  g_assert_false (ds_separation_check_sampling (&p, &check, &error));
  g_assert_error (error, DS_PROC_ERROR, DS_PROC_ERROR_PRECONDITION);
  g_assert_cmpfloat (check.affected_fraction, ==, 1);
  g_assert_nonnull (strstr (error->message, "edge blur 2 px"));
  g_clear_error (&error);
  g_assert_false (ds_separation_params_validate (&p, &error));
  g_assert_error (error, DS_PROC_ERROR, DS_PROC_ERROR_PRECONDITION);
}

/* The predicted systematic errors against real separations of rendered frames whose period is
 * not a whole number of pixels (so the pixels sample every position in a period): sine on square
 * stripes (the ripple of the sampled harmonic, the blur's loss of gain), maxmin on sine stripes
 * (with its warning), maxmin on sharp stripes (none). */
static void
test_predicted_errors (void)
{
  const struct {
    Stripes s;
    guint n;
    DsEstimator e;
  } cases[] = {
    { { .period = 12.37, .duty = 0.5, .aperture = 1 }, 4, DS_ESTIMATOR_SINE },
    { { .period = 12.37, .duty = 0.5, .blur = 1.0, .aperture = 1 }, 8, DS_ESTIMATOR_SINE },
    { { .period = 9.71, .duty = 0.3, .black = 0.1, .blur = 0.3, .aperture = 0.8 }, 6, DS_ESTIMATOR_SINE },
    { { .period = 12.37, .duty = 0.5, .sine = TRUE, .aperture = 0 }, 4, DS_ESTIMATOR_MAXMIN },
    { { .period = 12.37, .duty = 0.5, .aperture = 1 }, 16, DS_ESTIMATOR_MAXMIN },
    { { .period = 12.37, .duty = 0.5, .blur = 0.5, .aperture = 1 }, 16, DS_ESTIMATOR_ROBUST },
  };
  const guint w = 1237;
  for (guint i = 0; i < G_N_ELEMENTS (cases); i++) {
    DsSeparationParams p;
    params_for (&p, cases[i].n, cases[i].e, &cases[i].s, TRUE);
    DsSamplingCheck check;
    g_assert_true (ds_separation_check_sampling (&p, &check, NULL));
    g_assert_cmpint (check.warning[0] != 0, ==, cases[i].s.sine && cases[i].e != DS_ESTIMATOR_SINE);
    g_autoptr (GError) error = NULL;
    g_autoptr (DsSeparation) sep = separate_row (&p, &cases[i].s, w, 0, &error);
    g_assert_no_error (error);
    double sum_ld = 0, sum_lg = 0, worst = 0;
    for (guint x = 0; x < w; x++) {
      double e = ((float *) ds_image_row (sep->transmissive, 0))[x] / 1000 - 1;
      sum_ld += e;
      sum_lg += ((float *) ds_image_row (sep->scattered, 0))[x] / 1000;
      worst = fabs (e) > fabs (worst) ? e : worst;
    }
    g_test_message ("case %u: Ld error mean %.4f (predicted %.4f), worst %.4f (%.4f); Lg %.4f (%.4f)", i,
                    sum_ld / w, check.ld_error_mean, worst, check.ld_error_worst, sum_lg / w, check.lg_error_mean);
    g_assert_cmpfloat (fabs (sum_ld / w - check.ld_error_mean), <, 2e-3);
    g_assert_cmpfloat (fabs (sum_lg / w - check.lg_error_mean), <, 2e-3);
    g_assert_cmpfloat (fabs (fabs (worst) - fabs (check.ld_error_worst)), <, 5e-3 + 0.05 * fabs (worst));
  }
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  g_test_add_func ("/sampling/point-condition", test_point_condition);
  g_test_add_func ("/sampling/robust-margin-from-geometry", test_robust_margin_from_geometry);
  g_test_add_func ("/sampling/robust-margin-over-n", test_robust_margin_over_n);
  g_test_add_func ("/sampling/undersampled-flags", test_undersampled_flags);
  g_test_add_func ("/sampling/refused-everywhere", test_refused_everywhere);
  g_test_add_func ("/sampling/predicted-errors", test_predicted_errors);
  return g_test_run ();
}
