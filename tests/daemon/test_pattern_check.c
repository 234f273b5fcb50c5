/* The pilot frames' pattern check (daemon/operating/pattern_check.h) against closed-form frames
 * written here independently of the stripe model: square stripes of duty a and black level b
 * blurred by a Gaussian and integrated over the pixel (sampled at 16 points with erf), an object
 * of bars and discs, vignetting, scattered light made of a part that keeps the stripes (a
 * narrow blur of the lit light, or a kernel with long tails) and a part that does not (a wide
 * one), shot and read noise.
 *
 * No false alarm: every combination of duty, black level, blur, noise and scattering with the
 * right configuration gives MATCHES (a scattering scene's extra off-stripe light is scattered
 * light, as its dim parts show). Alarms: a duty 0.5 configured on stripes of 0.67 or 0.35, a
 * black level 0 on a rig of 0.14 (with and without scattering medium), 0.2 on one of 0.05; a
 * featureless scene cannot tell a black level from scattered light and names the assumption.
 * Behind an opaque grid at a medium's entry face, a right black level at 5.25 px is not refused
 * and a wrong one is. Under scattered light whose kernel has long tails, a right duty is not
 * refused and a wrong one is, with and without the pair at twice the period. */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "daemon/operating/pattern_check.h"
#include "daemon/operating/scene_probe.h"
#include "daemon/operating/operating_error.h"
#include "proc/clip_level.h"
#include "proc/harmonic_gain.h"
#include "tests/daemon/calibrate_lines.h"
#include "tests/common/test_random.h"

#define W 256
#define H 96

typedef struct {
  double period, duty, black, blur;
  double scatter;      /* scattered light relative to the direct light of a clear pixel */
  double keep;         /* the part of it that keeps the stripes */
  double photons;      /* electrons at full light: shot noise */
  double read_e;
  gboolean featureless;
  guint seed;
  gboolean sine;       /* sine stripes: b + (1 - b) (1 + B cos)/2, B the Gaussian's exp (-2 pi^2 s^2 / P^2) */
  double dn_per_e;     /* the sensor's gain (0: 0.5); a small one quantises tiny signals coarsely */
  double ceiling_dn;   /* a clip level below the format's top (a full well), 0 = none */
  gboolean blur_known; /* the edge blur is configured (descatterctl calibrate's edge-blur-px) */
  double calibrated_blur; /* what calibration configured when blur_known (0: the stripes' own blur) */
  guint entry_grid;    /* > 0: an opaque grid of this pitch (lines 3 px) at the medium's entry face; the
                          scattered light is then of the light the grid passes */
  gboolean behind;     /* the objects lie behind the medium: they darken its scattered light too */
  double halo_px;      /* > 0: the kept scattered light's kernel along x is exp (-|x| / halo_px),
                          whose long tails keep the higher harmonics a Gaussian removes */
} Scene;

static double
lit_fraction (const Scene *s, double period, double x, double shift)
{
  /* the pixel [x - 1/2, x + 1/2] at 16 points; stripes centred at P (j + shift) */
  double acc = 0, half = s->duty * period / 2;
  for (int i = 0; i < 16; i++) {
    double t = x - 0.5 + (i + 0.5) / 16.0;
    if (s->sine) {
      acc += 0.5 * (1 + exp (-2 * G_PI * G_PI * s->blur * s->blur / (period * period)) *
                          cos (2 * G_PI * (t / period - shift)));
      continue;
    }
    double c0 = period * (floor (t / period - shift) + shift);
    for (int j = -2; j <= 3; j++) {
      double c = c0 + j * period;
      if (s->blur > 0)
        acc += 0.5 * (erf ((t - c + half) / (G_SQRT2 * s->blur)) - erf ((t - c - half) / (G_SQRT2 * s->blur)));
      else
        acc += fabs (t - c) < half;
    }
  }
  return acc / 16;
}

static double
transmittance (const Scene *s, guint x, guint y)
{
  if (s->entry_grid && (x % s->entry_grid < 3 || y % s->entry_grid < 3))
    return 0.0;
  if (s->featureless)
    return 1.0;
  double t = 1.0;
  if ((x / 23) % 3 == 1)
    t *= 0.25;
  double dx = (double) x - 180, dy = (double) y - 48;
  if (dx * dx + dy * dy < 30 * 30)
    t *= 0.4;
  if (y > 70 && x < 100)
    t *= 0.15;
  /* fine detail: a checkerboard of 5-pixel cells */
  if (y < 40 && x > 60 && x < 160 && ((x / 5) + (y / 5)) % 2)
    t *= 0.2;
  return t;
}

/* Separable Gaussian blur of a W x H plane (edges clamped). */
static void
gauss_blur (double *plane, double sigma)
{
  int r = (int) ceil (3 * sigma);
  g_autofree double *k = g_new (double, 2 * r + 1), *tmp = g_new (double, W * H);
  double norm = 0;
  for (int i = -r; i <= r; i++)
    norm += k[i + r] = exp (-0.5 * i * i / (sigma * sigma));
  for (int pass = 0; pass < 2; pass++) {
    for (int y = 0; y < H; y++)
      for (int x = 0; x < W; x++) {
        double acc = 0;
        for (int i = -r; i <= r; i++) {
          int xx = pass ? x : CLAMP (x + i, 0, W - 1), yy = pass ? CLAMP (y + i, 0, H - 1) : y;
          acc += k[i + r] * plane[yy * W + xx];
        }
        tmp[y * W + x] = acc / norm;
      }
    memcpy (plane, tmp, sizeof (double) * W * H);
  }
}

