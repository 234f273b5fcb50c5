/* The pilot frames' temporal noise (proc/column_stats.h) against its closed form: frames drawn with
 * the photon-transfer variance var = r^2 + K s (read noise r DN, K DN per DN of signal s), so the
 * noise a - b holds is known, sample by sample, and its mean square over the scene is
 * 2 r^2 + K mean (a + b). The scenes are what fooled the readings: most of the scene dark (objects'
 * shadows), with the bright places a minority whose noise is several times the dark places', and
 * objects whose edges along y are soft (blurred over several rows). */
#include <glib.h>
#include <math.h>

#include "proc/column_stats.h"
#include "proc/image.h"

#define W 256u
#define H 192u
#define READ_DN 0.7
#define K_DN 0.05
#define PERIOD 23.75
#define DARK_DN 3.0

/* Ld of the scene at (x, y): a bright field with a dark object covering the rows below
 * `dark_from`, its edge along y blurred over about `edge_rows` rows, one more dark band, and where
 * `soft`, a soft grating along y (period 12 rows, a smooth object's shading). */
static double
scene_ld (guint x, guint y, double dark_from, double edge_rows, gboolean soft)
{
  double inside = 0.5 * (1 + erf ((y - dark_from) / (edge_rows * G_SQRT2)));
  double band = x > 40 && x < 60 ? 1.0 : 0.0;
  double shade = soft ? 0.75 + 0.25 * cos (2 * G_PI * y / 12.0) : 1.0;
  return 600.0 * (1 - inside) * (1 - band) * shade;
}

/* One phase (0 or 1/2) of sine stripes at `period` on the scene, with scattered light lg, a dark
 * level and the noise of its signal. */
static DsImage *
frame (GRand *r, double period, guint phase, double dark_from, double edge_rows, gboolean soft, double lg)
{
  DsImage *f = ds_image_new (DS_SAMPLE_F32, W, H, NULL);
  for (guint y = 0; y < H; y++) {
    float *row = ds_image_row (f, y);
    for (guint x = 0; x < W; x++) {
      double stripe = 0.5 + 0.5 * cos (2 * G_PI * (x / period - 0.5 * phase));
      double s = scene_ld (x, y, dark_from, edge_rows, soft) * stripe + 0.5 * lg;
      double sd = sqrt (READ_DN * READ_DN + K_DN * s);
      /* Box-Muller */
      double u1 = 1.0 - g_rand_double (r), u2 = g_rand_double (r);
      row[x] = (float) (DARK_DN + s + sd * sqrt (-2 * log (u1)) * cos (2 * G_PI * u2));
    }
  }
  return f;
}

/* The closed form over the rows and columns the second difference covers: mean over samples of
 * the variance of a - b (each frame's r^2 + K s). */
static double
expected_var_diff (const DsImage *a, const DsImage *b)
{
  double sum = 0;
  guint n = 0;
  for (guint y = 1; y + 1 < H; y++) {
    const float *ra = ds_image_row (a, y), *rb = ds_image_row (b, y);
    for (guint x = 0; x < W; x++, n++)
      sum += 2 * READ_DN * READ_DN + K_DN * (ra[x] + rb[x] - 2 * DARK_DN);
  }
  return sum / n;
}

/* Two pilot pairs over one scene, as the probe takes them: phases 0 and 1/2 at PERIOD, then at
 * 2 PERIOD (drawn from r in that order), and what the sets' and the first pair's noise readings
 * and their closed forms say of them. */
typedef struct {
  DsImage *frame[4];                /* a0, a1 at PERIOD; b0, b1 at 2 PERIOD */
  double sets_var, sets_want;       /* the sets' noise squared, DN^2, and its closed form */
  double single_var, single_want;   /* the same of the pair at PERIOD alone */
} TwoPairs;

static void
two_pairs_clear (TwoPairs *t)
{
  for (guint i = 0; i < 4; i++)
    g_clear_pointer (&t->frame[i], ds_image_free);
}

G_DEFINE_AUTO_CLEANUP_CLEAR_FUNC (TwoPairs, two_pairs_clear)

/* level: where the sets' noise reports its level (NULL: not asked). */
static void
two_pairs_read (TwoPairs *t, GRand *r, double dark_from, double edge_rows, gboolean soft, double lg, double *level)
{
  t->frame[0] = frame (r, PERIOD, 0, dark_from, edge_rows, soft, lg);
  t->frame[1] = frame (r, PERIOD, 1, dark_from, edge_rows, soft, lg);
  t->frame[2] = frame (r, 2 * PERIOD, 0, dark_from, edge_rows, soft, lg);
  t->frame[3] = frame (r, 2 * PERIOD, 1, dark_from, edge_rows, soft, lg);
  const DsImage *set_a[2] = { t->frame[0], t->frame[1] }, *set_b[2] = { t->frame[2], t->frame[3] };
  double sets = ds_column_stats_noise_sets_dn (set_a, set_b, NULL, 0, level);
  double single = ds_column_stats_noise_dn (t->frame[0], t->frame[1], 0);
  t->sets_var = sets * sets;
  t->sets_want = expected_var_diff (t->frame[0], t->frame[1]) + expected_var_diff (t->frame[2], t->frame[3]);
  t->single_var = single * single;
  t->single_want = expected_var_diff (t->frame[0], t->frame[1]);
}

