/* The single-frame estimator (proc/single_frame.h) against closed forms written here (the
 * pattern's m and h from their definitions, not from the library), against the phase-set
 * estimator on the same samples (the window of a whole period holds exactly the values a set
 * of N = P phases shows at one pixel of a uniform scene), and at the edges of its model: a
 * step in Ld (the resolution cost is the window), a saturated column (flagged in exactly the
 * windows that hold it), and the refusals. */
#include <float.h>
#include <math.h>
#include <string.h>

#include "proc/proc_error.h"
#include "proc/separation.h"
#include "proc/single_frame.h"

/* The pattern value at pixel centre x, point-sampled: b + (1 - b) * pattern(u), u the position
 * in the period wrapped to [-1/2, 1/2) (proc/harmonic_gain.h's convention). */
static double
pattern_at (DsPatternKind kind, double duty, double b, double period, double offset_cycles, double x)
{
  double u = x / period - offset_cycles;
  u -= floor (u + 0.5);
  double p = kind == DS_PATTERN_SINE ? 0.5 * (1 + cos (2 * G_PI * u)) : (fabs (u) < duty / 2 ? 1 : 0);
  return b + (1 - b) * p;
}

static DsImage *
render_f32 (guint w, guint h, DsPatternKind kind, double duty, double b, double period, double offset,
            const double *ld_of_x, double lg)
{
  double m = kind == DS_PATTERN_SINE ? b + (1 - b) / 2 : duty + b * (1 - duty);
  DsImage *img = ds_image_new (DS_SAMPLE_F32, w, h, NULL);
  for (guint y = 0; y < h; y++) {
    float *row = ds_image_row (img, y);
    for (guint x = 0; x < w; x++)
      row[x] = (float) (ld_of_x[x] * pattern_at (kind, duty, b, period, offset, x) + lg * m);
  }
  return img;
}

static void
sine_params (DsSeparationParams *p, double period, double b)
{
  ds_separation_params_init (p, 8);
  p->estimator = DS_ESTIMATOR_SINE;
  p->pattern = DS_PATTERN_SINE;
  p->black_level = b;
  p->geometry.period_px = period;
}

static void
test_sine_closed_form (void)
{
  /* A period that is not a whole number of pixels: the fit is still exact. */
  const guint w = 97, h = 3;
  double ld[97];
  for (guint x = 0; x < w; x++)
    ld[x] = 40;
  g_autoptr (DsImage) frame = render_f32 (w, h, DS_PATTERN_SINE, 0.5, 0.1, 10.4, 0.3, ld, 100);
  DsSeparationParams p;
  sine_params (&p, 10.4, 0.1);
  g_autoptr (DsSeparation) sep = NULL;
  DsSingleFrameInfo info;
  g_autoptr (GError) error = NULL;
  g_assert_true (ds_single_frame_separate (frame, NULL, &p, &sep, &info, &error));
  g_assert_no_error (error);
  g_assert_cmpuint (info.window_px, ==, 11);
  g_assert_cmpfloat_with_epsilon (sep->meta.pattern_mean, 0.55, 1e-12);   /* b + (1 - b)/2 */
  g_assert_cmpfloat_with_epsilon (sep->meta.harmonic_gain, 0.45, 1e-12);  /* (1 - b)/2 */
  for (guint y = 0; y < h; y++) {
    const float *t = ds_image_row (sep->transmissive, y), *g = ds_image_row (sep->scattered, y);
    const guint8 *mk = ds_image_row (sep->mask, y);
    for (guint x = 0; x < w; x++) {
      g_assert_cmpfloat_with_epsilon (t[x], 40, 40 * 1e-4);
      g_assert_cmpfloat_with_epsilon (g[x], 100, 100 * 1e-4);
      g_assert_cmpuint (mk[x], ==, 0);
    }
  }
  g_assert_cmpuint (sep->meta.valid_pixels, ==, (guint64) w * h);
}

