/* The MOTION mask bit (docs/estimators.md, "MOTION").
 *
 * Scenes are written here in closed form, independently of proc/: stripes integrated exactly
 * over each pixel's aperture (square: the lit length of the pixel; sine: its antiderivative),
 * shot noise (the normal approximation of Poisson, >= 200 electrons per sample) and read noise.
 * - A still scene flags at most the design's false-alarm rate, 1e-3 per pixel; the test allows
 *   3e-3 over about 1e5 pixels (the 1e-3 rate's count is at most 102 +- 10 there).
 * - Bars whose edges move s pixels per phase are flagged where an edge crossed a pixel's
 *   aperture during the set and at the still rate elsewhere; the detection rate against s is
 *   printed (the figures of docs/estimators.md) and held above a floor.
 * - The chi-square quantile against published table values, and the pattern's residual ratio
 *   against a full DFT of the sampled pattern. */
#include <glib.h>
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "proc/image.h"
#include "proc/separation.h"
#include "proc/separation_internal.h"
#include "tests/common/test_random.h"

#define W 320u
#define H 320u
#define PERIOD 13.7 /* not a multiple of N: pixels fall at every position in the period */
#define GAIN_DN_PER_E 0.5
#define READ_DN 2.0
/* Where phase 0's stripes are centred, in periods: off 0 so that no pixel centre falls exactly
 * on a sharp edge (a point there is lit by an ill-defined half, which no camera sees). */
#define OFFSET 0.0123

typedef struct {
  DsPatternKind kind;
  double duty;
  double aperture; /* 0: point sampling, 1: a full pixel */
} Stripes;

/* Integral over [a, b] of the lit fraction (0..1) of phase k of n; positions in pixels, phase
 * k's stripes centred at (j + k/n + OFFSET) PERIOD. */
static double
lit_integral (const Stripes *s, guint k, guint n, double a, double b)
{
  double shift = ((double) k / n + OFFSET) * PERIOD;
  if (s->kind == DS_PATTERN_SINE) {
    /* f = (1 + cos (2 pi (x - shift) / P)) / 2 */
    double w = 2 * G_PI / PERIOD;
    return 0.5 * (b - a) + (sin (w * (b - shift)) - sin (w * (a - shift))) / (2 * w);
  }
  double half = 0.5 * s->duty * PERIOD, total = 0;
  long j0 = (long) floor ((a - half - shift) / PERIOD) - 1, j1 = (long) ceil ((b + half - shift) / PERIOD) + 1;
  for (long j = j0; j <= j1; j++) {
    double c = j * PERIOD + shift;
    double lo = MAX (a, c - half), hi = MIN (b, c + half);
    total += hi > lo ? hi - lo : 0;
  }
  return total;
}

/* The point-sampled lit fraction (aperture 0). */
static double
lit_point (const Stripes *s, guint k, guint n, double x)
{
  double u = x / PERIOD - (double) k / n - OFFSET;
  u -= floor (u + 0.5);
  return s->kind == DS_PATTERN_SINE ? 0.5 * (1 + cos (2 * G_PI * u)) : (fabs (u) < s->duty / 2 ? 1.0 : 0.0);
}

/* Bars of transmittance 1 (width BAR) and LOW (the rest of BAR_PITCH), moving `speed` pixels per
 * phase; speed 0 = no object. */
#define BAR 32.0
#define BAR_PITCH 64.0
#define LOW 0.2

typedef struct {
  double speed;
} Bars;