/* A sharp-edged dark object over 70 % of the rows: one robust scale for all the samples is the
 * dark places', and its cut falls inside the bright places' core (asserted: one pair's reading
 * is under 0.8 of the closed form). The sets' noise, cut at each level's own scale, must come out
 * at the closed form within 4 %. */
static void
test_dark_majority (void)
{
  g_autoptr (GRand) r = g_rand_new_with_seed (11);
  g_auto (TwoPairs) t = { 0 };
  two_pairs_read (&t, r, 0.3 * H, 0.01, FALSE, 4, NULL);
  g_test_message ("dark majority: sets var %.3f, closed form %.3f (one pair %.3f against %.3f)", t.sets_var,
                  t.sets_want, t.single_var, t.single_want);
  g_assert_cmpfloat (t.single_var, <, 0.8 * t.single_want);
  g_assert_cmpfloat (fabs (t.sets_var / t.sets_want - 1), <, 0.04);
}

/* Soft structure along y (an edge blurred over 4 rows, a shading of 12 rows' period) is structure
 * the second difference of one pair keeps inside its cut (asserted: it reads more than the
 * closed form); between two pairs at two periods, whose sums are both the scene under the
 * pattern's mean, it cancels. The noise of the sets must be the four frames' (closed form) within
 * 4 %, and the level it reports their mean sum. */
static void
test_sets_cancel_the_scene (void)
{
  g_autoptr (GRand) r = g_rand_new_with_seed (12);
  g_auto (TwoPairs) t = { 0 };
  double level = NAN;
  two_pairs_read (&t, r, 0.45 * H, 4, TRUE, 20, &level);
  g_test_message ("sets: var %.3f, closed form %.3f (one pair's own reading %.3f against %.3f)", t.sets_var,
                  t.sets_want, t.single_var, t.single_want);
  g_assert_cmpfloat (fabs (t.sets_var / t.sets_want - 1), <, 0.04);
  g_assert_cmpfloat (t.single_var, >, 1.2 * t.single_want);
  /* The level: the four frames' mean sum over the samples read, dark level and all. */
  double sum = 0;
  guint n = 0;
  for (guint y = 1; y + 1 < H; y++)
    for (guint x = 0; x < W; x++, n++)
      for (guint i = 0; i < 4; i++)
        sum += ((const float *) ds_image_row (t.frame[i], y))[x];
  g_assert_cmpfloat (fabs (level / (sum / n) - 1), <, 0.02);
}

/* Where every sample has the same noise the result is that noise (the line through the strata is
 * flat), on integer samples too: a dark frame of 1.6 DN rounded to whole DN. */
static void
test_uniform_noise (void)
{
  g_autoptr (GRand) r = g_rand_new_with_seed (13);
  g_autoptr (DsImage) f = ds_image_new (DS_SAMPLE_F32, W, H, NULL);
  for (guint y = 0; y < H; y++) {
    float *row = ds_image_row (f, y);
    for (guint x = 0; x < W; x++) {
      double u1 = 1.0 - g_rand_double (r), u2 = g_rand_double (r);
      row[x] = (float) round (100 + 1.6 * sqrt (-2 * log (u1)) * cos (2 * G_PI * u2));
    }
  }
  /* Rounding adds 1/12 DN^2. */
  double got = ds_column_stats_noise_dn (f, NULL, 0), want = sqrt (1.6 * 1.6 + 1.0 / 12);
  g_test_message ("uniform: %.3f DN, closed form %.3f", got, want);
  g_assert_cmpfloat (fabs (got / want - 1), <, 0.03);
}

/* One phase (0 or 1/2) of square stripes of duty 0.23 at 3.25 px, each pixel integrating the
 * pattern over its width (so a pixel's share of the lit stripe varies from column to column),
 * on the scene, with the noise of its signal. Opposite phases of such stripes do not sum flat, so
 * no second period cancels the scene; only the pair's own ratio does. */