/* Along x only (the stripes vary along x): the kernel exp (-|i| / a), normalised, edges clamped. */
static void
laplace_blur_x (double *plane, double a)
{
  int r = (int) ceil (8 * a);
  g_autofree double *k = g_new (double, 2 * r + 1), *row = g_new (double, W);
  double norm = 0;
  for (int i = -r; i <= r; i++)
    norm += k[i + r] = exp (-fabs ((double) i) / a);
  for (int y = 0; y < H; y++) {
    for (int x = 0; x < W; x++) {
      double acc = 0;
      for (int i = -r; i <= r; i++)
        acc += k[i + r] * plane[y * W + CLAMP (x + i, 0, W - 1)];
      row[x] = acc / norm;
    }
    memcpy (plane + y * W, row, sizeof (double) * W);
  }
}

/* A 16-bit frame of phase shift `shift` at `period` (illuminator on), or the dark frame. */
static DsImage *
render (const Scene *s, double period, double shift, gboolean on, GRand *rng)
{
  DsImage *img = ds_image_new (DS_SAMPLE_U16, W, H, NULL);
  img->bit_depth = 16;
  g_autofree double *direct = g_new0 (double, W * H), *narrow = g_new0 (double, W * H), *wide = g_new0 (double, W * H);
  for (guint y = 0; y < H; y++)
    for (guint x = 0; x < W; x++) {
      double vignette = 1 - 0.35 * (((double) x - W / 2.0) * ((double) x - W / 2.0) / (W * W / 4.0));
      double pattern = on ? s->black + (1 - s->black) * lit_fraction (s, period, x, shift) : 0;
      direct[y * W + x] = vignette * transmittance (s, x, y) * pattern;
      narrow[y * W + x] = wide[y * W + x] = s->entry_grid ? direct[y * W + x] : vignette * pattern;
    }
  if (on && s->scatter > 0) {
    if (s->halo_px > 0)
      laplace_blur_x (narrow, s->halo_px);
    else
      gauss_blur (narrow, 0.35 * period);
    gauss_blur (wide, 12);
  }
  for (guint y = 0; y < H; y++) {
    guint16 *row = ds_image_row (img, y);
    for (guint x = 0; x < W; x++) {
      gsize i = y * W + x;
      double scattered = on ? s->scatter * (s->keep * narrow[i] + (1 - s->keep) * wide[i]) : 0;
      double light = direct[i] + (s->behind ? transmittance (s, x, y) : 1.0) * scattered;
      double e = s->photons * light + 200; /* 200 e of dark signal */
      double dn = e + sqrt (e + s->read_e * s->read_e) * test_normal (rng);
      double scale = s->dn_per_e > 0 ? s->dn_per_e : 0.5, top = s->ceiling_dn > 0 ? s->ceiling_dn : 65534;
      row[x] = (guint16) CLAMP (lround (dn * scale), 0, top);
    }
  }
  return img;
}

static int failures;

static void
check (gboolean cond, const char *what)
{
  printf ("%s %s\n", cond ? "ok  " : "FAIL", what);
  if (!cond)
    failures++;
}

static DsPatternCheck run_configured (const Scene *s, DsPatternKind kind, double conf_duty, double conf_black,
                                      double conf_gain, gboolean coarse);

static DsPatternCheck
run (const Scene *s, double conf_duty, double conf_black, gboolean coarse)
{
  return run_configured (s, DS_PATTERN_SQUARE, conf_duty, conf_black, 0, coarse);
}

/* The pilot frames of scene s checked against the configured pattern (conf_gain: the calibrated
 * harmonic gain, 0 = none). */
static DsPatternCheck
run_configured (const Scene *s, DsPatternKind kind, double conf_duty, double conf_black, double conf_gain,
                gboolean coarse)
{
  g_autoptr (GRand) rng = g_rand_new_with_seed (s->seed);
  g_autoptr (DsImage) dark = render (s, s->period, 0, FALSE, rng);
  g_autoptr (DsImage) l0 = render (s, s->period, 0.1, TRUE, rng);
  g_autoptr (DsImage) l1 = render (s, s->period, 0.6, TRUE, rng);
  g_autoptr (DsImage) c0 = coarse ? render (s, 2 * s->period, 0.1, TRUE, rng) : NULL;
  g_autoptr (DsImage) c1 = coarse ? render (s, 2 * s->period, 0.6, TRUE, rng) : NULL;
  DsProbeFrames f = {
    .dark = dark, .lit = { l0, l1 }, .coarse = { c0, c1 }, .saturation_dn = 65535,
    .geometry = { .kind = kind, .period_px = s->period, .duty = conf_duty, .black_level = conf_black },
    .calibrated_gain = conf_gain, .blur_known = s->blur_known, .calibrated_blur_px = !s->blur_known ? 0 : s->calibrated_blur > 0 ? s->calibrated_blur : s->blur,
  };
  DsPatternCheck c;
  g_autoptr (GError) error = NULL;
  if (!ds_pattern_check (&f, &c, &error)) {
    printf ("FAIL %s\n", error->message);
    failures++;
    memset (&c, 0, sizeof c);
    c.verdict = (DsPatternVerdict) -1;
  }
  return c;
}

static void
describe (const Scene *s, const DsPatternCheck *c, char *buf, gsize len, double conf_duty, double conf_black)
{
  g_snprintf (buf, len,
              "P %.1f a %.2f b %.2f blur %.1f scatter %.1f keep %.2f photons %.0f%s (configured a %.2f b %.2f): "
              "%s; duty %.3f/%.3f (expected %.3f+-%.3f/%.3f+-%.3f) level %.3f/%.3f (centres %.3f/%.3f) dim %.3f "
              "bright %.3f x%.2f",
              s->period, s->duty, s->black, s->blur, s->scatter, s->keep, s->photons,
              s->featureless ? " featureless" : "", conf_duty, conf_black, ds_pattern_verdict_name (c->verdict),
              c->pair[0].duty, c->pair[1].duty, c->pair[0].expected_duty, c->pair[0].duty_tolerance,
              c->pair[1].expected_duty, c->pair[1].duty_tolerance, c->pair[0].off_level, c->pair[1].off_level, c->pair[0].centre_off,
              c->pair[1].centre_off, c->off_dim,
              c->off_bright, c->brightness_ratio);
}