static void
test_maxmin_closed_form (void)
{
  /* Square stripes, P = 8, duty 1/2, black 0.05, offset off the pixel edges: every window of 8
   * columns holds 4 lit and 4 unlit samples. Ld 40, Lg 80: lit 40 + 80 m = 82, unlit
   * 0.05 * 40 + 42 = 44 DN with m = 0.5 + 0.05 * 0.5 = 0.525, both whole: a u16 frame is exact. */
  const guint w = 64, h = 2;
  g_autoptr (DsImage) frame = ds_image_new (DS_SAMPLE_U16, w, h, NULL);
  for (guint y = 0; y < h; y++) {
    guint16 *row = ds_image_row (frame, y);
    for (guint x = 0; x < w; x++)
      row[x] = pattern_at (DS_PATTERN_SQUARE, 0.5, 0.05, 8, 0.0625, x) > 0.5 ? 82 : 44;
  }
  DsSeparationParams p;
  ds_separation_params_init (&p, 8);
  p.estimator = DS_ESTIMATOR_MAXMIN;
  p.black_level = 0.05;
  p.geometry.period_px = 8;
  g_autoptr (DsSeparation) sep = NULL;
  g_autoptr (GError) error = NULL;
  g_assert_true (ds_single_frame_separate (frame, NULL, &p, &sep, NULL, &error));
  for (guint y = 0; y < h; y++) {
    const float *t = ds_image_row (sep->transmissive, y), *g = ds_image_row (sep->scattered, y);
    for (guint x = 0; x < w; x++) {
      g_assert_cmpfloat_with_epsilon (t[x], 40, 1e-4);
      g_assert_cmpfloat_with_epsilon (g[x], 80, 1e-4);
    }
  }
}

static void
test_sine_matches_phase_set (void)
{
  /* Sine stripes, P = N = 8 on a uniform scene: frame k of a set is frame 0 shifted by k
   * columns, so at pixel x the set sees the values of columns x - k of frame 0, the same
   * values the single-frame window of 8 columns fits. Rounded to u16 on both sides. */
  const guint w = 48, h = 2, n = 8;
  const double period = 8, b = 0.2, off = 0.17, ld = 500, lg = 1200;
  double m = b + (1 - b) / 2;
  DsSeparationParams p;
  sine_params (&p, period, b);
  p.n_phases = n;
  g_autoptr (DsPhaseSet) set = ds_phase_set_new (&p, w, h, NULL);
  g_autoptr (DsImage) first = NULL;
  for (guint k = 0; k < n; k++) {
    g_autoptr (DsImage) f = ds_image_new (DS_SAMPLE_U16, w, h, NULL);
    for (guint y = 0; y < h; y++) {
      guint16 *row = ds_image_row (f, y);
      for (guint x = 0; x < w; x++)
        row[x] = (guint16) lround (ld * pattern_at (DS_PATTERN_SINE, 0.5, b, period, off + (double) k / n, x) + lg * m);
    }
    g_assert_true (ds_phase_set_accumulate (set, k, f, NULL));
    if (k == 0)
      first = g_steal_pointer (&f);
  }
  g_autoptr (GError) error = NULL;
  g_autoptr (DsSeparation) temporal = ds_phase_set_finalize (set, &error);
  g_assert_no_error (error);
  g_autoptr (DsSeparation) spatial = NULL;
  g_assert_true (ds_single_frame_separate (first, NULL, &p, &spatial, NULL, &error));
  for (guint y = 0; y < h; y++) {
    const float *tt = ds_image_row (temporal->transmissive, y), *ts = ds_image_row (spatial->transmissive, y);
    const float *gt = ds_image_row (temporal->scattered, y), *gs = ds_image_row (spatial->scattered, y);
    /* The set's pixel x sees columns x .. x - 7 (wrapped within the period); the window of
     * a pixel away from the sides holds 8 consecutive columns: the same values whenever the
     * scene is uniform, so the two agree to float rounding at every pixel. */
    for (guint x = 0; x < w; x++) {
      g_assert_cmpfloat_with_epsilon (ts[x], tt[x], 1e-3 * ld);
      g_assert_cmpfloat_with_epsilon (gs[x], gt[x], 1e-3 * lg);
    }
  }
}

