/* The set's last frame folded on the finalize's pass (ds_phase_set_accumulate_finalize_into,
 * what descatterd calls) and the integer maxmin kernel behind it, against two expectations:
 *   - the two calls it stands for (ds_phase_set_accumulate, then ds_phase_set_finalize_into):
 *     the same planes, mask, counts and meta bit for bit, with 1, 2, 3 and 5 threads (odd
 *     heights: bands of unequal size), and the same state afterwards;
 *   - a reference written here from the definitions in docs/estimators.md, per pixel in double
 *     over all N frames kept in memory (not streamed): Ld, Lg within float rounding, every mask
 *     bit exact but where the double value lies within float rounding of the bit's threshold.
 * The frames hold clipped pixels (at the saturation level in some phases), dark pixels, pixels
 * at 0 in one phase and full scale in another, a dark frame above the signal in one region,
 * at 16 and 12 bits, u8, with and without a dark frame, b = 0 and b > 0, undersampled columns.
 * The reference takes the noise threshold from ds_separation_frame_noise and the quantiles
 * from ds_separation_range_quantile / _normal_upper_quantile (checked by
 * /separation-noise/... and /separation/low-modulation); UNDERSAMPLED comes from the sampling
 * model's column flags (/sampling/undersampled-flags). */
#include <float.h>
#include <glib.h>
#include <math.h>
#include <string.h>

#include "proc/proc_error.h"
#include "proc/separation.h"
#include "proc/separation_internal.h"
#include "tests/common/phase_frames.h"

typedef struct {
  const char *name;
  DsSampleType type;
  guint bit_depth;
  guint n;
  guint w, h;
  double black, duty;
  gboolean dark;
  gboolean undersampled; /* a period and an edge blur that leave some columns undersampled */
  double saturation_level; /* 0: the default */
  gboolean motion;       /* detect_motion: its sums folded on the pass too (the bit itself is
                            /motion/...'s; here the fused and the two calls agree on it) */
} Case;

/* Square stripes of the case's duty, their levels varying along x only; one pixel in 16 is a
 * hard one. */
static void
fused_stripes (gconstpointer data, guint k, guint x, guint64 col, guint full, PhaseLevel *out)
{
  const Case *c = data;
  out->lit = ((x * c->n / 6 + k) % c->n) < (guint) MAX (1.0, c->duty * c->n);
  out->flat = full * (0.05 + 0.2 * (col % 100) / 100.0);
  double hi = out->flat + full * 0.4 * ((col >> 16) % 100) / 100.0;
  out->level = out->lit ? hi : out->flat;
}

static DsImage *
make_frame (const Case *c, guint k, GRand *r, gsize pad)
{
  /* the motion cases: brighter after the first phase, as when an edge passed */
  const PhasePixelKind kinds[] = { PHASE_PIXEL_CLIPPED_LIT, PHASE_PIXEL_FEW_DN, PHASE_PIXEL_ZERO_THEN_FULL,
                                   PHASE_PIXEL_FLAT, c->motion ? PHASE_PIXEL_STEP : PHASE_PIXEL_STRIPES };
  const PhaseFrames f = { c->n, (1u << c->bit_depth) - 1, fused_stripes, c, 64, kinds, G_N_ELEMENTS (kinds) };
  gsize size = c->type == DS_SAMPLE_U8 ? 1 : 2;
  DsImage *img = ds_image_new_with_stride (c->type, c->w, c->h, c->w * size + pad, NULL);
  g_assert_nonnull (img);
  img->bit_depth = c->bit_depth;
  memset (img->data, 0xA5, img->stride * c->h); /* padding that would show if read */
  phase_frames_fill (img, &f, k, r);
  return img;
}

/* The dark frame: a small offset, far above the signal in the top-left region. */
static DsImage *
make_dark (const Case *c)
{
  return phase_frames_dark (c->type, c->bit_depth, c->w, c->h, 3);
}