static void
test_no_false_alarm (void)
{
  guint said_scattered = 0, scattering = 0;
  const double duties[] = { 0.3, 0.5, 0.67 }, blacks[] = { 0.0, 0.12 }, blurs[] = { 0.0, 1.5 };
  const double photons[] = { 20000, 800 };
  const struct {
    double scatter, keep;
  } media[] = { { 0, 0 }, { 0.6, 0.2 }, { 3.0, 0.1 } };
  guint seed = 1;
  for (guint a = 0; a < G_N_ELEMENTS (duties); a++)
    for (guint b = 0; b < G_N_ELEMENTS (blacks); b++)
      for (guint s = 0; s < G_N_ELEMENTS (blurs); s++)
        for (guint m = 0; m < G_N_ELEMENTS (media); m++) {
          guint n = seed % 2; /* the noise alternates */
          {
            scattering += media[m].scatter > 0;
            Scene sc = { .period = 14, .duty = duties[a], .black = blacks[b], .blur = blurs[s],
                         .scatter = media[m].scatter, .keep = media[m].keep, .photons = photons[n],
                         .read_e = 10, .seed = seed++ };
            /* two periods for the coarse pair only on half the cases: both paths are checked */
            DsPatternCheck c = run (&sc, sc.duty, sc.black, (seed / 2) % 2 == 0);
            char what[480];
            describe (&sc, &c, what, sizeof what, sc.duty, sc.black);
            /* a medium's extra off-stripe light is never called a wrong configuration; where the
             * scene shows it is scattered light, nothing is said at all */
            gboolean fine = sc.scatter > 0 ? c.verdict == DS_PATTERN_MATCHES || c.verdict == DS_PATTERN_OFF_LEVEL_ASSUMED
                                           : c.verdict == DS_PATTERN_MATCHES;
            check (fine && c.pair[0].measured, what);
            if (sc.scatter > 0 && c.verdict == DS_PATTERN_MATCHES)
              said_scattered++;
          }
        }
  /* the object's detail shows scattered light for what it is on most scattering scenes */
  char what[120];
  g_snprintf (what, sizeof what, "%u of %u scattering scenes recognised as scattering (want >= 2/3)", said_scattered,
              scattering);
  check (3 * said_scattered >= 2 * scattering, what);
}

static void
expect_alarm (const Scene *sc, double conf_duty, double conf_black, gboolean coarse, DsPatternVerdict want,
       const char *must_say)
{
  DsPatternCheck c = run (sc, conf_duty, conf_black, coarse);
  char what[480];
  describe (sc, &c, what, sizeof what, conf_duty, conf_black);
  check (c.verdict == want, what);
  if (c.verdict == want && must_say) {
    gboolean says = strstr (c.message, must_say) && strstr (c.message, "descatterctl calibrate") &&
                    strstr (c.message, "black-level=");
    printf ("     %s\n", c.message);
    check (says, "the message names the configured value, what the frames show and the remedy");
  }
}

static void
test_alarms (void)
{
  /* gen-21-03 of the lab-user trial: no medium, duty 0.67, black level 0.14, the daemon's
   * defaults configured */
  Scene clear = { .period = 14, .duty = 0.67, .black = 0.14, .blur = 0.5, .photons = 5000, .read_e = 10, .seed = 101 };
  expect_alarm (&clear, 0.5, 0.0, TRUE, DS_PATTERN_WRONG_DUTY, "duty 0.50 is configured, the pilot frames show duty 0.6");
  expect_alarm (&clear, 0.5, 0.0, FALSE, DS_PATTERN_WRONG_DUTY, "duty 0.50 is configured");
  Scene narrow = clear;
  narrow.duty = 0.35;
  narrow.black = 0.0;
  expect_alarm (&narrow, 0.5, 0.0, TRUE, DS_PATTERN_WRONG_DUTY, "duty 0.50 is configured, the pilot frames show duty 0.3");
  /* a black level left at 0: the same fraction on dim and bright parts of the object */
  expect_alarm (&clear, 0.67, 0.0, TRUE, DS_PATTERN_WRONG_BLACK_LEVEL, "black level 0.00 is configured");
  Scene murky = clear;
  murky.scatter = 0.3;
  murky.keep = 0.2;
  murky.seed = 102;
  /* with a medium in front, the black level hides in scattered light unless it dominates: a
   * configured duty that is wrong is still seen */
  expect_alarm (&murky, 0.5, 0.14, TRUE, DS_PATTERN_WRONG_DUTY, "duty 0.50 is configured");
  /* a configured black level above what the frames show */
  Scene low = clear;
  low.black = 0.05;
  expect_alarm (&low, 0.67, 0.2, TRUE, DS_PATTERN_WRONG_BLACK_LEVEL, "black level 0.20 is configured");
  expect_alarm (&low, 0.67, 0.2, TRUE, DS_PATTERN_WRONG_BLACK_LEVEL, "off-stripe level of only 0.0");
  /* a featureless clear scene: the extra off-stripe light is named as an assumption */
  Scene plain = clear;
  plain.featureless = TRUE;
  expect_alarm (&plain, 0.67, 0.0, TRUE, DS_PATTERN_OFF_LEVEL_ASSUMED, "taken as scattered light");
}

/* A clear reference's phase set at `period` (N = 8). */
static void
reference_phases (const Scene *ref, double period, GRand *rng, DsImage **out)
{
  for (guint k = 0; k < 8; k++)
    out[k] = render (ref, period, k / 8.0, TRUE, rng);
}

/* The lines `descatterctl calibrate` prints for a sine illuminator (its black level told from
 * its blur at two periods), read as descatterd reads its configuration, make the pattern check
 * accept pilot frames of a scene lit by the same illuminator, clear or behind a medium; a black
 * level 0.1 too high is still refused, and so are the lines of the lab trial's calibration,
 * which folded the blur into the black level (the sinusoid at one period: b 0.10 where the
 * illuminator's is 0.022, and the pilot at twice the period shows the stripes sharper than a
 * blur-free configuration allows). */