static void
test_resolution_cost (void)
{
  /* A step in Ld at column 60: the window (11 columns at P = 10.4) mixes both sides only
   * within half a window of the step; beyond it each side is exact. */
  const guint w = 120, step = 60;
  double ld[120];
  for (guint x = 0; x < w; x++)
    ld[x] = x < step ? 20 : 60;
  g_autoptr (DsImage) frame = render_f32 (w, 1, DS_PATTERN_SINE, 0.5, 0, 10.4, 0.1, ld, 50);
  DsSeparationParams p;
  sine_params (&p, 10.4, 0);
  g_autoptr (DsSeparation) sep = NULL;
  DsSingleFrameInfo info;
  g_assert_true (ds_single_frame_separate (frame, NULL, &p, &sep, &info, NULL));
  const float *t = ds_image_row (sep->transmissive, 0);
  guint mixed = 0;
  for (guint x = 0; x < w; x++) {
    gboolean window_holds_step = x + info.window_px / 2 >= step && x < step + info.window_px / 2 + 1;
    double expect = x < step ? 20 : 60;
    if (!window_holds_step)
      g_assert_cmpfloat_with_epsilon (t[x], expect, 1e-3 * expect);
    else if (fabs (t[x] - expect) > 1e-3 * expect)
      mixed++;
  }
  /* The cost is at most one window of columns. */
  g_assert_cmpuint (mixed, >, 0);
  g_assert_cmpuint (mixed, <=, info.window_px);
}

static void
test_saturation_flags_windows (void)
{
  /* One clipped sample at column 40 (P = 8, 8-column windows): the pixels whose window holds
   * it are the 8 with window start in [33, 40], pixels 37 .. 44; nothing else is flagged. */
  const guint w = 80;
  g_autoptr (DsImage) frame = ds_image_new (DS_SAMPLE_U16, w, 1, NULL);
  frame->bit_depth = 12;
  guint16 *row = ds_image_row (frame, 0);
  for (guint x = 0; x < w; x++)
    row[x] = (guint16) lround (1000 + 500 * cos (2 * G_PI * x / 8.0));
  row[40] = 4095;
  DsSeparationParams p;
  sine_params (&p, 8, 0);
  g_autoptr (DsSeparation) sep = NULL;
  g_assert_true (ds_single_frame_separate (frame, NULL, &p, &sep, NULL, NULL));
  const guint8 *mk = ds_image_row (sep->mask, 0);
  for (guint x = 0; x < w; x++)
    g_assert_cmpuint (!!(mk[x] & DS_MASK_SATURATED), ==, x >= 37 && x <= 44);
  g_assert_cmpuint (sep->meta.flagged[0], ==, 8);
}

static void
test_refusals (void)
{
  g_autoptr (DsImage) frame = ds_image_new (DS_SAMPLE_U16, 16, 2, NULL);
  DsSeparationParams p;
  struct {
    DsEstimator estimator;
    double period, black;
    gint code;
    const char *names;
  } cases[] = {
    { DS_ESTIMATOR_ROBUST, 8, 0, DS_PROC_ERROR_INVALID_ARGUMENT, "robust" },
    { DS_ESTIMATOR_SINE, 2.5, 0, DS_PROC_ERROR_INVALID_ARGUMENT, "period 2.5" },
    { DS_ESTIMATOR_MAXMIN, 2, 0, DS_PROC_ERROR_INVALID_ARGUMENT, "period 2" },
    { DS_ESTIMATOR_SINE, 20, 0, DS_PROC_ERROR_INVALID_ARGUMENT, "16 px wide" },
    { DS_ESTIMATOR_MAXMIN, 8, 0.999, DS_PROC_ERROR_ILL_CONDITIONED, "black level 0.999" },
  };
  for (guint i = 0; i < G_N_ELEMENTS (cases); i++) {
    ds_separation_params_init (&p, 8);
    p.estimator = cases[i].estimator;
    p.black_level = cases[i].black;
    p.geometry.period_px = cases[i].period;
    g_autoptr (DsSeparation) sep = NULL;
    g_autoptr (GError) error = NULL;
    g_assert_false (ds_single_frame_separate (frame, NULL, &p, &sep, NULL, &error));
    g_assert_error (error, DS_PROC_ERROR, cases[i].code);
    g_assert_nonnull (strstr (error->message, cases[i].names));
    g_assert_null (sep);
  }
  /* A dark frame of another shape. */
  g_autoptr (DsImage) dark = ds_image_new (DS_SAMPLE_U16, 15, 2, NULL);
  ds_separation_params_init (&p, 8);
  p.geometry.period_px = 8;
  g_autoptr (DsSeparation) sep = NULL;
  g_autoptr (GError) error = NULL;
  g_assert_false (ds_single_frame_separate (frame, dark, &p, &sep, NULL, &error));
  g_assert_error (error, DS_PROC_ERROR, DS_PROC_ERROR_SIZE_MISMATCH);
}

