/* Stripes in the pilot frames of an automatic capture (daemon/operating/pilot_stripes.h), on
 * frames written here in closed form: square stripes of period 16 px over a scene with its own
 * detail pass, with heavy scattered light (a modulation of 2 %) and noise too; flat frames with
 * noise, the same stripes at a period other than the configured one, and a noise-free picture
 * whose first harmonic is under 1e-4 of its mean (what Aravis's fake camera shows) are refused with
 * `failed` and the reason. */
#include <glib.h>
#include <math.h>
#include <string.h>

#include "daemon/operating/pilot_stripes.h"
#include "daemon/operating/operating_error.h"
#include "tests/common/test_random.h"

#define W 320u
#define H 96u
#define P 16.0

typedef struct {
  double period, stripes, scattered, noise, ripple; /* ripple: a noise-free cosine at P, DN */
} Scene;

/* phase: 0 or 0.5 of a period; lit FALSE: the dark frame. */
static DsImage *
frame (const Scene *s, double phase, gboolean lit, GRand *r)
{
  DsImage *img = ds_image_new (DS_SAMPLE_U16, W, H, NULL);
  for (guint y = 0; y < H; y++) {
    guint16 *row = ds_image_row (img, y);
    for (guint x = 0; x < W; x++) {
      double object = 0.6 + 0.4 * (((x / 23) + (y / 17)) % 2); /* the scene's own detail */
      double u = (x + 0.5) / s->period - phase;
      double v = 100;
      if (lit)
        v += object * (s->stripes * (u - floor (u) < 0.5) + s->scattered) +
             s->ripple * cos (2 * G_PI * ((x + 0.5) / P - phase));
      v += s->noise * test_normal (r);
      row[x] = (guint16) CLAMP (lround (v), 0, 65535);
    }
  }
  return img;
}

static gboolean
check_clip (const Scene *s, double saturation_dn, DsPilotStripes *out, GError **error)
{
  GRand *r = g_rand_new_with_seed (5);
  g_autoptr (DsImage) dark = frame (s, 0, FALSE, r);
  g_autoptr (DsImage) l0 = frame (s, 0, TRUE, r);
  g_autoptr (DsImage) l1 = frame (s, 0.5, TRUE, r);
  g_rand_free (r);
  DsProbeFrames f = { .dark = dark, .lit = { l0, l1 }, .exposure_us = 1000, .saturation_dn = saturation_dn,
                      .geometry = { .kind = DS_PATTERN_SQUARE, .period_px = P, .duty = 0.5 } };
  return ds_pilot_stripes_check (&f, out, error);
}

static gboolean
check (const Scene *s, DsPilotStripes *out, GError **error)
{
  return check_clip (s, 65535, out, error);
}

static void
test_stripes_pass (void)
{
  const Scene cases[] = {
    { P, 1000, 0, 5, 0 },     /* clear */
    { P, 100, 5000, 30, 0 },  /* scattered light 50 x the stripes: 1 % modulation, noisy */
  };
  for (guint i = 0; i < G_N_ELEMENTS (cases); i++) {
    g_autoptr (GError) error = NULL;
    DsPilotStripes st;
    g_assert_true (check (&cases[i], &st, &error));
    g_assert_no_error (error);
    /* the difference's first harmonic of a square of duty 0.5: 2 x (2 / pi) x the stripes x the
     * object's mean (0.8) */
    double want = 2 * 2 / G_PI * cases[i].stripes * 0.8;
    g_assert_cmpfloat (fabs (st.amplitude / want - 1), <, 0.05);
  }
}

static void
assert_refused (const Scene *s, const char *what)
{
  g_autoptr (GError) error = NULL;
  DsPilotStripes st;
  g_assert_false (check (s, &st, &error));
  g_assert_error (error, DS_OPERATING_ERROR, DS_OPERATING_ERROR_NO_STRIPES);
  g_test_message ("%s: %s", what, error->message);
  g_assert_nonnull (strstr (error->message, "no stripes at the configured period 16 px"));
  g_assert_nonnull (strstr (error->message, "standard errors of the noise"));
}

static void
test_no_stripes_refused (void)
{
  const Scene flat = { P, 0, 2000, 10, 0 };
  assert_refused (&flat, "flat");
  /* stripes of 23 px where 16 are configured: 13.8 periods leave a harmonic at 16 px of
   * under 1 % of theirs, which the noise hides */
  const Scene other = { 23, 1000, 0, 200, 0 };
  assert_refused (&other, "another period");
  /* noise-free, a first harmonic under 1e-4 of the mean: "significant", but no light to separate */
  const Scene ripple = { P, 0, 20000, 0, 0.05 * 20000 / 1000 };
  assert_refused (&ripple, "noise-free ripple");
}

/* Square stripes of duty 1/2: every pixel is lit in one of the two phases. Lit, it holds
 * 100 + object (stripes + scattered) DN with the object's 0.6 to 1: 100 + 0.6 x 1500 = 1000 at
 * the least, at or above a clip level of 1000 DN, so every pixel of the pair clips in one frame
 * and no column keeps a sample. At 1601 DN nothing clips and the stripes pass. */
static void
test_clipped_refused (void)
{
  const Scene bright = { P, 1000, 500, 0, 0 };
  g_autoptr (GError) error = NULL;
  DsPilotStripes st;
  g_assert_false (check_clip (&bright, 1000, &st, &error));
  g_assert_error (error, DS_OPERATING_ERROR, DS_OPERATING_ERROR_CLIPPED);
  g_test_message ("%s", error->message);
  g_assert_nonnull (strstr (error->message, "100 % of the pixels are at the clip level (1000 DN)"));
  g_assert_nonnull (strstr (error->message, "lower the exposure or the gain"));
  g_autoptr (GError) partial = NULL;
  g_assert_true (check_clip (&bright, 1601, &st, &partial));
  g_assert_no_error (partial);
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  g_test_add_func ("/pilot-stripes/stripes-pass", test_stripes_pass);
  g_test_add_func ("/pilot-stripes/no-stripes-refused", test_no_stripes_refused);
  g_test_add_func ("/pilot-stripes/clipped-refused", test_clipped_refused);
  return g_test_run ();
}
