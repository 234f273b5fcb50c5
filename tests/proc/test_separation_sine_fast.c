/* The integer sine's float finalize row (ds_sine_fast_row: no noise model, no extrema, no
 * motion test) against the general row in double precision (separation_rows.c), which the
 * same set takes when it keeps its extrema (keep_extrema changes nothing else of Ld, Lg or the
 * mask on integer input):
 *   - Ld and Lg within float rounding: 8 float epsilons of the pixel's scale, the full scale
 *     plus the dark value over min (m, h), which bounds every term of A / h and mean / m;
 *   - every mask bit equal, but where the double value lies within that rounding of the bit's
 *     threshold (the float row may round either way there); SATURATED is compared on an
 *     integer maximum against a threshold rounded up to an integer, so always exactly;
 *   - the counts equal to the mask's, and the meta the general path's.
 * The thresholds are computed here from docs/estimators.md ("Quality mask") with the noise of
 * the first frame (ds_separation_frame_noise): DARK mean <= sigma, LOW_MODULATION
 * A < 3.717 sqrt(2/N) sigma, DARK_EXCEEDS d - min > z sqrt (sigma^2 (1 + dark)).
 * Rows hold random stripes and edge cases: pixels clipped at full scale in some phases, at 0
 * in every phase, 0 in one phase and full scale in another, flat, a dark frame above the
 * signal; u16 at 16 and 12 bits, u8, N = 3..8, b = 0 and b > 0, a saturation level. */
#include <float.h>
#include <glib.h>
#include <math.h>
#include <string.h>

#include "proc/harmonic_gain.h"
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
  double saturation_level; /* 0: the default */
} Case;

/* Sine stripes of period 11 px, their levels varying along x only; one pixel in 12 is an edge
 * case. */
static void
sine_stripes (gconstpointer data, guint k, guint x, guint64 col, guint full, PhaseLevel *out)
{
  const Case *c = data;
  out->flat = full * (0.02 + 0.3 * (col % 100) / 100.0);
  double amp = full * 0.5 * ((col >> 16) % 100) / 100.0;
  out->level = out->flat + amp * (0.5 + 0.5 * cos (2 * G_PI * ((double) k / c->n + x / 11.0)));
  out->lit = FALSE;
}

static DsImage *
make_frame (const Case *c, guint k, GRand *r)
{
  static const PhasePixelKind kinds[] = { PHASE_PIXEL_CLIPPED_THIRD, PHASE_PIXEL_ZERO, PHASE_PIXEL_ZERO_THEN_FULL,
                                          PHASE_PIXEL_FLAT, PHASE_PIXEL_FULL, PHASE_PIXEL_HALF_FULL,
                                          PHASE_PIXEL_FEW_DN };
  const PhaseFrames f = { c->n, (1u << c->bit_depth) - 1, sine_stripes, c, 96, kinds, G_N_ELEMENTS (kinds) };
  DsImage *img = ds_image_new (c->type, c->w, c->h, NULL);
  g_assert_nonnull (img);
  img->bit_depth = c->bit_depth;
  phase_frames_fill (img, &f, k, r);
  return img;
}

/* A dark frame of a few DN, far above the signal in the top-left region. */
static DsImage *
make_dark (const Case *c)
{
  return phase_frames_dark (c->type, c->bit_depth, c->w, c->h, 5);
}

static double
sample (const DsImage *img, guint x, guint y)
{
  return img->type == DS_SAMPLE_U8 ? ((const guint8 *) ds_image_row (img, y))[x]
                                   : ((const guint16 *) ds_image_row (img, y))[x];
}

static float
pix (const DsImage *img, guint x, guint y)
{
  return ((const float *) ds_image_row (img, y))[x];
}