/* ---- The fast paths against a direct per-pixel reference ----
 * The reference fits each pixel's window on its own, in double: the absolute basis
 * cos/sin(2 pi x/P) of the window's columns, its 3x3 normal equations solved by Cramer's
 * rule, and max/min by scanning. No rotation, no doubling, no tiles: a different route to
 * the same numbers. */

static guint
ref_start (guint x, guint w, guint l)
{
  guint s = x >= l / 2 ? x - l / 2 : 0;
  return MIN (s, w - l);
}

static double
det3 (const double a[3][3])
{
  return a[0][0] * (a[1][1] * a[2][2] - a[1][2] * a[2][1]) - a[0][1] * (a[1][0] * a[2][2] - a[1][2] * a[2][0]) +
         a[0][2] * (a[1][0] * a[2][1] - a[1][1] * a[2][0]);
}

/* The window's fit (M, a, b) by Cramer's rule; also the largest row sum of |G^-1| (by solving
 * for the unit vectors), the factor from an error in the sums to one in (M, a, b). */
static void
ref_fit (const double *v, guint s, guint l, double period, double out[3], double *ginv_norm)
{
  double g[3][3] = { { 0 } }, t[3] = { 0 };
  for (guint j = s; j < s + l; j++) {
    double u = fmod ((double) j, period) / period;
    double basis[3] = { 1, cos (2 * G_PI * u), sin (2 * G_PI * u) };
    for (guint i = 0; i < 3; i++) {
      t[i] += v[j] * basis[i];
      for (guint k = 0; k < 3; k++)
        g[i][k] += basis[i] * basis[k];
    }
  }
  double d = det3 (g), norm = 0;
  for (guint col = 0; col < 3; col++) {
    double a[3][3];
    memcpy (a, g, sizeof a);
    for (guint i = 0; i < 3; i++)
      a[i][col] = t[i];
    out[col] = det3 (a) / d;
  }
  for (guint i = 0; i < 3; i++) {
    double row = 0;
    for (guint col = 0; col < 3; col++) {
      double a[3][3];
      memcpy (a, g, sizeof a);
      for (guint k = 0; k < 3; k++)
        a[k][col] = k == i;
      row += fabs (det3 (a) / d);
    }
    norm = fmax (norm, row);
  }
  *ginv_norm = norm;
}

/* Random u8 and u16 over the whole range (the largest sums, so the largest rounding), an
 * optional dark frame (without one, integer frames take the kernels on their own samples),
 * several widths against the tile and periods whose windows take every route through the
 * doubling (odd, two low bits, powers of two, one above) and both fits of the sine (integer
 * periods: an isotropic window). Every column is checked, the clamped windows at the sides
 * included. */