static void
test_calibrated_sine (void)
{
  Scene ref = { .period = 16, .duty = 0.5, .black = 0.0222, .blur = 1.479, .photons = 20000, .read_e = 10,
                .featureless = TRUE, .seed = 201, .sine = TRUE };
  g_autoptr (GRand) rng = g_rand_new_with_seed (ref.seed);
  DsImage *at_p[8], *at_2p[8];
  g_autoptr (DsImage) dark = render (&ref, 16, 0, FALSE, rng);
  reference_phases (&ref, 16, rng, at_p);
  reference_phases (&ref, 32, rng, at_2p);
  double contrast;
  g_autofree char *lines = calibrate_lines (at_p, at_2p, 8, dark, 32, &contrast);
  for (guint k = 0; k < 8; k++) {
    ds_image_free (at_p[k]);
    ds_image_free (at_2p[k]);
  }
  g_autoptr (GKeyFile) kf = g_key_file_new ();
  check (g_key_file_load_from_data (kf, lines, (gsize) -1, G_KEY_FILE_NONE, NULL), "the printed lines load");
  g_autofree char *pattern = g_key_file_get_string (kf, "illuminator", "pattern", NULL);
  double b = g_key_file_get_double (kf, "illuminator", "black-level", NULL);
  double h = g_key_file_get_double (kf, "illuminator", "harmonic-gain", NULL);
  char what[480];
  g_snprintf (what, sizeof what, "calibrated: pattern=%s black-level=%.4f (illuminator 0.0222) harmonic-gain=%.4f",
              pattern ? pattern : "?", b, h);
  check (pattern && g_str_equal (pattern, "sine") && fabs (b - 0.0222) < 0.01, what);

  Scene scene = ref;
  scene.featureless = FALSE;
  scene.seed = 202;
  for (int coarse = 0; coarse < 2; coarse++) {
    DsPatternCheck c = run_configured (&scene, DS_PATTERN_SINE, 0.5, b, h, coarse);
    describe (&scene, &c, what, sizeof what, 0.5, b);
    check (c.verdict == DS_PATTERN_MATCHES && c.pair[0].measured, what);
  }
  Scene murky = scene;
  murky.scatter = 0.6;
  murky.keep = 0.2;
  DsPatternCheck c = run_configured (&murky, DS_PATTERN_SINE, 0.5, b, h, TRUE);
  describe (&murky, &c, what, sizeof what, 0.5, b);
  check (c.verdict == DS_PATTERN_MATCHES || c.verdict == DS_PATTERN_OFF_LEVEL_ASSUMED, what);

  c = run_configured (&scene, DS_PATTERN_SINE, 0.5, b + 0.1, h, TRUE);
  describe (&scene, &c, what, sizeof what, 0.5, b + 0.1);
  check (c.verdict == DS_PATTERN_WRONG_BLACK_LEVEL, what);
  /* one period's apparent level with the gain that goes with it: right at P, wrong at 2P */
  double b_app = (1 - contrast) / (1 + contrast), h_app = (1 + b_app) / 2 * contrast;
  c = run_configured (&scene, DS_PATTERN_SINE, 0.5, b_app, h_app, TRUE);
  describe (&scene, &c, what, sizeof what, 0.5, b_app);
  check (c.verdict == DS_PATTERN_WRONG_BLACK_LEVEL && strstr (c.message, "harmonic-gain="), what);
  printf ("     %s\n", c.message);
}

/* The probe and the pattern check refuse the same malformed pilot frames with the same error,
 * which names the frame at fault; well-formed frames pass both shape checks. */
static void
test_frame_shapes (void)
{
  g_autoptr (DsImage) a = ds_image_new (DS_SAMPLE_U16, W, H, NULL);
  g_autoptr (DsImage) b = ds_image_new (DS_SAMPLE_U16, W, H, NULL);
  g_autoptr (DsImage) c = ds_image_new (DS_SAMPLE_U16, W, H, NULL);
  g_autoptr (DsImage) narrow = ds_image_new (DS_SAMPLE_U16, W / 2, H, NULL);
  g_autoptr (DsImage) flt = ds_image_new (DS_SAMPLE_F32, W, H, NULL);
  const DsStripeModel geometry = { .kind = DS_PATTERN_SQUARE, .period_px = 8, .duty = 0.5 };
  struct {
    DsProbeFrames f;
    const char *names; /* what the error must name; NULL: accepted */
  } cases[] = {
    { { .dark = a, .lit = { b, c }, .geometry = geometry }, NULL },
    { { .dark = a, .lit = { b, c }, .coarse = { b, c }, .geometry = geometry }, NULL },
    { { .lit = { b, c }, .geometry = geometry }, "dark frame is missing" },
    { { .dark = a, .lit = { b, NULL }, .geometry = geometry }, "phase-1/2 frame at the period is missing" },
    { { .dark = a, .lit = { narrow, c }, .geometry = geometry }, "phase-0 frame at the period is 128x96" },
    { { .dark = a, .lit = { b, flt }, .geometry = geometry }, "phase-1/2 frame at the period is 256x96 f32" },
    { { .dark = a, .lit = { b, c }, .coarse = { b, NULL }, .geometry = geometry },
      "phase-1/2 frame at twice the period is missing" },
    { { .dark = a, .lit = { b, c }, .coarse = { NULL, c }, .geometry = geometry },
      "phase-0 frame at twice the period is missing" },
    { { .dark = a, .lit = { b, c }, .coarse = { b, narrow }, .geometry = geometry },
      "phase-1/2 frame at twice the period is 128x96" },
  };
  for (guint i = 0; i < G_N_ELEMENTS (cases); i++) {
    g_autoptr (GError) e_check = NULL, e_probe = NULL, e_shape = NULL;
    DsPatternCheck pc;
    DsSceneProbe probe;
    gboolean shape_ok = ds_probe_frames_check (&cases[i].f, &e_shape);
    gboolean check_ok = ds_pattern_check (&cases[i].f, &pc, &e_check);
    gboolean probe_ok = ds_scene_probe_measure (&cases[i].f, &probe, &e_probe);
    char what[160];
    g_snprintf (what, sizeof what, "frame shapes case %u: %s", i, cases[i].names ? cases[i].names : "accepted");
    if (!cases[i].names) {
      /* Blank frames show no stripes: the probe may refuse them, but not for their shape. */
      check (shape_ok && check_ok && (probe_ok || !g_error_matches (e_probe, DS_OPERATING_ERROR,
                                                                    DS_OPERATING_ERROR_PILOT_FRAMES)),
             what);
      continue;
    }
    check (!shape_ok && !check_ok && !probe_ok &&
               g_error_matches (e_check, DS_OPERATING_ERROR, DS_OPERATING_ERROR_PILOT_FRAMES) &&
               g_error_matches (e_probe, DS_OPERATING_ERROR, DS_OPERATING_ERROR_PILOT_FRAMES) &&
               strcmp (e_check->message, e_shape->message) == 0 && strcmp (e_probe->message, e_shape->message) == 0 &&
               strstr (e_shape->message, cases[i].names) != NULL,
           what);
    if (e_shape)
      printf ("     %s\n", e_shape->message);
  }
}