static DsImage *
frame_square (GRand *r, guint phase, double dark_from, double edge_rows, gboolean soft)
{
  const double period = 3.25, duty = 0.23;
  DsImage *f = ds_image_new (DS_SAMPLE_F32, W, H, NULL);
  for (guint y = 0; y < H; y++) {
    float *row = ds_image_row (f, y);
    for (guint x = 0; x < W; x++) {
      double lit = 0;
      for (guint k = 0; k < 64; k++) {
        double u = (x + (k + 0.5) / 64) / period - 0.5 * phase;
        lit += (u - floor (u) < duty) / 64.0;
      }
      double s = scene_ld (x, y, dark_from, edge_rows, soft) * (0.05 + 0.95 * lit);
      double sd = sqrt (READ_DN * READ_DN + K_DN * s);
      double u1 = 1.0 - g_rand_double (r), u2 = g_rand_double (r);
      row[x] = (float) (DARK_DN + s + sd * sqrt (-2 * log (u1)) * cos (2 * G_PI * u2));
    }
  }
  return f;
}

/* The pair's ratio per column, as the probe takes it from its column statistics. */
static double *
pair_ratio (const DsImage *a, const DsImage *b)
{
  DsColumnStats st;
  g_assert_true (ds_column_stats_compute (a, b, 0, &st, NULL));
  double *rho = g_new (double, W);
  for (guint x = 0; x < W; x++) {
    double sum = st.mean_sum[x] - 2 * DARK_DN;
    rho[x] = st.count[x] && sum > 1 ? st.mean_diff[x] / sum : NAN;
  }
  ds_column_stats_clear (&st);
  return rho;
}

/* Square stripes of duty 0.23 over soft structure along y (an edge over 4 rows, a 12-row
 * shading) and a dark object below `dark_from` of the rows: the pair's difference keeps the
 * structure, and where the dark object is the majority its one scale cuts into the bright places'
 * noise (asserted: its reading over the closed form is above `single_above` or below
 * `single_below`); the ratio-weighted pair cancels the structure and reads each level at its own
 * scale. The gain it gives, (noise^2 - var0 mean_w2) / mean_shot, must be the frames' K within
 * 8 %, and its mean square the closed form of c's variance over the samples within 5 %. */
static void
check_pair_weighted (guint seed, double dark_share, double single_above, double single_below)
{
  g_autoptr (GRand) r = g_rand_new_with_seed (seed);
  g_autoptr (DsImage) a = frame_square (r, 0, dark_share * H, 4, TRUE);
  g_autoptr (DsImage) b = frame_square (r, 1, dark_share * H, 4, TRUE);
  g_autofree double *rho = pair_ratio (a, b);
  double w2 = NAN, shot = NAN;
  double noise = ds_column_stats_noise_pair_dn (a, b, rho, DARK_DN, 0, &w2, &shot);
  double gain = (noise * noise - READ_DN * READ_DN * w2) / shot;
  /* The closed form of c's variance, sample by sample: (1 - rho)^2 var a + (1 + rho)^2 var b. */
  double want = 0;
  guint n = 0;
  for (guint y = 1; y + 1 < H; y++) {
    const float *ra = ds_image_row (a, y), *rb = ds_image_row (b, y);
    for (guint x = 0; x < W; x++) {
      if (!isfinite (rho[x]))
        continue;
      double p = CLAMP (rho[x], -1.0, 1.0), wa = (1 - p) * (1 - p), wb = (1 + p) * (1 + p);
      want += wa * (READ_DN * READ_DN + K_DN * (ra[x] - DARK_DN)) + wb * (READ_DN * READ_DN + K_DN * (rb[x] - DARK_DN));
      n++;
    }
  }
  want /= n;
  double single = ds_column_stats_noise_dn (a, b, 0), single_want = expected_var_diff (a, b);
  g_test_message ("pair weighted (dark below %.0f %% of the rows): gain %.4f (K %.4f), var %.3f against %.3f; the difference alone "
                  "%.3f against %.3f",
                  100 * dark_share, gain, K_DN, noise * noise, want, single * single, single_want);
  g_assert_true (single * single > single_above * single_want || single * single < single_below * single_want);
  g_assert_cmpfloat (fabs (gain / K_DN - 1), <, 0.08);
  g_assert_cmpfloat (fabs (noise * noise / want - 1), <, 0.05);
}

static void
test_pair_weighted (void)
{
  check_pair_weighted (14, 0.45, 1.2, 0);
  check_pair_weighted (15, 0.3, INFINITY, 0.95);
  /* Three rows, the fewest a second difference needs (its level is then read in the rows it
   * spans): a value, and on frames of zeros, no noise. */
  g_autoptr (DsImage) a = ds_image_new (DS_SAMPLE_F32, W, 3, NULL);
  g_autoptr (DsImage) b = ds_image_new (DS_SAMPLE_F32, W, 3, NULL);
  g_autofree double *rho = g_new0 (double, W);
  double w2 = NAN, shot = NAN;
  g_assert_cmpfloat (ds_column_stats_noise_pair_dn (a, b, rho, 0, 0, &w2, &shot), ==, 0.0);
  g_assert_cmpfloat (w2, ==, 2.0);
}