/* Integral over [a, b] of transmittance x (global + direct x lit fraction) in phase k. */
static double
pixel_signal (const Stripes *s, const Bars *bars, guint k, guint n, double x, double global, double direct)
{
  if (s->aperture == 0) {
    double t = 1;
    if (bars->speed != 0) {
      double u = fmod (x - bars->speed * k, BAR_PITCH);
      u += u < 0 ? BAR_PITCH : 0;
      t = u < BAR ? 1.0 : LOW;
    }
    return t * (global + direct * lit_point (s, k, n, x));
  }
  double a = x - 0.5 * s->aperture, b = x + 0.5 * s->aperture;
  if (bars->speed == 0)
    return (global * (b - a) + direct * lit_integral (s, k, n, a, b)) / s->aperture;
  /* split [a, b] at the bars' edges, e = speed k + m BAR_PITCH (+ BAR) */
  double cuts[8];
  guint nc = 0;
  cuts[nc++] = a;
  double off = bars->speed * k;
  for (long m = (long) floor ((a - off) / BAR_PITCH) - 1; m <= (long) ceil ((b - off) / BAR_PITCH) + 1; m++)
    for (int e = 0; e < 2; e++) {
      double c = off + m * BAR_PITCH + e * BAR;
      if (c > a && c < b && nc < 7)
        cuts[nc++] = c;
    }
  cuts[nc++] = b;
  /* sorted: at most two edges fall within one pixel and they come in order of m, e */
  for (guint i = 1; i < nc; i++)
    for (guint j = i; j > 0 && cuts[j] < cuts[j - 1]; j--) {
      double tmp = cuts[j];
      cuts[j] = cuts[j - 1];
      cuts[j - 1] = tmp;
    }
  double v = 0;
  for (guint i = 0; i + 1 < nc; i++) {
    double mid = 0.5 * (cuts[i] + cuts[i + 1]);
    double u = fmod (mid - off, BAR_PITCH);
    u += u < 0 ? BAR_PITCH : 0;
    double t = u < BAR ? 1.0 : LOW;
    v += t * (global * (cuts[i + 1] - cuts[i]) + direct * lit_integral (s, k, n, cuts[i], cuts[i + 1]));
  }
  return v / s->aperture;
}

/* Did a bar edge pass within the pixel's aperture (or over its point) during the set? */
static gboolean
crossed (const Bars *bars, const Stripes *s, guint n, double x)
{
  double travel = bars->speed * (n - 1);
  double a = x - 0.5 * s->aperture, b = x + 0.5 * s->aperture;
  for (long m = -1; m <= (long) (W / BAR_PITCH) + 1; m++)
    for (int e = 0; e < 2; e++) {
      double e0 = m * BAR_PITCH + e * BAR;
      /* the edge sweeps [e0, e0 + travel]; a point pixel is crossed when it lies inside */
      if (s->aperture == 0 ? (x >= e0 && x < e0 + travel) : (b > e0 && a < e0 + travel))
        return TRUE;
    }
  return FALSE;
}

typedef struct {
  DsEstimator estimator;
  Stripes stripes;
  guint n;
  gboolean model;  /* the noise model is given; else shot noise off and read noise only */
  double detect_floor; /* detection rate held at >= 1 px per phase (docs/estimators.md less
                          about 0.05 for the sampling spread) */
  gboolean float_input; /* f32 frames (else u16) */
  guint averages;       /* frames per phase, M (0: 1) */
} Case;

typedef struct {
  guint64 still_judged, still_flagged;  /* pixels no edge crossed */
  guint64 moved_judged, moved_flagged;  /* pixels an edge crossed */
} Rates;

/* Renders the set, separates it, counts MOTION over judged pixels (neither saturated nor dark
 * nor nonfinite) by whether an edge crossed them. */