/* g1 = exp (-2 pi^2 sigma^2 / P^2) sinc (1 / P): the first harmonic the blur and the whole pixel
 * leave, written here from the Fourier transforms of a Gaussian and a 1 px box. */
static double
closed_form_g1 (double period, double sigma)
{
  double f = 1 / period;
  return exp (-2 * G_PI * G_PI * sigma * sigma * f * f) * sin (G_PI * f) / (G_PI * f);
}

/* Where the measurement itself is poor the tolerance widens with it, and only there: stripes of
 * 3.5 px (the blur and the pixel keep g1 ~ 0.6 of the troughs' depth, the level is extrapolated)
 * and tiny, coarsely quantised signals (~20 DN lit, gain 0.03 DN/e) with the right configuration
 * pass; a black level 0.33 configured on stripes without one, none configured on stripes of 0.3
 * (named as an assumption where the scene cannot tell it from scattered light), and a duty 0.5
 * configured on stripes of 0.25 are still refused there. */
static void
test_poor_measurements (void)
{
  char what[480];
  Scene fine = { .period = 3.5, .duty = 0.51, .black = 0.33, .blur = 0.39, .photons = 5000, .read_e = 10, .seed = 301 };
  for (int coarse = 0; coarse < 2; coarse++) {
    DsPatternCheck c = run (&fine, fine.duty, fine.black, coarse);
    describe (&fine, &c, what, sizeof what, fine.duty, fine.black);
    check (c.verdict == DS_PATTERN_MATCHES && c.pair[0].measured, what);
    /* the tolerance at 3.5 px is LEVEL_TOLERANCE (0.03) over g1 at the true blur, to the blur's fit */
    double want = 0.03 / closed_form_g1 (fine.period, fine.blur);
    g_snprintf (what, sizeof what, "level tolerance at P 3.5: %.4f, closed form %.4f", c.pair[0].level_tolerance,
                want);
    check (fabs (c.pair[0].level_tolerance - want) < 0.15 * want && want > 0.04, what);
  }
  Scene unlit = fine;
  unlit.black = 0.0;
  unlit.seed = 302;
  expect_alarm (&unlit, 0.51, 0.33, TRUE, DS_PATTERN_WRONG_BLACK_LEVEL, "black level 0.33 is configured");
  expect_alarm (&unlit, 0.51, 0.33, FALSE, DS_PATTERN_WRONG_BLACK_LEVEL, "black level 0.33 is configured");
  Scene lifted = fine;
  lifted.black = 0.3;
  lifted.seed = 303;
  /* at 3.5 px the stripe centres' brightness spreads too little to tell a black level from
   * scattered light: the level is named as an assumption, never accepted as it stands */
  DsPatternCheck lc = run (&lifted, 0.51, 0.0, TRUE);
  describe (&lifted, &lc, what, sizeof what, 0.51, 0.0);
  check (lc.verdict == DS_PATTERN_WRONG_BLACK_LEVEL || lc.verdict == DS_PATTERN_OFF_LEVEL_ASSUMED, what);

  /* ~20 DN at the stripes' centres: 700 e at 0.03 DN/e, read noise 3 e */
  Scene dim = { .period = 11.25, .duty = 0.34, .blur = 0.95, .photons = 700, .read_e = 3, .dn_per_e = 0.03,
                .seed = 304 };
  for (int coarse = 0; coarse < 2; coarse++) {
    DsPatternCheck c = run (&dim, dim.duty, dim.black, coarse);
    describe (&dim, &c, what, sizeof what, dim.duty, dim.black);
    check (c.verdict == DS_PATTERN_MATCHES && c.pair[0].measured, what);
  }
  Scene dim_lifted = dim;
  dim_lifted.black = 0.3;
  dim_lifted.seed = 306;
  expect_alarm (&dim_lifted, 0.34, 0.0, TRUE, DS_PATTERN_WRONG_BLACK_LEVEL, "black level 0.00 is configured");
  Scene quarter = dim;
  quarter.duty = 0.25;
  quarter.seed = 305;
  expect_alarm (&quarter, 0.5, 0.0, TRUE, DS_PATTERN_WRONG_DUTY, "duty 0.50 is configured");
  expect_alarm (&quarter, 0.5, 0.0, FALSE, DS_PATTERN_WRONG_DUTY, "duty 0.50 is configured");
}

/* Clipped pilots: the lit centres of the bright parts are gone, the profile is sampled unevenly,
 * and neither duty nor level can be read from it. Stripes whose peaks reach a clip level below
 * the format's top (a full well: the samples pile up at one value) or the format's top itself
 * are not measured, and a right configuration is not refused; unclipped frames of the same
 * scene still are measured. */