/* The share of pixel x that square stripes of `duty` at `period`, shifted by half a period for
 * phase 1, light (each pixel integrating the pattern over its width). */
static double
square_lit (guint x, double period, double duty, guint phase)
{
  double lit = 0;
  for (guint k = 0; k < 64; k++) {
    double u = (x + (k + 0.5) / 64) / period - 0.5 * phase;
    lit += (u - floor (u) < duty) / 64.0;
  }
  return lit;
}

static DsImage *
frame_square_duty (GRand *r, double period, double duty, guint phase)
{
  DsImage *f = ds_image_new (DS_SAMPLE_F32, W, H, NULL);
  for (guint y = 0; y < H; y++) {
    float *row = ds_image_row (f, y);
    for (guint x = 0; x < W; x++) {
      double s = scene_ld (x, y, 0.6 * H, 4, TRUE) * (0.05 + 0.95 * square_lit (x, period, duty, phase)) + 20;
      double sd = sqrt (READ_DN * READ_DN + K_DN * s);
      double u1 = 1.0 - g_rand_double (r), u2 = g_rand_double (r);
      row[x] = (float) (DARK_DN + s + sd * sqrt (-2 * log (u1)) * cos (2 * G_PI * u2));
    }
  }
  return f;
}

/* Square stripes of duty 0.3 (and 0.7) at P and 2P over soft structure along y: opposite phases
 * leave gaps (overlaps) at other columns for each period, where the two pairs' sums differ by the
 * scene's light and its shading passes for noise (asserted: a third above the closed form over all
 * columns). Read on the columns where the two sums agree, and their neighbours, the scene cancels:
 * the closed form over those columns within 6 %. */
static void
test_sets_on_matching_columns (void)
{
  for (guint k = 0; k < 2; k++) {
    double duty = k ? 0.7 : 0.3, period = 24;
    g_autoptr (GRand) r = g_rand_new_with_seed (21 + k);
    g_autoptr (DsImage) a0 = frame_square_duty (r, period, duty, 0), a1 = frame_square_duty (r, period, duty, 1);
    g_autoptr (DsImage) b0 = frame_square_duty (r, 2 * period, duty, 0), b1 = frame_square_duty (r, 2 * period, duty, 1);
    guint8 match[W], columns[W] = { 0 };
    for (guint x = 0; x < W; x++)
      match[x] = fabs (square_lit (x, period, duty, 0) + square_lit (x, period, duty, 1) -
                       square_lit (x, 2 * period, duty, 0) - square_lit (x, 2 * period, duty, 1)) < 1e-9;
    guint kept = 0;
    for (guint x = 1; x + 1 < W; x++)
      kept += columns[x] = match[x - 1] && match[x] && match[x + 1];
    const DsImage *set_a[2] = { a0, a1 }, *set_b[2] = { b0, b1 };
    double masked = ds_column_stats_noise_sets_dn (set_a, set_b, columns, 0, NULL);
    double all = ds_column_stats_noise_sets_dn (set_a, set_b, NULL, 0, NULL);
    /* The closed form: each frame's r^2 + K s, summed over the four, averaged over the samples. */
    double want_kept = 0, want_all = 0;
    guint n_all = 0, n_kept = 0;
    const DsImage *four[4] = { a0, a1, b0, b1 };
    for (guint y = 1; y + 1 < H; y++)
      for (guint x = 0; x < W; x++) {
        double v = 0;
        for (guint i = 0; i < 4; i++)
          v += READ_DN * READ_DN + K_DN * (((const float *) ds_image_row (four[i], y))[x] - DARK_DN);
        want_all += v;
        n_all++;
        if (columns[x]) {
          want_kept += v;
          n_kept++;
        }
      }
    want_kept /= n_kept;
    want_all /= n_all;
    g_test_message ("duty %.1f: %u of %u columns kept; var %.2f against %.2f there, %.2f against %.2f over all", duty,
                    kept, W, masked * masked, want_kept, all * all, want_all);
    g_assert_cmpuint (kept, >, W / 4);
    g_assert_cmpfloat (all * all, >, 1.3 * want_all);
    g_assert_cmpfloat (fabs (masked * masked / want_kept - 1), <, 0.06);
  }
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  g_test_add_func ("/column-noise/dark-majority", test_dark_majority);
  g_test_add_func ("/column-noise/sets-cancel-the-scene", test_sets_cancel_the_scene);
  g_test_add_func ("/column-noise/sets-on-matching-columns", test_sets_on_matching_columns);
  g_test_add_func ("/column-noise/uniform", test_uniform_noise);
  g_test_add_func ("/column-noise/pair-weighted", test_pair_weighted);
  return g_test_run ();
}