/* Folds the frames into a set of `params` and finalizes it. */
static DsSeparation *
separate (const Case *c, const DsSeparationParams *p, DsImage **frames, const DsImage *dark)
{
  g_autoptr (GError) error = NULL;
  g_autoptr (DsPhaseSet) set = ds_phase_set_new (p, c->w, c->h, &error);
  g_assert_no_error (error);
  if (dark)
    g_assert_true (ds_phase_set_set_dark (set, dark, &error));
  for (guint k = 0; k < c->n; k++)
    g_assert_true (ds_phase_set_accumulate (set, k, frames[k], &error));
  DsSeparation *sep = ds_phase_set_finalize (set, &error);
  g_assert_no_error (error);
  return sep;
}

static void
run_case (const Case *c, guint threads)
{
  DsSeparationParams p;
  ds_separation_params_init (&p, c->n);
  p.estimator = DS_ESTIMATOR_SINE;
  p.black_level = c->black;
  p.duty = c->duty;
  p.threads = threads;
  p.saturation_level = c->saturation_level;
  GRand *r = g_rand_new_with_seed (c->w * 31 + c->n);
  DsImage **frames = g_new0 (DsImage *, c->n);
  for (guint k = 0; k < c->n; k++)
    frames[k] = make_frame (c, k, r);
  g_rand_free (r);
  g_autoptr (DsImage) dark = c->dark ? make_dark (c) : NULL;

  g_autoptr (DsSeparation) fast = separate (c, &p, frames, dark);
  DsSeparationParams pg = p;
  pg.keep_extrema = TRUE; /* the general row */
  g_autoptr (DsSeparation) gen = separate (c, &pg, frames, dark);
  g_assert_null (fast->max);
  g_assert_nonnull (gen->mean);

  const guint n = c->n, full = (1u << c->bit_depth) - 1;
  const double m = ds_pattern_mean (p.pattern, p.duty, p.black_level);
  const double h = ds_harmonic_gain_theory (p.pattern, p.duty, p.black_level);
  const double sat = c->saturation_level > 0 ? c->saturation_level : full;
  const double sigma = ds_separation_frame_noise (frames[0]);
  const double floor_ = sigma, lowamp = 3.7169221888498383 * sqrt (2.0 / n) * sigma;
  const double z = ds_separation_normal_upper_quantile (DS_DARK_EXCEEDS_FALSE_ALARM / n);
  const double exceed = isnan (sigma) ? 0.0 : z * sqrt (sigma * sigma * (dark ? 2.0 : 1.0));
  g_assert_cmpfloat (fabs (gen->meta.harmonic_gain - h), <, 1e-12);
  g_assert_cmpfloat (fabs (gen->meta.pattern_mean - m), <, 1e-12);

  guint64 skipped = 0, valid = 0, flagged[DS_MASK_N_BITS] = { 0 }, last_bits = 0;
  for (guint y = 0; y < c->h; y++)
    for (guint x = 0; x < c->w; x++) {
      double hi = -1, d = dark ? sample (dark, x, y) : 0.0;
      for (guint k = 0; k < n; k++)
        hi = MAX (hi, sample (frames[k], x, y));
      double scale = (full + d + 1) / MIN (m, h), tol = 8 * FLT_EPSILON * scale;
      float tf = pix (fast->transmissive, x, y), gf = pix (fast->scattered, x, y);
      double tg = pix (gen->transmissive, x, y), gg = pix (gen->scattered, x, y);
      if (fabs (tf - tg) > tol || fabs (gf - gg) > tol)
        g_error ("%s: (%u, %u) fast Ld %.9g Lg %.9g, general %.9g %.9g", c->name, x, y, tf, gf, tg, gg);
      last_bits += tf != tg || gf != gg;
      /* the general path's values, dark-subtracted: mean, min; A = h Ld */
      double mean = pix (gen->mean, x, y), lo = pix (gen->min, x, y), a = h * tg;
      guint8 mf = ((const guint8 *) ds_image_row (fast->mask, y))[x];
      guint8 mg = ((const guint8 *) ds_image_row (gen->mask, y))[x];
      struct {
        gboolean set;
        double margin; /* distance from the threshold */
      } bit[DS_MASK_N_BITS] = {
        [0] = { hi >= sat, G_MAXDOUBLE },
        [1] = { mean <= floor_, mean - floor_ },
        [2] = { a < lowamp, a - lowamp },
        [3] = { FALSE, G_MAXDOUBLE },
        [4] = { tg < 0 || gg < 0, MIN (tg, gg) },
        [5] = { -lo > exceed, -lo - exceed },
        [6] = { FALSE, G_MAXDOUBLE },
        [7] = { FALSE, G_MAXDOUBLE },
      };
      for (guint i = 0; i < DS_MASK_N_BITS; i++) {
        guint want = bit[i].set, got_f = (mf >> i) & 1, got_g = (mg >> i) & 1;
        double margin = bit[i].margin;
        if (!isnan (margin) && fabs (margin) <= tol) {
          skipped += got_f != got_g;
          continue;
        }
        if (got_f != got_g || got_g != want)
          g_error ("%s: (%u, %u) bit %u: fast mask %#x, general %#x, expected %u (max %g mean %g "
                   "min %g A %g dark %g)", c->name, x, y, i, mf, mg, want, hi, mean, lo, a, d);
      }
      valid += mf == 0;
      for (guint i = 0; i < DS_MASK_N_BITS; i++)
        flagged[i] += (mf >> i) & 1;
    }
  /* the counts are those of the plane; the meta otherwise the general path's */
  g_assert_cmpuint (fast->meta.valid_pixels, ==, valid);
  for (guint i = 0; i < DS_MASK_N_BITS; i++)
    g_assert_cmpuint (fast->meta.flagged[i], ==, flagged[i]);
  DsSeparationMeta mf = fast->meta, mg = gen->meta;
  mf.valid_pixels = mg.valid_pixels = 0;
  memset (mf.flagged, 0, sizeof mf.flagged);
  memset (mg.flagged, 0, sizeof mg.flagged);
  g_assert_cmpmem (&mf, sizeof mf, &mg, sizeof mg);
  /* the case exercises what it is about */
  g_assert_cmpuint (valid, >, 0);
  g_assert_cmpuint (flagged[0], >, 0);
  g_assert_cmpuint (flagged[3], ==, 0);
  if (c->dark || c->black > 0)
    g_assert_cmpuint (flagged[4], >, 0);
  if (!isnan (sigma)) {
    g_assert_cmpuint (flagged[1], >, 0);
    g_assert_cmpuint (flagged[2], >, 0);
  }
  if (c->dark)
    g_assert_cmpuint (flagged[5], >, 0);
  /* the two are distinct paths (float and double): their values differ in the last bits
   * somewhere, so this is not a path compared with itself */
  if ((guint64) c->w * c->h >= 1000)
    g_assert_cmpuint (last_bits, >, 0);
  g_test_message ("%s, %u threads: %" G_GUINT64_FORMAT " bits within rounding of a threshold, "
                  "%" G_GUINT64_FORMAT " pixels with other float bits",
                  c->name, threads, skipped, last_bits);
  g_assert_cmpuint (skipped, <=, (guint64) c->w * c->h / 1000 + 1);
  for (guint k = 0; k < n; k++)
    ds_image_free (frames[k]);
  g_free (frames);
}