static Rates
run_case_full (const Case *c, const Bars *bars, guint32 seed, gboolean extrema, guint8 *motion_out)
{
  g_autoptr (GRand) r = g_rand_new_with_seed (seed);
  /* direct and global light per column (constant down a column: the data noise estimate, from
   * differences along y, then sees noise only) */
  g_autofree double *direct = g_new (double, W), *global = g_new (double, W);
  for (guint x = 0; x < W; x++) {
    direct[x] = g_rand_double_range (r, 200, 2000);
    global[x] = g_rand_double_range (r, 200, 1200);
  }
  DsSeparationParams p;
  ds_separation_params_init (&p, c->n);
  p.estimator = c->estimator;
  p.pattern = c->stripes.kind;
  p.duty = c->stripes.kind == DS_PATTERN_SQUARE ? c->stripes.duty : 0.5;
  p.detect_motion = TRUE;
  p.keep_extrema = extrema;
  p.threads = 2;
  p.geometry.period_px = PERIOD;
  p.geometry.pixel_aperture = c->stripes.aperture;
  p.geometry.edge_blur_known = TRUE;
  p.geometry.phase_offset_known = TRUE;
  p.geometry.phase_offset_cycles = OFFSET;
  if (c->model) {
    p.system_gain = GAIN_DN_PER_E;
    p.read_noise_dn = READ_DN;
  }
  g_autoptr (GError) error = NULL;
  g_autoptr (DsPhaseSet) set = ds_phase_set_new (&p, W, H, &error);
  g_assert_no_error (error);
  for (guint fk = 0; fk < c->n * MAX (c->averages, 1u); fk++) {
    guint k = fk / MAX (c->averages, 1u);
    g_autoptr (DsImage) frame = ds_image_new (c->float_input ? DS_SAMPLE_F32 : DS_SAMPLE_U16, W, H, &error);
    g_assert_no_error (error);
    for (guint x = 0; x < W; x++) {
      double sig = pixel_signal (&c->stripes, bars, k, c->n, x, global[x], direct[x]);
      for (guint y = 0; y < H; y++) {
        double v = sig;
        if (c->model) {
          double electrons = sig / GAIN_DN_PER_E;
          v = GAIN_DN_PER_E * (electrons + sqrt (electrons) * test_normal (r)) + READ_DN * test_normal (r);
        } else {
          v += 5.0 * test_normal (r);
        }
        if (c->float_input)
          ((float *) ds_image_row (frame, y))[x] = (float) v;
        else
          ((guint16 *) ds_image_row (frame, y))[x] = (guint16) CLAMP (lround (v), 0, 65535);
      }
    }
    g_assert_true (ds_phase_set_accumulate (set, k, frame, &error));
    g_assert_no_error (error);
  }
  g_autoptr (DsSeparation) sep = ds_phase_set_finalize (set, &error);
  g_assert_no_error (error);
  g_assert_true (sep->meta.motion_checked);
  Rates out = { 0 };
  guint64 flagged = 0;
  for (guint y = 0; y < H; y++) {
    const guint8 *mk = ds_image_row (sep->mask, y);
    for (guint x = 0; x < W; x++) {
      flagged += (mk[x] & DS_MASK_MOTION) != 0;
      if (motion_out)
        motion_out[(gsize) y * W + x] = mk[x] & DS_MASK_MOTION;
      if (mk[x] & (DS_MASK_SATURATED | DS_MASK_DARK | DS_MASK_NONFINITE))
        continue;
      gboolean m = (mk[x] & DS_MASK_MOTION) != 0;
      if (bars->speed != 0 && crossed (bars, &c->stripes, c->n, x)) {
        out.moved_judged++;
        out.moved_flagged += m;
      } else {
        out.still_judged++;
        out.still_flagged += m;
      }
    }
  }
  g_assert_cmpuint (flagged, ==, sep->meta.flagged[7]);
  return out;
}

static Rates
run_case (const Case *c, const Bars *bars, guint32 seed)
{
  return run_case_full (c, bars, seed, FALSE, NULL);
}

static const char *
case_name (const Case *c, char *buf, gsize len)
{
  g_snprintf (buf, len, "%s %s%s N=%u%s%s aperture %g %s", ds_estimator_name (c->estimator),
              c->stripes.kind == DS_PATTERN_SINE ? "sine" : "square",
              c->stripes.kind == DS_PATTERN_SINE ? "" : (c->stripes.duty == 0.5 ? " a=0.5" : " a=0.25"), c->n,
              c->averages > 1 ? " M=2" : "", c->float_input ? " f32" : "", c->stripes.aperture, c->model ? "noise model" : "data noise");
  return buf;
}

