/* proc/stripe_profile.h against a reference written here another way: the threshold by
 * counting ranks instead of sorting, the local means by summing each box pixel by pixel
 * instead of integral images, the position in the period by fmod, and the bins by collecting
 * each bin's pixels before averaging. Frames are float, with clipped, NaN and infinite samples,
 * a dark frame that varies, and an object; and on plain sharp stripes the profile is what
 * the pattern says: r = 1 where phase 0 alone is lit, 0 where phase 1/2 alone is. */
#include <glib.h>
#include <math.h>
#include <string.h>

#include "proc/proc_error.h"
#include "proc/stripe_profile.h"

#define W 72
#define H 24

typedef struct {
  double period, offset, duty, black;
  gboolean texture, defects;
} Pattern;

/* phase k of 2: lit where frac (x / P - offset - k / 2) is within duty / 2 of 0 */
static double
lit (const Pattern *p, double x, guint k)
{
  double v = x / p->period - p->offset - 0.5 * k;
  v -= floor (v);
  return MIN (v, 1 - v) < 0.5 * p->duty ? 1.0 : p->black;
}

static DsImage *
frame (const Pattern *p, int k /* -1: dark */)
{
  DsImage *img = ds_image_new (DS_SAMPLE_F32, W, H, NULL);
  for (guint y = 0; y < H; y++) {
    float *row = ds_image_row (img, y);
    for (guint x = 0; x < W; x++) {
      double dark = 20 + 0.1 * x + 0.3 * y;
      double object = p->texture ? 0.3 + 0.7 * (((x / 9) + (y / 5)) % 3) / 2.0 : 1.0;
      double scattered = p->texture ? 40 : 0;
      row[x] = (float) (k < 0 ? dark : dark + 1000 * object * lit (p, x, (guint) k) + scattered);
    }
  }
  if (p->defects && k >= 0) {
    float *row = ds_image_row (img, 3);
    row[5] = 5000;       /* clipped */
    row[6] = NAN;
    row[7] = INFINITY;
    row = ds_image_row (img, 10);
    for (guint x = 0; x < 4; x++)
      row[x] = 0;         /* far below the threshold */
  }
  return img;
}

static double
px (const DsImage *img, guint x, guint y)
{
  return ((const float *) ds_image_row (img, y))[x];
}

typedef struct {
  double r[64], u[64], t[64];
  guint64 n[64], nt[64], pixels;
  double threshold;
} Reference;

static void
reference (const DsImage *d, const DsImage *a, const DsImage *b, double period, double offset, double clip,
           guint bins, Reference *ref, double *sum)
{
  memset (ref, 0, sizeof *ref);
  guint usable = 0;
  for (guint y = 0; y < H; y++)
    for (guint x = 0; x < W; x++) {
      double l0 = px (a, x, y), l1 = px (b, x, y), dk = px (d, x, y);
      gboolean ok = isfinite (l0) && isfinite (l1) && isfinite (dk) && l0 < clip && l1 < clip;
      sum[y * W + x] = ok ? l0 + l1 - 2 * dk : NAN;
      usable += ok;
    }
  if (usable < 64)
    return;
  /* the value of rank floor (0.9 (n - 1)) among the usable sums, by counting */
  guint rank = (guint) (0.9 * (usable - 1));
  double q = NAN;
  for (guint i = 0; i < W * H && isnan (q); i++) {
    if (isnan (sum[i]))
      continue;
    guint below = 0, equal = 0;
    for (guint j = 0; j < W * H; j++)
      if (!isnan (sum[j])) {
        below += sum[j] < sum[i];
        equal += sum[j] == sum[i];
      }
    if (below <= rank && rank < below + equal)
      q = sum[i];
  }
  ref->threshold = 0.25 * q;
  int radius = (int) MAX (4.0, ceil (period));
  double rs[64] = { 0 }, us[64] = { 0 }, ts[64] = { 0 };
  for (int y = 0; y < H; y++)
    for (int x = 0; x < W; x++) {
      double s = sum[y * W + x];
      double box = 0;
      guint count = 0;
      for (int yy = y - radius; yy <= y + radius; yy++)
        for (int xx = x - radius; xx <= x + radius; xx++)
          if (yy >= 0 && yy < H && xx >= 0 && xx < W && !isnan (sum[yy * W + xx])) {
            box += sum[yy * W + xx];
            count++;
          }
      double u = fmod (x / period - offset, 1.0);
      if (u < 0)
        u += 1.0;
      guint j = (guint) floor (u * bins);
      if (j >= bins)
        j = bins - 1;
      if (!isnan (s) && count > 0 && box / count > ref->threshold) {
        ts[j] += s / (box / count);
        ref->nt[j]++;
      }
      if (!isnan (s) && s > ref->threshold) {
        rs[j] += (px (a, x, y) - px (d, x, y)) / s;
        us[j] += u;
        ref->n[j]++;
        ref->pixels++;
      }
    }
  for (guint j = 0; j < bins; j++) {
    ref->r[j] = ref->n[j] ? rs[j] / ref->n[j] : 0;
    ref->u[j] = ref->n[j] ? us[j] / ref->n[j] : (j + 0.5) / bins;
    ref->t[j] = ref->nt[j] ? ts[j] / ref->nt[j] : 0;
  }
}