static const Case cases[] = {
  { "u16 16-bit N=8", DS_SAMPLE_U16, 16, 8, 517, 263, 0.0, 0.5, FALSE, 0 },
  { "u16 12-bit N=8 dark b=0.1 a=0.4", DS_SAMPLE_U16, 12, 8, 517, 263, 0.1, 0.4, TRUE, 0 },
  { "u16 N=5 saturation level 60000.5 b=0.05", DS_SAMPLE_U16, 16, 5, 611, 233, 0.05, 0.6, FALSE, 60000.5 },
  { "u8 N=4 dark", DS_SAMPLE_U8, 8, 4, 523, 271, 0.0, 0.5, TRUE, 0 },
  { "u8 7-bit N=3 b=0.2", DS_SAMPLE_U8, 7, 3, 131, 61, 0.2, 0.5, FALSE, 0 },
  { "u16 N=6 63x7 dark", DS_SAMPLE_U16, 16, 6, 63, 7, 0.0, 0.5, TRUE, 0 },
};

static void
test_against_general_row (void)
{
  const guint threads[] = { 1, 3 };
  for (guint i = 0; i < G_N_ELEMENTS (cases); i++)
    for (guint t = 0; t < G_N_ELEMENTS (threads); t++)
      run_case (&cases[i], threads[t]);
}