static const Case cases[] = {
  { DS_ESTIMATOR_MAXMIN, { DS_PATTERN_SQUARE, 0.5, 1 }, 8, TRUE, 0.58, FALSE, 1 },
  { DS_ESTIMATOR_MAXMIN, { DS_PATTERN_SQUARE, 0.5, 0 }, 8, TRUE, 0.63, FALSE, 1 },
  { DS_ESTIMATOR_ROBUST, { DS_PATTERN_SQUARE, 0.25, 1 }, 8, TRUE, 0.23, FALSE, 1 },
  { DS_ESTIMATOR_SINE, { DS_PATTERN_SINE, 0.5, 1 }, 8, TRUE, 0.95, FALSE, 1 },
  { DS_ESTIMATOR_SINE, { DS_PATTERN_SINE, 0.5, 1 }, 4, TRUE, 0.85, FALSE, 1 },
  { DS_ESTIMATOR_SINE, { DS_PATTERN_SINE, 0.5, 1 }, 8, FALSE, 0.95, FALSE, 1 },
  { DS_ESTIMATOR_MAXMIN, { DS_PATTERN_SQUARE, 0.5, 1 }, 16, FALSE, 0.76, FALSE, 1 },
  /* the float and averaging layouts of the accumulator */
  { DS_ESTIMATOR_SINE, { DS_PATTERN_SINE, 0.5, 1 }, 6, TRUE, 0.95, TRUE, 1 },
  { DS_ESTIMATOR_ROBUST, { DS_PATTERN_SINE, 0.5, 1 }, 6, TRUE, 0.95, TRUE, 1 },
  { DS_ESTIMATOR_MAXMIN, { DS_PATTERN_SQUARE, 0.5, 1 }, 6, TRUE, 0.5, FALSE, 2 },
  { DS_ESTIMATOR_ROBUST, { DS_PATTERN_SQUARE, 0.5, 1 }, 6, TRUE, 0.5, FALSE, 2 },
};

/* The design's rate is at most 1e-3 per pixel; 3e-3 leaves room for the binomial spread. */
#define STILL_BOUND 3e-3

static void
test_still (void)
{
  Bars still = { 0 };
  for (guint i = 0; i < G_N_ELEMENTS (cases); i++) {
    Rates r = run_case (&cases[i], &still, 100 + i);
    char name[128];
    double rate = (double) r.still_flagged / r.still_judged;
    printf ("still   %-46s false positives %6.2e (%" G_GUINT64_FORMAT " of %" G_GUINT64_FORMAT ")\n",
            case_name (&cases[i], name, sizeof name), rate, r.still_flagged, r.still_judged);
    g_assert_cmpuint (r.still_judged, >, W * H / 2);
    g_assert_cmpfloat (rate, <=, STILL_BOUND);
  }
}

/* Moving bars: detection where an edge crossed, the still rate elsewhere. The floors are the
 * detection rates docs/estimators.md states, less a margin for the sampling spread. */
static void
test_moving (void)
{
  static const double speeds[] = { 0.25, 0.5, 1, 2, 4 };
  for (guint i = 0; i < G_N_ELEMENTS (cases); i++) {
    const Case *c = &cases[i];
    char name[128];
    case_name (c, name, sizeof name);
    for (guint s = 0; s < G_N_ELEMENTS (speeds); s++) {
      /* the edges must leave pixels they never crossed: travel within a bar */
      if (speeds[s] * (c->n - 1) > BAR - 4)
        continue;
      Bars bars = { speeds[s] };
      Rates r = run_case (c, &bars, 1000 + 10 * i + s);
      double det = (double) r.moved_flagged / MAX (r.moved_judged, 1);
      double fp = (double) r.still_flagged / r.still_judged;
      printf ("moving  %-46s %4.2f px/phase: detected %5.3f of %6" G_GUINT64_FORMAT
              " crossed pixels, false positives %6.2e elsewhere\n",
              name, speeds[s], det, r.moved_judged, fp);
      g_assert_cmpuint (r.moved_judged, >, 0);
      g_assert_cmpfloat (fp, <=, STILL_BOUND);
      /* an edge crossing at >= 1 px per phase moves a whole pixel's worth of contrast */
      if (speeds[s] >= 1)
        g_assert_cmpfloat (det, >=, c->detect_floor);
    }
  }
}

