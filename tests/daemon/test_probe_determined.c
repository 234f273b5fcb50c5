/* The narrow kernel term is taken, where the harmonics do not over-determine it, only if it passes
 * through them (issue 12: gen-17-02; daemon/operating/scene_probe_determined.h). Pilot frames in closed form: sine stripes
 * of period Q, a Gaussian blur and the whole pixel's integration, the direct light Ld, scattered
 * light S that keeps no stripes (an isotropic medium's kernel, many periods wide) and, at each
 * pilot period, a kernel whose MTF at 1 / Q is given: the share e_Q of Ld that scattered light
 * keeps modulated there, in phase with the stripes. The truth the probe must find is e_P at P and
 * Ld; the renderer's Monte Carlo kernel of gen-17-02 keeps 1.3 to 4.3 % of its scattered light at
 * the pilot's periods (`descatter-sim describe` with period-px changed), 0.7 to 2.3 % of Ld, with
 * signs of their own, which is what e_Q is here. */
#include <math.h>
#include <string.h>

#include "daemon/operating/scene_probe.h"
#include "daemon/operating/scene_probe_determined.h"
#include "pilot_pairs.h"

#define W 256
#define H 192

typedef struct {
  double period, blur;       /* px */
  double ld, lg, dark;       /* DN */
  double kept[4];            /* e_Q at P/4, P/2, P and 2P: a share of Ld */
  double beta, kernel_px;    /* or a Gaussian kernel holding beta Ld (0: none) */
} Scene;

/* e_Q, from the list or the Gaussian kernel. */
static double
kept_at (const Scene *s, double q)
{
  if (s->beta > 0) {
    double k = G_PI / q;
    return s->beta * exp (-2 * k * k * s->kernel_px * s->kernel_px);
  }
  static const double ratio[4] = { 0.25, 0.5, 1, 2 };
  for (guint i = 0; i < 4; i++)
    if (fabs (q - s->period * ratio[i]) < 0.02 * q)
      return s->kept[i];
  g_assert_not_reached ();
}

static DsImage *
frame (const Scene *s, double q, double shift, gboolean on, GRand *r)
{
  DsImage *f = ds_image_new (DS_SAMPLE_F32, W, H, NULL);
  double k = G_PI / q;
  double gain = exp (-2 * k * k * s->blur * s->blur) * sin (k) / k; /* blur, then the pixel */
  double mean = (s->ld + s->lg) / 2, amp = s->ld / 2 * gain * (1 + kept_at (s, q));
  for (guint y = 0; y < H; y++) {
    float *row = ds_image_row (f, y);
    for (guint x = 0; x < W; x++) {
      double v = on ? mean + amp * cos (2 * G_PI * (x / q - shift)) : 0, sd = sqrt (4.0 + 0.25 * v);
      double u1 = 1 - g_rand_double (r), u2 = g_rand_double (r);
      row[x] = (float) (s->dark + v + sd * sqrt (-2 * log (u1)) * cos (2 * G_PI * u2));
    }
  }
  return f;
}

static DsImage *
pilot_frame (gconstpointer s, double q, double shift, gboolean on, GRand *r)
{
  return frame (s, q, shift, on, r);
}

/* Probes the scene from pairs at P, 2P and the finer periods the blur resolves. */
static void
probe (const Scene *s, DsSceneProbe *p)
{
  DsProbeFrames base = { .exposure_us = 1000, .finer_missing = "fixed by the test",
                         .geometry = { DS_PATTERN_SINE, s->period, 0.5, 0, 0 },
                         .blur_known = TRUE, .calibrated_blur_px = s->blur };
  guint nq = pilot_pairs_probe (pilot_frame, s, &base, s->blur, 17, p);
  g_assert_cmpuint (nq, ==, 2); /* the test is about four periods */
}

/* Probes the scene and says what it read against the truth; the leak at P read, *truth the kernel's. */
static double
probe_reported (const Scene *s, const char *what, DsSceneProbe *p, double *truth)
{
  probe (s, p);
  *truth = kept_at (s, s->period);
  double leak = ds_scene_probe_leak (p, s->period, 1);
  g_test_message ("%s, sine at four periods: leak at P %.4f (truth %.4f), Ld %.1f (truth %.1f), narrow kernel %.3f "
                  "of Ld, unresolved %d; %s",
                  what, leak, *truth, p->light.ld_mean, s->ld, p->narrow.fraction, p->narrow.unresolved, p->narrow.note);
  return leak;
}

/* gen-17-02 in closed form (no objects): P = 19.25 px, blur 0.9 px, Ld 2368 DN and S 1292 DN as the
 * renderer's truth of the scene without its objects, and the kernel's modulation as the probe read it
 * there over the truth's Ld (A / G 2341, 2303, 2418, 2392 DN at P/4, P/2, P, 2P against 2368, the
 * first corrected by the 1.6 % the same pilot reads low at P/4 without the medium): +0.5, -2.7, +2.1
 * and +1.0 %. Before the rule the probe read a narrow kernel of 1.4 px holding 15 % of Ld: Ld 2119,
 * the leak at P 12 %, missing the four harmonics by about 1 % RMS. Now the leak at P is the
 * kernel's within 2 % of Ld, Ld within 3 %, and the note says why no narrow kernel was taken. */