/* One pixel and 17x2 (no noise estimate: DARK and LOW_MODULATION off, DARK_EXCEEDS without a
 * margin), the kernel's loop tails; hand-made values checked against their closed form. */
static void
test_tiny (void)
{
  DsSeparationParams p;
  ds_separation_params_init (&p, 4);
  p.estimator = DS_ESTIMATOR_SINE;
  p.threads = 1;
  g_autoptr (DsPhaseSet) set = ds_phase_set_new (&p, 1, 1, NULL);
  /* 100 + 60 cos (2 pi k / 4 - 0): 160, 100, 40, 100 */
  const guint16 v[4] = { 160, 100, 40, 100 };
  for (guint k = 0; k < 4; k++) {
    g_autoptr (DsImage) f = ds_image_new (DS_SAMPLE_U16, 1, 1, NULL);
    f->bit_depth = 16;
    ((guint16 *) f->data)[0] = v[k];
    g_assert_true (ds_phase_set_accumulate (set, k, f, NULL));
  }
  g_autoptr (DsSeparation) s = ds_phase_set_finalize (set, NULL);
  double h = s->meta.harmonic_gain, m = s->meta.pattern_mean;
  /* A = 60, mean = 100: Ld = A / h, Lg = mean / m - A / h */
  g_assert_cmpfloat (fabs (((float *) s->transmissive->data)[0] - 60 / h), <, 1e-4);
  g_assert_cmpfloat (fabs (((float *) s->scattered->data)[0] - (100 / m - 60 / h)), <, 1e-4);
  g_assert_cmpuint (((guint8 *) s->mask->data)[0], ==, 100 / m - 60 / h < 0 ? DS_MASK_NEGATIVE : 0);

  const Case tiny = { "17x2 dark", DS_SAMPLE_U16, 16, 3, 17, 2, 0.0, 0.5, TRUE, 0 };
  GRand *r = g_rand_new_with_seed (5);
  DsImage *frames[3];
  for (guint k = 0; k < 3; k++)
    frames[k] = make_frame (&tiny, k, r);
  g_rand_free (r);
  g_autoptr (DsImage) dark = make_dark (&tiny);
  DsSeparationParams q;
  ds_separation_params_init (&q, 3);
  q.estimator = DS_ESTIMATOR_SINE;
  g_autoptr (DsSeparation) fast = separate (&tiny, &q, frames, dark);
  q.keep_extrema = TRUE;
  g_autoptr (DsSeparation) gen = separate (&tiny, &q, frames, dark);
  g_assert_true (isnan (fast->meta.noise_dn));
  for (guint y = 0; y < 2; y++)
    for (guint x = 0; x < 17; x++) {
      g_assert_cmpfloat (fabs (pix (fast->transmissive, x, y) - pix (gen->transmissive, x, y)), <, 1e-2);
      g_assert_cmpfloat (fabs (pix (fast->scattered, x, y) - pix (gen->scattered, x, y)), <, 1e-2);
      guint8 mf = ((guint8 *) ds_image_row (fast->mask, y))[x], mg = ((guint8 *) ds_image_row (gen->mask, y))[x];
      /* the thresholds of the noise tests are off or 0: only a value at exactly 0 is close */
      if (pix (gen->scattered, x, y) != 0)
        g_assert_cmpuint (mf, ==, mg);
    }
  for (guint k = 0; k < 3; k++)
    ds_image_free (frames[k]);
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  g_test_add_func ("/separation-sine-fast/against-general-row", test_against_general_row);
  g_test_add_func ("/separation-sine-fast/tiny", test_tiny);
  return g_test_run ();
}