static void
test_clipped (void)
{
  char what[480];
  /* peaks of 0.5 x 8000 e x 0.5 DN/e = 2000 DN at the centre of the vignette */
  Scene sc = { .period = 13.75, .duty = 0.28, .blur = 0.14, .photons = 8000, .read_e = 10, .seed = 401 };
  DsPatternCheck c = run (&sc, sc.duty, sc.black, TRUE);
  describe (&sc, &c, what, sizeof what, sc.duty, sc.black);
  check (c.verdict == DS_PATTERN_MATCHES && c.pair[0].measured && c.pair[0].clipped_share == 0, what);
  /* a full well at 1200 DN: the open stripes of the bright parts clip, a share of the pixels far
   * above 2 % (the lit positions are 2 x 0.28 of the period) */
  sc.ceiling_dn = 1200;
  for (int coarse = 0; coarse < 2; coarse++) {
    c = run (&sc, sc.duty, sc.black, coarse);
    describe (&sc, &c, what, sizeof what, sc.duty, sc.black);
    check (c.verdict == DS_PATTERN_MATCHES && !c.pair[0].measured && c.pair[0].clipped_share > 0.1, what);
  }
  /* the format's top as the clip level (saturation_dn): the same */
  sc.ceiling_dn = 65535;
  sc.photons = 200000;
  c = run (&sc, sc.duty, sc.black, TRUE);
  describe (&sc, &c, what, sizeof what, sc.duty, sc.black);
  check (c.verdict == DS_PATTERN_MATCHES && !c.pair[0].measured && c.pair[0].clipped_share > 0.1, what);
}

/* Square stripes a few pixels wide, the edge blur configured as calibrated: the fit's duty trades
 * against its blur and level there, and the check compares it with what the configured pattern
 * reads through the same measurement. Right configurations at 2.75 px and at 7 px (duty 0.24,
 * blur 0.94 px, black level 0.038; clear, behind a thin film that keeps part of its scattered
 * light's stripes, and behind a medium scattering as much light as it passes) are not refused; a duty 0.5 on stripes of 0.25 (and the reverse), 0.24 on 0.4,
 * and a black level 0.2 on a rig of 0.038 are. */
static void
test_narrow_stripes (void)
{
  char what[480];
  const struct {
    double period, duty, black, blur, scatter, keep, photons;
  } right[] = {
    { 2.75, 0.5, 0.0, 0.5, 0, 0, 20000 },   { 2.75, 0.3, 0.0, 0.5, 0, 0, 20000 },
    { 2.75, 0.5, 0.05, 0.3, 0, 0, 2000 },   { 7, 0.24, 0.038, 0.94, 0, 0, 20000 },
    { 7, 0.24, 0.038, 0.94, 0, 0, 2000 },   { 7, 0.24, 0.038, 0.94, 0.3, 0.5, 5000 },
    { 7, 0.24, 0.038, 0.94, 0.15, 0.3, 5000 }, { 7, 0.24, 0.038, 0.94, 1.0, 0.3, 5000 },
  };
  for (guint i = 0; i < G_N_ELEMENTS (right); i++)
    for (int coarse = 0; coarse < 2; coarse++) {
      Scene sc = { .period = right[i].period, .duty = right[i].duty, .black = right[i].black, .blur = right[i].blur,
                   .scatter = right[i].scatter, .keep = right[i].keep, .photons = right[i].photons, .read_e = 10,
                   .seed = 500 + 2 * i + (guint) coarse, .blur_known = TRUE };
      DsPatternCheck c = run (&sc, sc.duty, sc.black, coarse);
      describe (&sc, &c, what, sizeof what, sc.duty, sc.black);
      gboolean fine = c.verdict == DS_PATTERN_MATCHES || (sc.scatter > 0 && c.verdict == DS_PATTERN_OFF_LEVEL_ASSUMED);
      check (fine && c.pair[0].measured, what);
    }
  /* without the calibrated blur the fit may trade it against the duty, and the spread of the
   * frames' own readings says how far: the right duty is still not refused */
  Scene loose = { .period = 7, .duty = 0.24, .black = 0.038, .blur = 0.94, .photons = 20000, .read_e = 10, .seed = 520 };
  DsPatternCheck c = run (&loose, loose.duty, loose.black, FALSE);
  describe (&loose, &c, what, sizeof what, loose.duty, loose.black);
  check (c.verdict == DS_PATTERN_MATCHES && c.pair[0].measured, what);

  const struct {
    double period, duty, black, blur, conf_duty, conf_black;
    DsPatternVerdict want;
  } wrong[] = {
    { 7, 0.25, 0.0, 0.94, 0.5, 0.0, DS_PATTERN_WRONG_DUTY },     { 7, 0.5, 0.0, 0.94, 0.25, 0.0, DS_PATTERN_WRONG_DUTY },
    { 7, 0.4, 0.038, 0.94, 0.24, 0.038, DS_PATTERN_WRONG_DUTY }, { 2.75, 0.25, 0.0, 0.5, 0.5, 0.0, DS_PATTERN_WRONG_DUTY },
    { 2.75, 0.5, 0.0, 0.5, 0.25, 0.0, DS_PATTERN_WRONG_DUTY },   { 7, 0.24, 0.038, 0.94, 0.24, 0.2, DS_PATTERN_WRONG_BLACK_LEVEL },
  };
  for (guint i = 0; i < G_N_ELEMENTS (wrong); i++)
    for (int coarse = 0; coarse < 2; coarse++) {
      Scene sc = { .period = wrong[i].period, .duty = wrong[i].duty, .black = wrong[i].black, .blur = wrong[i].blur,
                   .photons = 20000, .read_e = 10, .seed = 540 + 2 * i + (guint) coarse, .blur_known = TRUE };
      c = run (&sc, wrong[i].conf_duty, wrong[i].conf_black, coarse);
      describe (&sc, &c, what, sizeof what, wrong[i].conf_duty, wrong[i].conf_black);
      check (c.verdict == wrong[i].want, what);
    }
}