/* maxmin without a noise model takes its integer fast path, which or-s the motion bits into
 * its own mask; keeping the extrema takes the general path: the same pixels either way. */
static void
test_fast_path_same (void)
{
  const Case c = { DS_ESTIMATOR_MAXMIN, { DS_PATTERN_SQUARE, 0.5, 1 }, 8, FALSE, 0, FALSE, 1 };
  Bars bars = { 2 };
  g_autofree guint8 *fast = g_new (guint8, W * H), *general = g_new (guint8, W * H);
  Rates a = run_case_full (&c, &bars, 7, FALSE, fast);
  Rates b = run_case_full (&c, &bars, 7, TRUE, general);
  g_assert_cmpuint (a.moved_flagged, >, 0);
  g_assert_cmpuint (a.moved_flagged, ==, b.moved_flagged);
  g_assert_cmpmem (fast, W * H, general, W * H);
}

/* Noise-free still frames (synthetic, or a scene far above its noise): the pattern's own
 * harmonics reach the allowance exactly at some positions, and nothing may be flagged for the
 * rounding of the sums; integer frames carry their quantisation, within the stated rate. */
static void
test_noise_free (void)
{
  static const Stripes stripes[] = { { DS_PATTERN_SQUARE, 0.5, 0 }, { DS_PATTERN_SQUARE, 0.5, 1 },
                                     { DS_PATTERN_SINE, 0.5, 1 } };
  const Bars still = { 0 };
  for (guint i = 0; i < G_N_ELEMENTS (stripes); i++)
    for (int is_float = 0; is_float < 2; is_float++) {
      const guint n = 8;
      DsSeparationParams p;
      ds_separation_params_init (&p, n);
      p.estimator = stripes[i].kind == DS_PATTERN_SINE ? DS_ESTIMATOR_SINE : DS_ESTIMATOR_MAXMIN;
      p.pattern = stripes[i].kind;
      p.detect_motion = TRUE;
      p.geometry.period_px = PERIOD;
      p.geometry.pixel_aperture = stripes[i].aperture;
      p.geometry.edge_blur_known = TRUE;
      g_autoptr (GError) error = NULL;
      g_autoptr (DsPhaseSet) set = ds_phase_set_new (&p, W, 64, &error);
      g_assert_no_error (error);
      for (guint k = 0; k < n; k++) {
        g_autoptr (DsImage) f = ds_image_new (is_float ? DS_SAMPLE_F32 : DS_SAMPLE_U16, W, 64, &error);
        for (guint x = 0; x < W; x++) {
          double v = pixel_signal (&stripes[i], &still, k, n, x, 300 + 3 * x, 2000 + 50 * (x % 7));
          for (guint y = 0; y < 64; y++) {
            if (is_float)
              ((float *) ds_image_row (f, y))[x] = (float) v;
            else
              ((guint16 *) ds_image_row (f, y))[x] = (guint16) lround (v);
          }
        }
        g_assert_true (ds_phase_set_accumulate (set, k, f, &error));
      }
      g_autoptr (DsSeparation) sep = ds_phase_set_finalize (set, &error);
      g_assert_no_error (error);
      g_assert_true (sep->meta.motion_checked);
      if (is_float)
        g_assert_cmpuint (sep->meta.flagged[7], ==, 0);
      else
        g_assert_cmpfloat ((double) sep->meta.flagged[7] / (W * 64), <=, STILL_BOUND);
    }
}

/* Published upper 0.999 quantiles of chi-square (e.g. NIST/SEMATECH e-Handbook, table 1.3.6.7.4),
 * and Wilson-Hilferty's approximation for a large nu. */