static void
fast_paths_match_reference (DsSampleType type)
{
  const double periods[] = { 3.0, 5.0, 7.3, 8.0, 13.7, 16.0, 16.2, 33.5 };
  const guint widths[] = { 40, 517, 1500 };
  guint64 state = 0x243F6A8885A308D3ull;
  for (guint wi = 0; wi < G_N_ELEMENTS (widths); wi++) {
    guint w = widths[wi], h = 3;
    g_autoptr (DsImage) frame = ds_image_new (type, w, h, NULL);
    g_autoptr (DsImage) dark = ds_image_new (type, w, h, NULL);
    for (guint y = 0; y < h; y++) {
      void *row = ds_image_row (frame, y), *drow = ds_image_row (dark, y);
      for (guint x = 0; x < w; x++) {
        state = state * 6364136223846793005ull + 1442695040888963407ull;
        if (type == DS_SAMPLE_U16) {
          ((guint16 *) row)[x] = (guint16) (state >> 48);
          ((guint16 *) drow)[x] = (guint16) ((state >> 20) & 255);
        } else {
          ((guint8 *) row)[x] = (guint8) (state >> 56);
          ((guint8 *) drow)[x] = (guint8) ((state >> 20) & 31);
        }
      }
    }
    for (guint pi = 0; pi < G_N_ELEMENTS (periods); pi++) {
      for (guint with_dark = 0; with_dark < 2; with_dark++) {
        for (DsEstimator e = DS_ESTIMATOR_MAXMIN; e <= DS_ESTIMATOR_SINE; e++) {
          double period = periods[pi];
          if (e == DS_ESTIMATOR_MAXMIN && period < 2.5)
            continue;
          guint l = (guint) ceil (period - 1e-9);
          if (w < l)
            continue;
          DsSeparationParams p;
          ds_separation_params_init (&p, 8);
          p.estimator = e;
          p.pattern = e == DS_ESTIMATOR_SINE ? DS_PATTERN_SINE : DS_PATTERN_SQUARE;
          p.black_level = 0.1;
          p.geometry.period_px = period;
          /* random data reaches full scale: count nothing saturated */
          p.saturation_level = type == DS_SAMPLE_U16 ? 65536 : 256;
          g_autoptr (DsSeparation) sep = NULL;
          g_autoptr (GError) error = NULL;
          g_assert_true (ds_single_frame_separate (frame, with_dark ? dark : NULL, &p, &sep, NULL, &error));
          g_assert_no_error (error);
          double m = p.pattern == DS_PATTERN_SINE ? 0.1 + 0.9 / 2 : 0.5 + 0.1 * 0.5;
          double hg = 0.9 / 2; /* sine stripes: h = (1 - b)/2 */
          g_assert_cmpfloat_with_epsilon (sep->meta.pattern_mean, m, 1e-12);
          guint64 unflagged = 0, negative = 0;
          for (guint y = 0; y < h; y++) {
            const void *in = ds_image_row (frame, y), *din = ds_image_row (dark, y);
            double v[1500];
            for (guint x = 0; x < w; x++)
              v[x] = ds_image_sample (frame, in, x) - (with_dark ? ds_image_sample (dark, din, x) : 0);
            const float *t = ds_image_row (sep->transmissive, y), *g = ds_image_row (sep->scattered, y);
            const guint8 *mk = ds_image_row (sep->mask, y);
            for (guint x = 0; x < w; x++) {
              /* nothing saturated, every sample finite: the one bit is the sign of Lg */
              g_assert_cmpuint (mk[x], ==, g[x] < 0 ? DS_MASK_NEGATIVE : 0);
              unflagged += mk[x] == 0;
              negative += mk[x] != 0;
              guint s = ref_start (x, w, l);
              double ld, lg, tol_ld, tol_lg;
              if (e == DS_ESTIMATOR_SINE) {
                double fit[3], norm;
                ref_fit (v, s, l, period, fit, &norm);
                ld = hypot (fit[1], fit[2]) / hg;
                lg = fit[0] / m - ld;
                /* the header's bound on the sums, 2 log2(l) float epsilons of the sum of
                 * the magnitudes, plus a few for the basis tables, the rotation and the
                 * fit; through G^-1 into (M, a, b) and on into Ld and Lg */
                double abs_sum = 0;
                for (guint j = s; j < s + l; j++)
                  abs_sum += fabs (v[j]);
                double dt = (2 * ceil (log2 (l)) + 8) * FLT_EPSILON * abs_sum;
                tol_ld = sqrt (2) * norm * dt / hg + 1e-6 * fabs (ld);
                tol_lg = norm * dt / m + tol_ld + 1e-6 * fabs (lg);
              } else {
                double mx = v[s], mn = v[s];
                for (guint j = s; j < s + l; j++) {
                  mx = fmax (mx, v[j]);
                  mn = fmin (mn, v[j]);
                }
                ld = (mx - mn) / (1 - 0.1);
                lg = (mn - 0.1 * ld) / m;
                /* the extremes are exact; two float operations each */
                tol_ld = 4 * FLT_EPSILON * (fabs (ld) + 1);
                tol_lg = 8 * FLT_EPSILON * (fabs (lg) + fabs (ld) + fabs (mn) + 1);
              }
              if (fabs (t[x] - ld) > tol_ld || fabs (g[x] - lg) > tol_lg)
                g_error ("%s %s P %g width %u dark %u pixel (%u, %u): Ld %.9g want %.9g (+-%.3g), Lg %.9g want %.9g "
                         "(+-%.3g)",
                         ds_sample_type_name (type), ds_estimator_name (e), period, w, with_dark, x, y, t[x], ld,
                         tol_ld, g[x], lg, tol_lg);
            }
          }
          /* the counts in meta are the mask's */
          g_assert_cmpuint (sep->meta.valid_pixels, ==, unflagged);
          g_assert_cmpuint (sep->meta.flagged[g_bit_nth_lsf (DS_MASK_NEGATIVE, -1)], ==, negative);
        }
      }
    }
  }
}

static void
test_fast_paths_match_reference_u16 (void)
{
  fast_paths_match_reference (DS_SAMPLE_U16);
}