static void
assert_close (double got, double want, const char *what, guint j)
{
  if (fabs (got - want) > 1e-9 * MAX (1.0, fabs (want)))
    g_error ("%s[%u]: %.12g, reference %.12g", what, j, got, want);
}

static void
test_against_reference (void)
{
  const Pattern cases[] = {
    { .period = 7.3, .offset = 0.21, .duty = 0.5, .black = 0.05, .texture = TRUE, .defects = TRUE },
    { .period = 12, .offset = 0.9, .duty = 0.35, .black = 0.0, .texture = TRUE, .defects = FALSE },
    { .period = 4.5, .offset = 0.0, .duty = 0.6, .black = 0.2, .texture = FALSE, .defects = TRUE },
  };
  const guint bins_list[] = { 40, 17, 8 };
  for (guint c = 0; c < G_N_ELEMENTS (cases); c++) {
    const Pattern *p = &cases[c];
    g_autoptr (DsImage) d = frame (p, -1);
    g_autoptr (DsImage) a = frame (p, 0);
    g_autoptr (DsImage) b = frame (p, 1);
    guint bins = bins_list[c];
    double clip = 4000;
    g_autoptr (GError) error = NULL;
    g_autoptr (DsStripeProfile) prof = ds_stripe_profile_bin (d, a, b, p->period, p->offset, clip, bins, &error);
    g_assert_no_error (error);
    Reference ref;
    double sum[W * H];
    reference (d, a, b, p->period, p->offset, clip, bins, &ref, sum);
    g_test_message ("period %g: %" G_GUINT64_FORMAT " pixels in %u bins, threshold %g", p->period, prof->pixels,
                    prof->bins_used, prof->threshold);
    g_assert_cmpuint (prof->n_bins, ==, bins);
    g_assert_cmpuint (prof->pixels, ==, ref.pixels);
    g_assert_cmpuint (prof->pixels, >, W * H / 3);
    assert_close (prof->threshold, ref.threshold, "threshold", 0);
    guint used = 0;
    for (guint j = 0; j < bins; j++) {
      g_assert_cmpuint (prof->n[j], ==, ref.n[j]);
      g_assert_cmpuint (prof->nt[j], ==, ref.nt[j]);
      assert_close (prof->r[j], ref.r[j], "r", j);
      assert_close (prof->u[j], ref.u[j], "u", j);
      assert_close (prof->t[j], ref.t[j], "t", j);
      used += ref.n[j] || ref.nt[j];
    }
    g_assert_cmpuint (prof->bins_used, ==, used);
    for (guint i = 0; i < W * H; i++)
      g_assert_true ((isnan (prof->sum[i]) && isnan (sum[i])) || prof->sum[i] == sum[i]);

    /* The stripe centres: brightness is the sum; off is the dark phase over the lit one where one
     * phase's centre is within a quarter of min (a, 1 - a) of a period. */
    g_autofree double *bright = g_new (double, W * H), *off = g_new (double, W * H);
    ds_stripe_profile_centres (prof, d, a, b, p->duty, bright, off);
    double window = 0.25 * MIN (p->duty, 1 - p->duty);
    for (guint y = 0; y < H; y++)
      for (guint x = 0; x < W; x++) {
        guint i = y * W + x;
        g_assert_true ((isnan (bright[i]) && isnan (sum[i])) || bright[i] == sum[i]);
        double u = fmod (x / p->period - p->offset, 1.0);
        u += u < 0;
        double from0 = MIN (u, 1 - u), from1 = fabs (u - 0.5);
        double want = NAN;
        if (!isnan (sum[i]) && sum[i] > ref.threshold && (from0 < window || from1 < window)) {
          gboolean zero = from0 < window;
          double lit_v = (zero ? px (a, x, y) : px (b, x, y)) - px (d, x, y);
          double off_v = (zero ? px (b, x, y) : px (a, x, y)) - px (d, x, y);
          want = lit_v > 0 ? off_v / lit_v : NAN;
        }
        if (isnan (want))
          g_assert_true (isnan (off[i]));
        else
          assert_close (off[i], want, "off", i);
      }
  }
}