static void
init_params (const Case *c, guint threads, DsSeparationParams *p)
{
  ds_separation_params_init (p, c->n);
  p->black_level = c->black;
  p->duty = c->duty;
  p->threads = threads;
  p->saturation_level = c->saturation_level;
  p->detect_motion = c->motion;
  if (c->undersampled) {
    p->geometry.period_px = 8;
    p->geometry.edge_blur_px = 0.6; /* a third of the columns undersampled at N = 6 */
    p->geometry.edge_blur_known = TRUE;
    p->geometry.phase_offset_known = TRUE;
    p->geometry.phase_offset_cycles = 0.3;
  }
}

static double
sample (const DsImage *img, guint x, guint y)
{
  return img->type == DS_SAMPLE_U8 ? ((const guint8 *) ds_image_row (img, y))[x]
                                   : ((const guint16 *) ds_image_row (img, y))[x];
}

static void
assert_same_plane (const DsImage *a, const DsImage *b, const char *what)
{
  g_assert_nonnull (a);
  g_assert_nonnull (b);
  g_assert_cmpuint (a->width, ==, b->width);
  g_assert_cmpuint (a->height, ==, b->height);
  gsize row = (gsize) a->width * ds_sample_size (a->type);
  for (guint y = 0; y < a->height; y++)
    if (memcmp (ds_image_row (a, y), ds_image_row (b, y), row) != 0)
      g_error ("%s: row %u differs", what, y);
}

static void
assert_same_result (const DsSeparation *a, const DsSeparation *b)
{
  assert_same_plane (a->transmissive, b->transmissive, "transmissive");
  assert_same_plane (a->scattered, b->scattered, "scattered");
  assert_same_plane (a->mask, b->mask, "mask");
  g_assert_null (a->max);
  g_assert_null (b->max);
  g_assert_cmpmem (&a->meta, sizeof a->meta, &b->meta, sizeof b->meta);
}

/* Checks `sep` against the reference on `frames`; returns how many (pixel, bit) decisions
 * were skipped as within rounding of their threshold. */