/* A calibrated blur wider than the frames' own (sharp stripes, 0.6 px configured): at 8 px the
 * frames alone tell the duty from the blur, so a right duty 0.5 is not refused and a duty 0.5
 * configured on stripes of 0.25 is; at 2.75 px they cannot, and the floor still refuses that
 * wrong duty. */
static void
test_calibration_wider (void)
{
  char what[480];
  const struct {
    double period, duty, blur, calibrated, conf_duty;
    gboolean refused;
  } cases[] = {
    { 8, 0.5, 0.0, 0.6, 0.5, FALSE },  { 8, 0.25, 0.0, 0.6, 0.25, FALSE }, { 8, 0.25, 0.0, 0.6, 0.5, TRUE },
    { 8, 0.5, 0.0, 0.6, 0.25, TRUE },  { 2.75, 0.25, 0.2, 0.5, 0.5, TRUE },
  };
  for (guint i = 0; i < G_N_ELEMENTS (cases); i++)
    for (int coarse = 0; coarse < 2; coarse++) {
      Scene sc = { .period = cases[i].period, .duty = cases[i].duty, .blur = cases[i].blur, .photons = 20000,
                   .read_e = 10, .seed = 600 + 2 * i + (guint) coarse, .blur_known = TRUE,
                   .calibrated_blur = cases[i].calibrated };
      DsPatternCheck c = run (&sc, cases[i].conf_duty, 0, coarse);
      describe (&sc, &c, what, sizeof what, cases[i].conf_duty, 0);
      check (c.pair[0].measured && (c.verdict == DS_PATTERN_WRONG_DUTY) == cases[i].refused, what);
    }
}

/* A 16-bit frame of known samples: level + a ramp along x of `slope` DN per column, Gaussian
 * noise of sigma DN, clamped at `well` (a full well below the format's top; 0 = none). */
static DsImage *
clip_frame (double level, double slope, double sigma, double well, guint seed)
{
  g_autoptr (GRand) rng = g_rand_new_with_seed (seed);
  DsImage *img = ds_image_new (DS_SAMPLE_U16, W, H, NULL);
  img->bit_depth = 16;
  for (guint y = 0; y < H; y++) {
    guint16 *row = ds_image_row (img, y);
    for (guint x = 0; x < W; x++) {
      double v = level + slope * x + sigma * test_normal (rng);
      row[x] = (guint16) CLAMP (lround (v), 0, well > 0 ? well : 65535);
    }
  }
  return img;
}

/* The shared clip rule (proc/clip_level.h) on closed-form frames: a ramp from 100 to 2650 DN with
 * 8 DN of noise clamped at a full well of 2000 DN piles a quarter of its samples there, far below
 * the format's top, and those pixels are the clipped ones; the same ramp unclamped, and a
 * noise-free frame whose flat top holds half its samples (a plateau, not a clip), show none. */
static void
test_clip_rule (void)
{
  g_autoptr (DsImage) dark = clip_frame (100, 0, 8, 0, 601);
  g_autoptr (DsImage) piled = clip_frame (100, 10, 8, 2000, 602);
  g_autoptr (DsImage) open = clip_frame (100, 10, 8, 0, 603);
  DsClipLevel c;
  const DsImage *lit[2] = { piled, open };
  ds_clip_level_find (dark, lit, 2, 65535, &c);
  /* columns x >= 190 reach 2000 DN (2000 - 100) / 10, less the noise's few columns either way */
  guint64 clipped = ds_clip_count (piled, NULL, c.level), want = (guint64) (W - 190) * H;
  char what[200];
  g_snprintf (what, sizeof what, "a full well at 2000 DN: level %.0f (piled %d), %" G_GUINT64_FORMAT " pixels clipped, "
              "about %" G_GUINT64_FORMAT " expected", c.level, c.piled, clipped, want);
  check (c.piled && c.level == 2000 && clipped > want - 3 * H && clipped < want + 3 * H, what);
  const DsImage *unclipped[2] = { open, open };
  ds_clip_level_find (dark, unclipped, 2, 65535, &c);
  g_snprintf (what, sizeof what, "an unclipped ramp: level %.0f (piled %d), %" G_GUINT64_FORMAT " pixels clipped",
              c.level, c.piled, ds_clip_count (open, open, c.level));
  check (!c.piled && c.level == 65535 && ds_clip_count (open, open, c.level) == 0, what);
  g_autoptr (DsImage) quiet_dark = clip_frame (100, 0, 0, 0, 604);
  g_autoptr (DsImage) plateau = clip_frame (100, 0, 0, 0, 605);
  for (guint y = 0; y < H; y++) {
    guint16 *row = ds_image_row (plateau, y);
    for (guint x = 0; x < W / 2; x++)
      row[x] = (guint16) (100 + 4 * x);
    for (guint x = W / 2; x < W; x++)
      row[x] = 100 + 4 * (W / 2);
  }
  const DsImage *flat[2] = { plateau, plateau };
  ds_clip_level_find (quiet_dark, flat, 2, 65535, &c);
  g_snprintf (what, sizeof what, "a noise-free flat top: level %.0f (piled %d)", c.level, c.piled);
  check (!c.piled && c.level == 65535, what);
}

/* A leaky illuminator (black level 0.27) with square stripes of 5.25 px, duty 0.22, through a
 * scattering slab behind an opaque grid at its entry face: the pixels behind the grid's lines see
 * only light scattered in from their sides, whose stripes are weaker and shifted, and the grid's
 * pitch (14 px, 8/3 periods) puts them at some positions of the period more than at others. No
 * pixel's off-stripe light is below 0.27 of its lit light (the frames are mixtures of the
 * illuminator's light), so the right black level is not refused, whatever the medium; 0.27
 * configured on a rig of 0.08 behind the same grid and a medium that does not lift its
 * off-stripe light to 0.27 is. */