/* Sharp stripes of duty 1/2, no black level, nothing scattered: r is 1 in the bins where phase 0
 * alone is lit and 0 where phase 1/2 alone is; the sum is the same everywhere, so t is 1; and
 * at the stripe centres the off-stripe fraction is 0. */
static void
test_pattern_itself (void)
{
  Pattern p = { .period = 16, .offset = 0.1, .duty = 0.5, .black = 0 };
  g_autoptr (DsImage) d = frame (&p, -1);
  g_autoptr (DsImage) a = frame (&p, 0);
  g_autoptr (DsImage) b = frame (&p, 1);
  g_autoptr (DsStripeProfile) prof = ds_stripe_profile_bin (d, a, b, p.period, p.offset, 0, 16, NULL);
  g_assert_nonnull (prof);
  g_assert_cmpuint (prof->pixels, ==, W * H);
  for (guint j = 0; j < 16; j++) {
    double centre = (j + 0.5) / 16;
    double from0 = MIN (centre, 1 - centre);
    if (prof->n[j] == 0)
      continue;
    g_assert_cmpfloat (fabs (prof->t[j] - 1), <, 1e-9);
    if (from0 < 0.2)
      g_assert_cmpfloat (fabs (prof->r[j] - 1), <, 1e-9);
    else if (from0 > 0.3)
      g_assert_cmpfloat (fabs (prof->r[j]), <, 1e-9);
  }
  g_autofree double *bright = g_new (double, W * H), *off = g_new (double, W * H);
  ds_stripe_profile_centres (prof, d, a, b, 0.5, bright, off);
  guint centres = 0;
  for (guint i = 0; i < W * H; i++)
    if (!isnan (off[i])) {
      g_assert_cmpfloat (fabs (off[i]), <, 1e-9);
      centres++;
    }
  g_assert_cmpuint (centres, >, W * H / 4);
  /* and the offset is found where it was put */
  double offset;
  g_assert_true (ds_stripe_profile_offset (a, b, p.period, &offset));
  g_assert_cmpfloat (fabs (remainder (offset - p.offset, 1.0)), <, 0.02);
}

static void
test_bad_input (void)
{
  Pattern p = { .period = 8, .duty = 0.5 };
  g_autoptr (DsImage) d = frame (&p, -1);
  g_autoptr (DsImage) a = frame (&p, 0);
  g_autoptr (DsImage) small = ds_image_new (DS_SAMPLE_F32, W / 2, H, NULL);
  g_autoptr (GError) error = NULL;
  g_assert_null (ds_stripe_profile_bin (d, a, small, 8, 0, 0, 40, &error));
  g_assert_error (error, DS_PROC_ERROR, DS_PROC_ERROR_INVALID_ARGUMENT);
  g_clear_error (&error);
  g_assert_null (ds_stripe_profile_bin (d, a, a, 0, 0, 0, 40, &error));
  g_assert_error (error, DS_PROC_ERROR, DS_PROC_ERROR_INVALID_ARGUMENT);
  g_clear_error (&error);
  /* every sample clipped: a profile without pixels, not an error */
  g_autoptr (DsStripeProfile) none = ds_stripe_profile_bin (d, a, a, 8, 0, 1, 40, &error);
  g_assert_no_error (error);
  g_assert_cmpuint (none->pixels, ==, 0);
  g_assert_cmpfloat (none->threshold, ==, 0);
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  g_test_add_func ("/stripe-profile/against-reference", test_against_reference);
  g_test_add_func ("/stripe-profile/pattern-itself", test_pattern_itself);
  g_test_add_func ("/stripe-profile/bad-input", test_bad_input);
  return g_test_run ();
}