static guint64
check_reference (const Case *c, const DsSeparationParams *p, DsImage **frames, const DsImage *dark,
                 const DsSeparation *sep)
{
  const guint n = c->n;
  const double b = c->black, m = c->duty + c->black * (1 - c->duty);
  const double sat = c->saturation_level > 0 ? c->saturation_level : (double) ((1u << c->bit_depth) - 1);
  const double sigma = ds_separation_frame_noise (frames[0]);
  const double q = ds_separation_range_quantile (n, 0.999);
  const double z = ds_separation_normal_upper_quantile (DS_DARK_EXCEEDS_FALSE_ALARM / n);
  /* without an estimate (NAN) DARK and LOW_MODULATION are off, DARK_EXCEEDS has no margin */
  const double floor_ = sigma, lowmod = q * sigma;
  const double exceed = isnan (sigma) ? 0.0 : z * sqrt (sigma * sigma * (dark ? 2.0 : 1.0));
  g_autofree guint8 *columns = g_new0 (guint8, c->w);
  DsSamplingCheck check;
  g_assert_true (ds_separation_check_sampling (p, &check, NULL));
  guint64 under_columns = 0;
  if (c->undersampled)
    under_columns = ds_sampling_column_flags (p, p->geometry.phase_offset_cycles, c->w, columns);
  g_assert_true (!c->undersampled || (under_columns > 0 && under_columns < c->w));

  guint64 skipped = 0, valid = 0, flagged[DS_MASK_N_BITS] = { 0 };
  for (guint y = 0; y < c->h; y++) {
    const float *t = ds_image_row (sep->transmissive, y), *g = ds_image_row (sep->scattered, y);
    const guint8 *mk = ds_image_row (sep->mask, y);
    for (guint x = 0; x < c->w; x++) {
      double hi = -1, lo = G_MAXDOUBLE;
      for (guint k = 0; k < n; k++) {
        double v = sample (frames[k], x, y);
        hi = MAX (hi, v);
        lo = MIN (lo, v);
      }
      double d = dark ? sample (dark, x, y) : 0.0;
      double ld = (hi - lo) / (1 - b), lg = (lo - d - b * ld) / m, mean = m * (ld + lg);
      /* float rounding: the kernel works in float on values up to the full scale */
      double tol = 4 * FLT_EPSILON * (hi + d + 1) / MIN (m, 1 - b);
      if (fabs (t[x] - ld) > tol || fabs (g[x] - lg) > tol)
        g_error ("%s: (%u, %u) Ld %.9g Lg %.9g, reference %.9g %.9g", c->name, x, y, t[x], g[x], ld, lg);
      struct {
        gboolean set;
        double margin; /* distance from the threshold */
      } bit[DS_MASK_N_BITS] = {
        [0] = { hi >= sat, hi - sat },
        [1] = { mean <= floor_, mean - floor_ },
        [2] = { hi - lo < lowmod, hi - lo - lowmod },
        [3] = { FALSE, G_MAXDOUBLE },
        [4] = { ld < 0 || lg < 0, MIN (ld, lg) },
        [5] = { d - lo > exceed, d - lo - exceed },
        [6] = { columns[x] != 0, G_MAXDOUBLE },
        [7] = { c->motion && ((mk[x] >> 7) & 1), G_MAXDOUBLE }, /* motion: not judged here */
      };
      guint8 want = 0;
      for (guint i = 0; i < DS_MASK_N_BITS; i++) {
        want |= (guint8) (bit[i].set << i);
        double margin = bit[i].margin;
        if (!isnan (margin) && margin != 0 && fabs (margin) <= tol) {
          skipped += ((mk[x] >> i) & 1) != (guint) bit[i].set;
          continue;
        }
        if (((mk[x] >> i) & 1) != (guint) bit[i].set)
          g_error ("%s: (%u, %u) mask %#x, reference %#x (bit %u; max %g min %g dark %g)", c->name, x, y,
                   mk[x], want, i, hi, lo, d);
      }
      valid += mk[x] == 0;
      for (guint i = 0; i < DS_MASK_N_BITS; i++)
        flagged[i] += (mk[x] >> i) & 1;
    }
  }
  /* the counts are those of the plane */
  g_assert_cmpuint (sep->meta.valid_pixels, ==, valid);
  for (guint i = 0; i < DS_MASK_N_BITS; i++)
    g_assert_cmpuint (sep->meta.flagged[i], ==, flagged[i]);
  /* the case exercises what it is about */
  g_assert_cmpuint (valid, >, 0);
  g_assert_cmpuint (flagged[0], >, 0); /* saturated */
  if (c->dark || c->black > 0)
    g_assert_cmpuint (flagged[4], >, 0); /* negative */
  if (!isnan (sigma)) {
    g_assert_cmpuint (flagged[1], >, 0); /* dark */
    g_assert_cmpuint (flagged[2], >, 0); /* low modulation */
  }
  if (c->dark)
    g_assert_cmpuint (flagged[5], >, 0); /* dark exceeds */
  if (c->undersampled)
    g_assert_cmpuint (flagged[6], ==, under_columns * c->h);
  return skipped;
}