static void
test_entry_grid (void)
{
  char what[480];
  const struct {
    double scatter, keep;
  } media[] = { { 0.5, 0.3 }, { 1.0, 0.3 }, { 0.5, 0.6 }, { 1.0, 0.6 }, { 2.0, 0.5 } };
  for (guint m = 0; m < G_N_ELEMENTS (media); m++)
    for (int coarse = 0; coarse < 2; coarse++) {
      Scene sc = { .period = 5.25, .duty = 0.22, .black = 0.27, .blur = 0.26, .scatter = media[m].scatter,
                   .keep = media[m].keep, .photons = 5000, .read_e = 10, .featureless = TRUE, .entry_grid = 14,
                   .seed = 700 + 2 * m + (guint) coarse, .blur_known = TRUE };
      DsPatternCheck c = run (&sc, sc.duty, sc.black, coarse);
      describe (&sc, &c, what, sizeof what, sc.duty, sc.black);
      check (c.verdict == DS_PATTERN_MATCHES || c.verdict == DS_PATTERN_OFF_LEVEL_ASSUMED, what);
      if (sc.scatter > 0.5)
        continue; /* more scattered light than that lifts 0.08 to 0.27 and beyond: nothing to refuse */
      Scene dark = sc;
      dark.black = 0.08;
      c = run (&dark, sc.duty, 0.27, coarse);
      describe (&dark, &c, what, sizeof what, sc.duty, 0.27);
      check (c.verdict == DS_PATTERN_WRONG_BLACK_LEVEL, what);
    }
}

/* Objects behind a medium that scatters widely: its light reaches them already scattered, so
 * they darken it with the direct light, and dim and bright parts show the same extra off-stripe
 * share as a black level would. Configured with the right black level but no calibration, the
 * check refuses (it cannot tell the two: the message must say a calibration does); with the
 * calibrated harmonic gain that goes with that black level, the excess is taken as scattered
 * light and the pilot runs. A black level configured above the truth is still refused with it. */
static void
test_objects_behind_medium (void)
{
  Scene s = { .period = 14, .duty = 0.45, .black = 0.03, .blur = 0.5, .scatter = 0.12, .keep = 0.0,
              .photons = 8000, .read_e = 10, .seed = 131, .behind = TRUE };
  char what[480];
  DsPatternCheck c = run (&s, s.duty, s.black, TRUE);
  describe (&s, &c, what, sizeof what, s.duty, s.black);
  check (c.verdict == DS_PATTERN_WRONG_BLACK_LEVEL && strstr (c.message, "calibration tells the two apart"), what);
  printf ("     %s\n", c.message);
  double h = ds_harmonic_gain_theory (DS_PATTERN_SQUARE, s.duty, s.black);
  for (int coarse = 0; coarse < 2; coarse++) {
    c = run_configured (&s, DS_PATTERN_SQUARE, s.duty, s.black, h, coarse);
    describe (&s, &c, what, sizeof what, s.duty, s.black);
    check (c.verdict == DS_PATTERN_OFF_LEVEL_ASSUMED && strstr (c.message, "calibrated black level is 0.03"), what);
  }
  printf ("     %s\n", c.message);
  double high = 0.25;
  c = run_configured (&s, DS_PATTERN_SQUARE, s.duty, high, ds_harmonic_gain_theory (DS_PATTERN_SQUARE, s.duty, high),
                      TRUE);
  describe (&s, &c, what, sizeof what, s.duty, high);
  check (c.verdict == DS_PATTERN_WRONG_BLACK_LEVEL, what);
}

/* Scattered light that keeps the stripes through a kernel with a sharp core and long tails (a
 * forward-peaked medium's; here exp (-|x| / a) along the stripes' axis, a = 0.8-3 px) behind
 * square stripes of duty 0.71 at 7.75 px, black level 0.16, the edge blur calibrated: no
 * Gaussian renders that kernel, and the fit reads the duty up to 0.89 on one pair. The right
 * configuration is never refused, with the pair at 2P and without it; a duty 0.5 configured on
 * the same frames always is (the kernel-free reading, mean_position () in pattern_check.c, lies
 * between what the edge blur gives the configured duty and 1/2 for any kernel). */
static void
test_halo (void)
{
  char what[480];
  const double scatters[] = { 1, 3, 8 }, keeps[] = { 0.3, 0.6 }, halos[] = { 0.8, 1.5, 3 };
  guint seed = 700;
  /* each kernel width with two of the six media, so the run stays short */
  for (guint i = 0; i < G_N_ELEMENTS (scatters); i++)
    for (guint j = 0; j < G_N_ELEMENTS (keeps); j++)
        for (int coarse = 0; coarse < 2; coarse++) {
          Scene sc = { .period = 7.75, .duty = 0.71, .black = 0.16, .blur = 0.68, .scatter = scatters[i],
                       .keep = keeps[j], .halo_px = halos[(i + j) % G_N_ELEMENTS (halos)], .photons = 8000,
                       .read_e = 10, .seed = seed++, .blur_known = TRUE };
          DsPatternCheck c = run (&sc, sc.duty, sc.black, coarse);
          describe (&sc, &c, what, sizeof what, sc.duty, sc.black);
          check (c.verdict == DS_PATTERN_MATCHES || c.verdict == DS_PATTERN_OFF_LEVEL_ASSUMED, what);
          c = run (&sc, 0.5, sc.black, coarse);
          describe (&sc, &c, what, sizeof what, 0.5, sc.black);
          check (c.verdict == DS_PATTERN_WRONG_DUTY, what);
        }
}

int
main (void)
{
  test_entry_grid ();
  test_frame_shapes ();
  test_alarms ();
  test_calibrated_sine ();
  test_no_false_alarm ();
  test_poor_measurements ();
  test_clipped ();
  test_narrow_stripes ();
  test_calibration_wider ();
  test_clip_rule ();
  test_objects_behind_medium ();
  test_halo ();
  printf ("%d failure(s)\n", failures);
  return failures ? 1 : 0;
}