static void
test_fast_paths_match_reference_u8 (void)
{
  fast_paths_match_reference (DS_SAMPLE_U8);
}

/* Rows shared by several threads give the bits one thread gives (every row is computed
 * alone), and a plan reused for a second frame into the same planes gives the bits of a
 * fresh call. */
static void
test_threads_and_reuse (void)
{
  const guint w = 640, h = 300; /* above DS_SINGLE_FRAME_THREADED_PIXELS */
  g_assert_cmpuint (w * h, >=, DS_SINGLE_FRAME_THREADED_PIXELS);
  g_autoptr (DsImage) a = ds_image_new (DS_SAMPLE_U16, w, h, NULL);
  g_autoptr (DsImage) b = ds_image_new (DS_SAMPLE_U16, w, h, NULL);
  guint64 state = 7;
  for (guint y = 0; y < h; y++) {
    guint16 *ra = ds_image_row (a, y), *rb = ds_image_row (b, y);
    for (guint x = 0; x < w; x++) {
      state = state * 6364136223846793005ull + 1442695040888963407ull;
      ra[x] = (guint16) (state >> 52);
      rb[x] = (guint16) (state >> 40);
    }
  }
  for (DsEstimator e = DS_ESTIMATOR_MAXMIN; e <= DS_ESTIMATOR_SINE; e++) {
    DsSeparationParams p;
    ds_separation_params_init (&p, 8);
    p.estimator = e;
    p.geometry.period_px = 11.5;
    p.saturation_level = 4095; /* 12-bit data touches it: some windows are flagged */
    p.threads = 1;
    g_autoptr (DsSeparation) one = NULL;
    g_assert_true (ds_single_frame_separate (b, NULL, &p, &one, NULL, NULL));
    g_assert_cmpuint (one->meta.flagged[0], >, 0);
    p.threads = 3;
    g_autoptr (GError) error = NULL;
    g_autoptr (DsSingleFrame) sf = ds_single_frame_new (&p, w, h, &error);
    g_assert_no_error (error);
    g_autoptr (DsSeparation) pooled = ds_separation_new ();
    g_assert_true (ds_single_frame_separate_into (sf, a, NULL, pooled, NULL));
    const guint8 *planes[2] = { pooled->transmissive->data, pooled->scattered->data };
    g_assert_true (ds_single_frame_separate_into (sf, b, NULL, pooled, NULL));
    g_assert_true (pooled->transmissive->data == planes[0]); /* written in place */
    g_assert_true (pooled->scattered->data == planes[1]);
    for (guint y = 0; y < h; y++) {
      g_assert_cmpmem (ds_image_row (pooled->transmissive, y), w * 4, ds_image_row (one->transmissive, y), w * 4);
      g_assert_cmpmem (ds_image_row (pooled->scattered, y), w * 4, ds_image_row (one->scattered, y), w * 4);
      g_assert_cmpmem (ds_image_row (pooled->mask, y), w, ds_image_row (one->mask, y), w);
    }
    g_assert_cmpmem (&pooled->meta, sizeof pooled->meta, &one->meta, sizeof one->meta);
    /* a frame of another size is refused by the plan */
    g_autoptr (DsImage) other = ds_image_new (DS_SAMPLE_U16, w - 1, h, NULL);
    g_assert_false (ds_single_frame_separate_into (sf, other, NULL, pooled, &error));
    g_assert_error (error, DS_PROC_ERROR, DS_PROC_ERROR_INVALID_ARGUMENT);
  }
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  g_test_add_func ("/single-frame/sine/closed-form", test_sine_closed_form);
  g_test_add_func ("/single-frame/maxmin/closed-form", test_maxmin_closed_form);
  g_test_add_func ("/single-frame/sine/matches-phase-set", test_sine_matches_phase_set);
  g_test_add_func ("/single-frame/resolution-cost", test_resolution_cost);
  g_test_add_func ("/single-frame/saturation-flags-windows", test_saturation_flags_windows);
  g_test_add_func ("/single-frame/refusals", test_refusals);
  g_test_add_func ("/single-frame/fast-paths-match-reference/u16", test_fast_paths_match_reference_u16);
  g_test_add_func ("/single-frame/fast-paths-match-reference/u8", test_fast_paths_match_reference_u8);
  g_test_add_func ("/single-frame/threads-and-reuse", test_threads_and_reuse);
  return g_test_run ();
}