/* One case at `threads`: the two calls, the fused call, the reference. */
static void
run_case (const Case *c, guint threads)
{
  DsSeparationParams p;
  init_params (c, threads, &p);
  g_autoptr (GError) error = NULL;
  g_autoptr (DsPhaseSet) two = ds_phase_set_new (&p, c->w, c->h, &error);
  g_assert_no_error (error);
  g_autoptr (DsPhaseSet) one = ds_phase_set_new (&p, c->w, c->h, &error);
  g_assert_no_error (error);
  g_autoptr (DsImage) dark = c->dark ? make_dark (c) : NULL;
  if (dark) {
    g_assert_true (ds_phase_set_set_dark (two, dark, &error));
    g_assert_true (ds_phase_set_set_dark (one, dark, &error));
  }
  GRand *r = g_rand_new_with_seed (c->w * 31 + c->n);
  DsImage **frames = g_new0 (DsImage *, c->n);
  for (guint k = 0; k < c->n; k++)
    frames[k] = make_frame (c, k, r, k % 2 ? 6 : 0);
  g_rand_free (r);

  /* pooled results, as the daemon keeps them: two sets, each finalized into the same planes
   * (the second after a reset, so that nothing of the first may remain) */
  g_autoptr (DsSeparation) a = ds_separation_new ();
  g_autoptr (DsSeparation) f = ds_separation_new ();
  for (guint round = 0; round < 2; round++) {
    ds_phase_set_reset (two);
    ds_phase_set_reset (one);
    /* the second round's fused finalize on one thread, as descatterd's in continuous mode,
     * against the two calls' on all */
    ds_phase_set_set_finalize_threads (one, round == 1 ? 1 : 0);
    for (guint k = 0; k < c->n; k++) {
      /* as descatterd: every other frame on one thread */
      ds_phase_set_set_fold_threads (two, k % 2 ? 1 : 0);
      ds_phase_set_set_fold_threads (one, k % 2 ? 1 : 0);
      g_assert_true (ds_phase_set_accumulate (two, k, frames[k], &error));
      if (k + 1 < c->n) {
        g_assert_true (ds_phase_set_accumulate (one, k, frames[k], &error));
      } else {
        gboolean folded = FALSE;
        g_assert_true (ds_phase_set_accumulate_finalize_into (one, k, frames[k], f, &folded, &error));
        g_assert_no_error (error);
        g_assert_true (folded);
      }
    }
    g_assert_true (ds_phase_set_finalize_into (two, a, &error));
    g_assert_no_error (error);
    assert_same_result (a, f);
    g_assert_cmpuint (ds_phase_set_frames_folded (one), ==, c->n);
    /* the hard pixels (a sample at 0 or full scale in one phase) depart from any stripes */
    g_assert_true (!c->motion || f->meta.flagged[7] > 0);
  }
  /* the state holds the last frame too: a second finalize gives the same result */
  g_autoptr (DsSeparation) again = ds_phase_set_finalize (one, &error);
  g_assert_no_error (error);
  assert_same_result (f, again);

  if (threads == 1) {
    guint64 skipped = check_reference (c, &p, frames, dark, f);
    g_test_message ("%s: %" G_GUINT64_FORMAT " decisions within rounding of a threshold", c->name, skipped);
    g_assert_cmpuint (skipped, <=, (guint64) c->w * c->h / 1000);
  }
  for (guint k = 0; k < c->n; k++)
    ds_image_free (frames[k]);
  g_free (frames);
}

static const Case cases[] = {
  { "u16 16-bit N=4", DS_SAMPLE_U16, 16, 4, 517, 263, 0.0, 0.5, FALSE, FALSE, 0, FALSE },
  { "u16 12-bit N=8 dark b=0.1 a=0.4", DS_SAMPLE_U16, 12, 8, 517, 263, 0.1, 0.4, TRUE, FALSE, 0, FALSE },
  { "u16 N=6 undersampled columns, dark", DS_SAMPLE_U16, 16, 6, 301, 449, 0.0, 0.5, TRUE, TRUE, 0, FALSE },
  { "u16 N=5 saturation level 60000 b=0.05", DS_SAMPLE_U16, 16, 5, 611, 233, 0.05, 0.6, FALSE, FALSE, 60000, FALSE },
  { "u8 N=4 dark", DS_SAMPLE_U8, 8, 4, 523, 271, 0.0, 0.5, TRUE, FALSE, 0, FALSE },
  { "u8 7-bit N=3 b=0.2", DS_SAMPLE_U8, 7, 3, 13, 11, 0.2, 0.5, FALSE, FALSE, 0, FALSE },
  { "u16 N=4 63x7", DS_SAMPLE_U16, 16, 4, 63, 7, 0.0, 0.5, TRUE, FALSE, 0, FALSE },
  { "u16 12-bit N=8 dark b=0.1 motion", DS_SAMPLE_U16, 12, 8, 517, 263, 0.1, 0.4, TRUE, FALSE, 0, TRUE },
  { "u8 N=6 undersampled columns motion", DS_SAMPLE_U8, 8, 6, 301, 449, 0.0, 0.5, FALSE, TRUE, 0, TRUE },
};

static void
test_against_two_calls_and_reference (void)
{
  const guint threads[] = { 1, 2, 3, 5 };
  for (guint i = 0; i < G_N_ELEMENTS (cases); i++)
    for (guint t = 0; t < G_N_ELEMENTS (threads); t++) {
      g_test_message ("%s, %u threads", cases[i].name, threads[t]);
      run_case (&cases[i], threads[t]);
    }
}

/* One pixel, two rows (no noise estimate: NAN), the kernel's loop tails: the reference still
 * holds and the fused call equals the two calls. */