static void
test_chi2_quantile (void)
{
  static const struct {
    guint nu;
    double q;
  } table[] = { { 1, 10.828 }, { 2, 13.816 }, { 3, 16.266 }, { 5, 20.515 }, { 10, 29.588 }, { 13, 34.528 },
                { 29, 58.301 }, { 100, 149.449 } };
  for (guint i = 0; i < G_N_ELEMENTS (table); i++)
    g_assert_cmpfloat_with_epsilon (ds_chi2_upper_quantile (table[i].nu, 1e-3), table[i].q, 2e-3);
  double nu = 4093, z = 3.090232306167813, t = 2.0 / (9 * nu);
  double wh = nu * pow (1 - t + z * sqrt (t), 3);
  g_assert_cmpfloat (fabs (ds_chi2_upper_quantile (4093, 1e-3) / wh - 1), <, 1e-3);
}

/* The residual ratio of sharp point-sampled square stripes: a full DFT of the sampled pattern
 * (every bin, by its definition) against the function's closed form. */
static void
test_pattern_ratio (void)
{
  static const struct {
    guint n;
    double duty;
  } cases_r[] = { { 4, 0.5 }, { 8, 0.5 }, { 8, 0.25 }, { 12, 0.5 }, { 6, 1.0 / 3 } };
  for (guint i = 0; i < G_N_ELEMENTS (cases_r); i++) {
    guint n = cases_r[i].n;
    double worst = 0;
    for (guint lit = (guint) floor (cases_r[i].duty * n); lit <= (guint) ceil (cases_r[i].duty * n); lit++) {
      double h1 = 0, rest = 0;
      for (guint j = 1; j < n; j++) {
        double re = 0, im = 0;
        for (guint k = 0; k < lit; k++) {
          re += cos (2 * G_PI * j * k / n);
          im -= sin (2 * G_PI * j * k / n);
        }
        double e = (re * re + im * im) / n;
        if (j == 1 || j == n - 1)
          h1 += e;
        else
          rest += e;
      }
      worst = MAX (worst, rest / h1);
    }
    DsSeparationParams p;
    ds_separation_params_init (&p, n);
    p.duty = cases_r[i].duty;
    g_assert_cmpfloat_with_epsilon (ds_motion_pattern_ratio (&p), worst, 1e-9);
    p.pattern = DS_PATTERN_SINE;
    g_assert_cmpfloat (ds_motion_pattern_ratio (&p), ==, 0);
  }
}

/* Off by default, and never judged below N = 4: nothing is flagged then, whatever moved. */
static void
test_off_and_small_n (void)
{
  for (guint variant = 0; variant < 2; variant++) {
    guint n = variant == 0 ? 8 : 3;
    DsSeparationParams p;
    ds_separation_params_init (&p, n);
    p.estimator = DS_ESTIMATOR_SINE;
    p.pattern = DS_PATTERN_SINE;
    p.detect_motion = variant == 1;
    g_autoptr (GError) error = NULL;
    g_autoptr (DsPhaseSet) set = ds_phase_set_new (&p, 64, 16, &error);
    g_assert_no_error (error);
    for (guint k = 0; k < n; k++) {
      g_autoptr (DsImage) f = ds_image_new (DS_SAMPLE_U16, 64, 16, &error);
      for (guint y = 0; y < 16; y++)
        for (guint x = 0; x < 64; x++) /* a scene that changes wholesale between frames */
          ((guint16 *) ds_image_row (f, y))[x] = (guint16) (1000 + 500 * ((k * 7 + x) % 3) + (y % 2));
      g_assert_true (ds_phase_set_accumulate (set, k, f, &error));
    }
    g_autoptr (DsSeparation) sep = ds_phase_set_finalize (set, &error);
    g_assert_no_error (error);
    g_assert_false (sep->meta.motion_checked);
    g_assert_cmpuint (sep->meta.flagged[7], ==, 0);
  }
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  g_test_add_func ("/motion/chi2-quantile", test_chi2_quantile);
  g_test_add_func ("/motion/pattern-ratio", test_pattern_ratio);
  g_test_add_func ("/motion/off-and-small-n", test_off_and_small_n);
  g_test_add_func ("/motion/still", test_still);
  g_test_add_func ("/motion/fast-path-same", test_fast_path_same);
  g_test_add_func ("/motion/noise-free", test_noise_free);
  g_test_add_func ("/motion/moving-bars", test_moving);
  return g_test_run ();
}