static void
test_isotropic_sine (void)
{
  const Scene s = { .period = 19.25, .blur = 0.9, .ld = 2368, .lg = 1292, .dark = 30,
                    .kept = { 0.005, -0.027, 0.021, 0.010 } };
  DsSceneProbe p;
  double truth, leak = probe_reported (&s, "isotropic", &p, &truth);
  g_assert_cmpfloat (fabs (leak - truth), <, 0.02);
  g_assert_cmpfloat (fabs (p.light.ld_mean - s.ld), <, 0.03 * s.ld);
  g_assert_cmpfloat (p.narrow.fraction, ==, 0);
  g_assert_nonnull (strstr (p.narrow.note, "narrow kernel not taken"));
}

/* A narrow kernel that is there, on sine stripes: a Gaussian of 1.5 px holding 25 % of Ld at P =
 * 24 px (test_probe_narrow.c's case on square stripes, where it is fitted) keeps 23.1 % of Ld at P.
 * Its search on four first harmonics finds a kernel keeping more than a quarter of Ld modulated
 * at the finest period (narrower than the pilot resolves), and that still makes the prediction a
 * lower bound whatever the rule says of the term: Ld is no higher than the modulation at P says
 * (the kernel's light taken for direct at most), the leak at P under the truth, and the
 * prediction flagged. */
static void
test_narrow_sine (void)
{
  const Scene s = { .period = 24, .blur = 0.5, .ld = 1500, .lg = 675, .dark = 30, .beta = 0.25, .kernel_px = 1.5 };
  DsSceneProbe p;
  double truth, leak = probe_reported (&s, "narrower than resolved", &p, &truth);
  g_assert_cmpfloat (p.light.ld_mean, <, s.ld * (1 + truth) * 1.01);
  g_assert_cmpfloat (leak, <, truth);
  g_assert_true (p.narrow.unresolved);
  g_assert_nonnull (strstr (p.narrow.note, "narrower than the periods show"));
}

/* A narrow kernel the four first harmonics show as a kernel does, rising with the period (gen-10-03's
 * kind: a Gaussian of 2 px holding 6.5 % of Ld at P = 23.25 px keeps 5.6 % of Ld at P): the term
 * passes through them and is taken, its leak at P within 35 % of the kernel's (test_probe_narrow.c:
 * the probe's form is not a Gaussian), Ld within 3 %. */
static void
test_kernel_sine (void)
{
  const Scene s = { .period = 23.25, .blur = 1.0, .ld = 4100, .lg = 300, .dark = 30, .beta = 0.065, .kernel_px = 2 };
  DsSceneProbe p;
  double truth, leak = probe_reported (&s, "kernel", &p, &truth);
  g_assert_cmpfloat (p.narrow.fraction, >, 0);
  g_assert_cmpfloat (fabs (leak - truth), <, 0.35 * truth);
  g_assert_cmpfloat (fabs (p.light.ld_mean - s.ld), <, 0.03 * s.ld);
}

/* Distinct points: harmonics at the same x = Q / n count once; a term on as many points as its
 * parameters is taken only within DS_PROBE_NARROW_PASS_RMS of them, one on more points always. The
 * weighted RMS is the relative residual a chi2 over equally weighted equations stands for. */
static void
test_measured (void)
{
  DsProbeEquation eq[] = {
    { .period = 24, .n = 1, .amplitude = 1000, .sigma = 1 }, { .period = 48, .n = 1, .amplitude = 1000, .sigma = 1 },
    { .period = 12, .n = 1, .amplitude = 1000, .sigma = 1 }, { .period = 6, .n = 1, .amplitude = 1000, .sigma = 1 },
    { .period = 72, .n = 3, .amplitude = 1000, .sigma = 1 }, /* x = 24 again */
  };
  g_assert_cmpuint (ds_probe_distinct_points (eq, 5), ==, 4);
  /* Five equations each 1 % off: chi2 = 5 (0.01)^2 / (0.001^2 + 0.02^2). */
  double w = 1 / (1e-6 + DS_PROBE_TRANSFER_FLOOR * DS_PROBE_TRANSFER_FLOOR);
  g_assert_cmpfloat_with_epsilon (ds_probe_residual_rms (eq, 5, 5 * 1e-4 * w), 0.01, 1e-9);
  g_assert_false (ds_probe_narrow_measured (eq, 5, 5 * 1e-4 * w, NULL, 0));
  /* 0.4 % off: within half the objects' 1 %. */
  g_assert_true (ds_probe_narrow_measured (eq, 5, 5 * 0.16e-4 * w, NULL, 0));
  eq[4].period = 120; /* x = 40: five points, one degree of freedom */
  g_assert_cmpuint (ds_probe_distinct_points (eq, 5), ==, 5);
  g_assert_true (ds_probe_narrow_measured (eq, 5, 5 * 1e-4 * w, NULL, 0));
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  g_test_add_func ("/probe-determined/isotropic-sine", test_isotropic_sine);
  g_test_add_func ("/probe-determined/narrow-sine", test_narrow_sine);
  g_test_add_func ("/probe-determined/kernel-sine", test_kernel_sine);
  g_test_add_func ("/probe-determined/measured", test_measured);
  return g_test_run ();
}