static void
test_tiny (void)
{
  const Case tiny[] = {
    { "1x1", DS_SAMPLE_U16, 16, 2, 1, 1, 0.0, 0.5, FALSE, FALSE, 0, FALSE },
    { "17x2 dark", DS_SAMPLE_U16, 16, 3, 17, 2, 0.0, 0.5, TRUE, FALSE, 0, FALSE },
  };
  for (guint i = 0; i < G_N_ELEMENTS (tiny); i++) {
    const Case *c = &tiny[i];
    DsSeparationParams p;
    init_params (c, 1, &p);
    g_autoptr (DsPhaseSet) two = ds_phase_set_new (&p, c->w, c->h, NULL);
    g_autoptr (DsPhaseSet) one = ds_phase_set_new (&p, c->w, c->h, NULL);
    g_autoptr (DsImage) dark = c->dark ? make_dark (c) : NULL;
    if (dark) {
      g_assert_true (ds_phase_set_set_dark (two, dark, NULL));
      g_assert_true (ds_phase_set_set_dark (one, dark, NULL));
    }
    GRand *r = g_rand_new_with_seed (3);
    g_autoptr (DsSeparation) f = ds_separation_new ();
    for (guint k = 0; k < c->n; k++) {
      g_autoptr (DsImage) frame = make_frame (c, k, r, 0);
      /* the hard pixels need the full range: the one pixel is clipped in the last phase */
      if (c->w == 1)
        ((guint16 *) frame->data)[0] = (guint16) (k + 1 == c->n ? 65535 : 100 * k);
      g_assert_true (ds_phase_set_accumulate (two, k, frame, NULL));
      if (k + 1 < c->n)
        g_assert_true (ds_phase_set_accumulate (one, k, frame, NULL));
      else
        g_assert_true (ds_phase_set_accumulate_finalize_into (one, k, frame, f, NULL, NULL));
    }
    g_rand_free (r);
    g_autoptr (DsSeparation) a = ds_phase_set_finalize (two, NULL);
    assert_same_result (a, f);
    g_assert_true (isnan (f->meta.noise_dn));
    if (c->w == 1) {
      g_assert_cmpfloat (((float *) f->transmissive->data)[0], ==, 65535);
      g_assert_cmpfloat (((float *) f->scattered->data)[0], ==, 0);
      g_assert_cmpuint (((guint8 *) f->mask->data)[0], ==, DS_MASK_SATURATED);
    }
  }
}

/* Errors: a bad frame folds nothing; a plane of the wrong shape, or a phase still without a
 * frame, folds the frame and fails as the finalize would; a configuration the single pass
 * does not cover (extrema kept, sine, averaging) gives what the two calls give. */
