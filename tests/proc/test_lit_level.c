/* Each pixel's lit level from a pair of opposite phases (proc/lit_level.h) against frames built
 * with a known level per pixel: L (x, y) split between the two phases as the model's sum e (x)
 * says, over a dark frame that varies per pixel. The sum of the phases less twice the dark, over
 * e, is L again. The columns and pixels to skip are laid out by the test (gap columns, clipped
 * and non-finite samples), not found by the rule under test. */
#include <glib.h>
#include <math.h>

#include "proc/image.h"
#include "proc/lit_level.h"

#include "pair_frames.h"

#define W 40u
#define H 23u
#define CLIP 5000.0

/* The model's sum of the two phases at x: a column pattern of period 5 whose last column is a gap
 * (0.1, below half the mean 0.72) and whose third is half lit (0.5, above it). */
static double
sum_at (guint x)
{
  static const double e[5] = { 1, 1, 0.5, 1, 0.1 };
  return e[x % 5];
}

static gboolean
gap_column (guint x)
{
  return x % 5 == 4;
}

/* The level, and the dark frame: whole numbers, so that the frames hold them exactly. */
static double
level_at (guint x, guint y)
{
  return 100 + 4 * x + 8 * y;
}

static double
dark_at (guint x, guint y)
{
  return 10 + (x * y) % 7;
}

/* Pixels whose second phase sits at the clip level, and pixels whose first phase is NaN. */
static gboolean
clipped (guint x, guint y)
{
  return (x + y) % 11 == 0;
}

static gboolean
not_finite (guint x, guint y)
{
  return (3 * x + y) % 13 == 0;
}

typedef struct {
  PairFrames pair;
  double e[W];
} Frames;

/* Phase 0 takes all of the column's sum on odd columns and none on even ones: only the sum of
 * the two phases tells the level. */
static void
frames_init (Frames *f)
{
  pair_frames_init (&f->pair, W, H);
  for (guint x = 0; x < W; x++)
    f->e[x] = sum_at (x);
  for (guint y = 0; y < H; y++) {
    float *r0 = ds_image_row (f->pair.l0, y), *r1 = ds_image_row (f->pair.l1, y), *rd = ds_image_row (f->pair.dark, y);
    for (guint x = 0; x < W; x++) {
      double share = x % 2 ? 1.0 : 0.0, lit = level_at (x, y) * sum_at (x);
      rd[x] = (float) dark_at (x, y);
      r0[x] = (float) (dark_at (x, y) + share * lit);
      r1[x] = (float) (dark_at (x, y) + (1 - share) * lit);
      if (clipped (x, y))
        r1[x] = (float) CLIP;
      if (not_finite (x, y))
        r0[x] = NAN;
    }
  }
}

/* Every row_step-th row, the columns that are not gaps, the pixels that neither clip nor hold a
 * NaN: their levels, in row order. */
static void
check_levels (guint row_step)
{
  Frames f;
  frames_init (&f);
  g_autofree double *got = g_new (double, W * H);
  g_autofree double *want = g_new (double, W * H);
  gsize n_want = 0;
  for (guint y = 0; y < H; y += row_step)
    for (guint x = 0; x < W; x++)
      if (!gap_column (x) && !clipped (x, y) && !not_finite (x, y))
        want[n_want++] = level_at (x, y);
  double mean = -1;
  gsize n = ds_lit_level_samples (f.pair.l0, f.pair.l1, f.pair.dark, f.e, CLIP, row_step, got, &mean);
  g_assert_cmpuint (n, ==, n_want);
  for (gsize i = 0; i < n; i++)
    g_assert_cmpfloat_with_epsilon (got[i], want[i], 1e-9 * want[i]);
  /* the kept columns' sums: 1, 1, 0.5, 1 */
  g_assert_cmpfloat_with_epsilon (mean, 3.5 / 4, 1e-12);
  pair_frames_clear (&f.pair);
}

static void
test_every_row (void)
{
  check_levels (1);
}

static void
test_row_step (void)
{
  check_levels (3);
}

/* With no clip level the clipped pixels count, at the level their samples give: the clip value
 * stands in for phase 1's lit part. */
static void
test_no_clip (void)
{
  Frames f;
  frames_init (&f);
  g_autofree double *got = g_new (double, W * H);
  gsize n = ds_lit_level_samples (f.pair.l0, f.pair.l1, f.pair.dark, f.e, 0, 1, got, NULL), i = 0;
  for (guint y = 0; y < H; y++)
    for (guint x = 0; x < W; x++) {
      if (gap_column (x) || not_finite (x, y))
        continue;
      g_assert_cmpuint (i, <, n);
      double share = x % 2 ? 1.0 : 0.0, lit = level_at (x, y) * sum_at (x);
      double p1 = clipped (x, y) ? CLIP : dark_at (x, y) + (1 - share) * lit;
      double want = clipped (x, y) ? (share * lit + p1 - dark_at (x, y)) / sum_at (x) : level_at (x, y);
      g_assert_cmpfloat_with_epsilon (got[i], want, 1e-9 * fabs (want));
      i++;
    }
  g_assert_cmpuint (i, ==, n);
  pair_frames_clear (&f.pair);
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  g_test_add_func ("/lit-level/every-row", test_every_row);
  g_test_add_func ("/lit-level/row-step", test_row_step);
  g_test_add_func ("/lit-level/no-clip", test_no_clip);
  return g_test_run ();
}