static void
test_errors_and_other_paths (void)
{
  const Case c = { "errors", DS_SAMPLE_U16, 16, 4, 40, 30, 0.0, 0.5, FALSE, FALSE, 0, FALSE };
  DsSeparationParams p;
  init_params (&c, 1, &p);
  GRand *r = g_rand_new_with_seed (5);
  DsImage *frames[4];
  for (guint k = 0; k < 4; k++)
    frames[k] = make_frame (&c, k, r, 0);
  g_rand_free (r);
  g_autoptr (GError) error = NULL;
  g_autoptr (DsPhaseSet) set = ds_phase_set_new (&p, c.w, c.h, NULL);
  g_autoptr (DsSeparation) sep = ds_separation_new ();
  for (guint k = 0; k < 3; k++)
    g_assert_true (ds_phase_set_accumulate (set, k, frames[k], NULL));

  /* a frame of another size: nothing folded */
  gboolean folded = TRUE;
  g_autoptr (DsImage) small = ds_image_new (DS_SAMPLE_U16, c.w - 1, c.h, NULL);
  g_assert_false (ds_phase_set_accumulate_finalize_into (set, 3, small, sep, &folded, &error));
  g_assert_error (error, DS_PROC_ERROR, DS_PROC_ERROR_SIZE_MISMATCH);
  g_clear_error (&error);
  g_assert_false (folded);
  g_assert_cmpuint (ds_phase_set_frames_folded (set), ==, 3);
  /* no result to write into: nothing folded */
  g_assert_false (ds_phase_set_accumulate_finalize_into (set, 3, frames[3], NULL, &folded, &error));
  g_assert_error (error, DS_PROC_ERROR, DS_PROC_ERROR_INVALID_ARGUMENT);
  g_clear_error (&error);
  g_assert_false (folded);

  /* a pooled plane of another shape: folded, the finalize's error, nothing written */
  sep->transmissive = ds_image_new (DS_SAMPLE_F32, c.w, c.h + 1, NULL);
  g_assert_false (ds_phase_set_accumulate_finalize_into (set, 3, frames[3], sep, &folded, &error));
  g_assert_error (error, DS_PROC_ERROR, DS_PROC_ERROR_INVALID_ARGUMENT);
  g_assert_nonnull (strstr (error->message, "transmissive"));
  g_clear_error (&error);
  g_assert_true (folded);
  g_assert_cmpuint (ds_phase_set_frames_folded (set), ==, 4);
  g_autoptr (DsSeparation) after = ds_phase_set_finalize (set, &error);
  g_assert_no_error (error);
  g_autoptr (DsPhaseSet) ref_set = ds_phase_set_new (&p, c.w, c.h, NULL);
  for (guint k = 0; k < 4; k++)
    g_assert_true (ds_phase_set_accumulate (ref_set, k, frames[k], NULL));
  g_autoptr (DsSeparation) ref = ds_phase_set_finalize (ref_set, NULL);
  assert_same_result (ref, after);

  /* a phase still missing: folded, NOT_ENOUGH_PHASES */
  ds_phase_set_reset (set);
  g_assert_true (ds_phase_set_accumulate (set, 0, frames[0], NULL));
  g_assert_false (ds_phase_set_accumulate_finalize_into (set, 2, frames[2], sep, &folded, &error));
  g_assert_error (error, DS_PROC_ERROR, DS_PROC_ERROR_NOT_ENOUGH_PHASES);
  g_clear_error (&error);
  g_assert_true (folded);
  g_assert_cmpuint (ds_phase_set_frames_folded (set), ==, 2);

  /* other configurations: the two calls' result */
  for (guint variant = 0; variant < 4; variant++) {
    DsSeparationParams q = p;
    guint averages = 1;
    if (variant == 0)
      q.keep_extrema = TRUE;
    else if (variant == 1)
      q.estimator = DS_ESTIMATOR_SINE;
    else if (variant == 2)
      averages = 2;
    else
      q.system_gain = 0.5;
    g_autoptr (DsPhaseSet) s1 = ds_phase_set_new (&q, c.w, c.h, NULL);
    g_autoptr (DsPhaseSet) s2 = ds_phase_set_new (&q, c.w, c.h, NULL);
    g_autoptr (DsSeparation) fused = ds_separation_new ();
    for (guint k = 0; k < 4; k++)
      for (guint m = 0; m < averages; m++) {
        g_assert_true (ds_phase_set_accumulate (s2, k, frames[(k + m) % 4], NULL));
        if (k == 3 && m + 1 == averages)
          g_assert_true (ds_phase_set_accumulate_finalize_into (s1, k, frames[(k + m) % 4], fused, NULL, &error));
        else
          g_assert_true (ds_phase_set_accumulate (s1, k, frames[(k + m) % 4], NULL));
        g_assert_no_error (error);
      }
    g_autoptr (DsSeparation) two = ds_phase_set_finalize (s2, NULL);
    g_assert_cmpmem (&two->meta, sizeof two->meta, &fused->meta, sizeof fused->meta);
    assert_same_plane (two->transmissive, fused->transmissive, "transmissive");
    assert_same_plane (two->scattered, fused->scattered, "scattered");
    assert_same_plane (two->mask, fused->mask, "mask");
  }
  for (guint k = 0; k < 4; k++)
    ds_image_free (frames[k]);
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  g_test_add_func ("/separation-fused/two-calls-and-reference", test_against_two_calls_and_reference);
  g_test_add_func ("/separation-fused/tiny", test_tiny);
  g_test_add_func ("/separation-fused/errors-and-other-paths", test_errors_and_other_paths);
  return g_test_run ();
}
