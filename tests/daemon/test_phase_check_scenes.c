/* The per-frame phase check (proc/phase_check.c) on scenes the project's generator draws
 * (daemon/ctl/scene_gen.c, `descatterctl generate-scenes`, version 2: sine and square stripes
 * of duty 0.2-0.8, periods from 2.5 px, black levels up to 0.4, heavy forward scattering, 8- to
 * 16-bit sensors), with N drawn from 2 to 16 and a quarter of the scenes in dim light (low
 * contrast against the noise).
 * Every frame is rendered by the scene simulator (drivers/sim: the light of each phase once,
 * then the sensor's noise per frame), so the expectation is the simulator's: the frame was
 * lit with the phase it is labelled with, or, in the trials, with another.
 *
 * Asserted over all scenes:
 * - no false refusal: every correct frame of three sets (the first checked as a whole, the
 *   others against the last set) passes (OK or "cannot verify"), taken again as the sequencer
 *   does when refused (the phase applied afresh); refused on every try, or a set not
 *   confirmed, is a false refusal. Frames refused once and passed on the retry are counted;
 * - a frame one step wrong (it shows phase k - 1 or k + 1), a repeated frame (the buffer of
 *   the frame before it again) and a frame without the illuminator (lit off) are caught, in a
 *   first set and in a later one, except where the check said "cannot verify" (counted apart);
 *   the misses stay below MISS_BOUND of the verifiable trials.
 * The counts are printed (--verbose); docs/reliability.md, "Phase check", states them for the
 * seeds 5000-5199, 6000-6199 and 7000-7199 (the check was developed on seeds 1-50 and 5000-5199). */
#include <glib.h>
#include <math.h>
#include <string.h>

#include "daemon/ctl/scene_gen.h"
#include "drivers/sim/renderer.h"
#include "drivers/sim/scene.h"
#include "proc/phase_check.h"
#include "proc/stripe_phase.h"

/* Misses (a wrong frame accepted where the check claimed it could tell) allowed, as a share of
 * the trials that were verifiable. */
#define MISS_BOUND 0.02
/* A refused correct frame is taken again up to this many times (phase-retries' default). */
#define RETRIES 3

typedef struct {
  guint scenes, frames, sets, false_refusals, retried_frames, unverified_frames, unverified_sets;
  guint trials, caught, missed, cannot_verify;
  guint blank_trials, blank_caught;
  guint no_stripes_scenes;
} Tally;

static double
uniform (GRand *r, double lo, double hi)
{
  return lo + (hi - lo) * g_rand_double (r);
}

typedef struct {
  const DsRenderer *renderer;
  DsImage *light[16]; /* photons of each phase */
  guint n;
  double exposure_us;
  guint64 seed;
  DsImage *last;      /* the frame sent before, for the repeat trials */
  const char *name;
} Scene;

static DsImage *
expose (Scene *s, guint shows)
{
  DsRenderRequest req = { .phase = shows, .n_phases = s->n, .illuminator_on = TRUE, .exposure_us = s->exposure_us,
                          .seed = ++s->seed };
  g_autoptr (GError) error = NULL;
  DsImage *img = ds_renderer_expose (s->renderer, s->light[shows], &req, &error);
  g_assert_no_error (error);
  return img;
}

/* A frame with the illuminator off (the ambient light and the sensor only). */
static DsImage *
expose_dark (Scene *s)
{
  DsRenderRequest req = { .phase = 0, .n_phases = s->n, .illuminator_on = FALSE, .exposure_us = s->exposure_us,
                          .seed = ++s->seed };
  g_autoptr (GError) error = NULL;
  DsImage *img = ds_renderer_render (s->renderer, &req, &error);
  g_assert_no_error (error);
  return img;
}

/* Sends `img` as phase k; keeps it as the last frame sent. */
static DsPhaseVerdict
send (DsPhaseCheck *c, Scene *s, DsImage *img, guint k, char **why)
{
  double measured;
  g_clear_pointer (why, g_free);
  DsPhaseVerdict v = ds_phase_check_frame (c, img, k, s->n, &measured, why);
  if (s->last != img) {
    g_clear_pointer (&s->last, ds_image_free);
    s->last = img;
  }
  return v;
}

static void
correct_set (DsPhaseCheck *c, Scene *s, Tally *t)
{
  g_autofree char *why = NULL;
  gboolean refused = FALSE;
  ds_phase_check_begin_set (c);
  for (guint k = 0; k < s->n; k++) {
    DsPhaseVerdict v = DS_PHASE_VERDICT_WRONG;
    for (guint i = 0; i <= RETRIES && (v == DS_PHASE_VERDICT_WRONG || v == DS_PHASE_VERDICT_NO_STRIPES); i++) {
      if (i > 0) {
        t->retried_frames++;
        g_test_message ("%s: correct frame %u of %u refused, taken again: %s", s->name, k, s->n, why);
      }
      v = send (c, s, expose (s, k), k, &why);
    }
    t->frames++;
    if (v == DS_PHASE_VERDICT_WRONG || v == DS_PHASE_VERDICT_NO_STRIPES) {
      g_test_message ("%s: correct frame %u of %u refused: %s", s->name, k, s->n, why);
      refused = TRUE;
    } else if (v == DS_PHASE_VERDICT_UNVERIFIABLE)
      t->unverified_frames++;
  }
  g_clear_pointer (&why, g_free);
  t->sets++;
  guint64 sets_unverified = c->sets_unverified;
  if (refused)
    ds_phase_check_abandon (c);
  else if (!ds_phase_check_confirm (c, &why)) {
    g_test_message ("%s: correct set of %u refused: %s", s->name, s->n, why);
    refused = TRUE;
  }
  t->unverified_sets += c->sets_unverified > sets_unverified;
  t->false_refusals += refused;
}

/* One set whose frame for phase `at` is wrong: shows at + dir (dir +-1), repeats the frame
 * sent before it (dir 0), or was exposed with the illuminator off (dir 2). Caught when a frame
 * of the set is refused or the set is not confirmed; a wrong frame accepted while some frame
 * of the set could not be verified is a "cannot verify", not a miss. */
static void
wrong_set (DsPhaseCheck *c, Scene *s, guint at, int dir, Tally *t)
{
  g_autofree char *why = NULL;
  gboolean caught = FALSE, unverified = FALSE;
  ds_phase_check_begin_set (c);
  for (guint k = 0; k < s->n && !caught; k++) {
    DsImage *img = k != at                ? expose (s, k)
                   : dir == 2             ? expose_dark (s)
                   : dir == 0 && s->last ? s->last
                                          : expose (s, (k + s->n + dir) % s->n);
    DsPhaseVerdict v = send (c, s, img, k, &why);
    caught = v == DS_PHASE_VERDICT_WRONG || v == DS_PHASE_VERDICT_NO_STRIPES;
    unverified |= v == DS_PHASE_VERDICT_UNVERIFIABLE;
  }
  g_clear_pointer (&why, g_free);
  guint64 sets_unverified = c->sets_unverified;
  if (!caught && !ds_phase_check_confirm (c, &why))
    caught = TRUE;
  unverified |= c->sets_unverified > sets_unverified;
  if (caught)
    ds_phase_check_abandon (c);
  if (dir == 2) {
    /* Counted apart: no stripes is no phase, and it is refused outright or not at all. */
    t->blank_trials++;
    t->blank_caught += caught;
    if (!caught)
      g_test_message ("%s: N %u, frame %u with the illuminator off not caught", s->name, s->n, at);
    return;
  }
  t->trials++;
  if (caught)
    t->caught++;
  else if (unverified)
    t->cannot_verify++;
  else {
    t->missed++;
    g_test_message ("%s: N %u, frame %u %s not caught", s->name, s->n, at,
                    dir == 0 ? "repeating the frame before" : dir > 0 ? "showing the next phase" : "showing the previous phase");
  }
}

static void
run_scene (guint64 seed, Tally *t)
{
  g_autoptr (GError) error = NULL;
  g_autofree char *text = ds_scene_generate (seed, 0, 2, &error);
  g_assert_no_error (error);
  g_autoptr (GRand) r = g_rand_new_with_seed_array ((const guint32[]){ (guint32) seed, 36 }, 2);
  static const guint phases[] = { 2, 3, 4, 6, 8, 12, 16 };
  guint n = phases[g_rand_int_range (r, 0, G_N_ELEMENTS (phases))];
  g_autofree char *name = g_strdup_printf ("scene %" G_GUINT64_FORMAT, seed);
  /* At half the generator's size (objects scaled, stripes and medium kept): a quarter of the
   * rendering, and a noisier first harmonic than a camera's frame gives, which is the harder
   * case for a check that must not mistake noise for a wrong phase. */
  g_autoptr (DsScene) drawn_scene = ds_scene_load_data (text, strlen (text), name, &error);
  g_assert_no_error (error);
  g_autoptr (DsScene) scene = ds_scene_copy_resized (drawn_scene, ds_scene_width (drawn_scene) / 2,
                                                     ds_scene_height (drawn_scene) / 2);
  g_autoptr (DsRenderer) renderer = ds_renderer_new (scene, NULL, &error);
  g_assert_no_error (error);
  /* A quarter of the scenes in dim light (a hundredth to a third of the generator's exposure):
   * stripes from well above the noise down into it, where the check must say it cannot tell. */
  double dim = g_rand_double (r) < 0.25 ? exp (uniform (r, log (0.01), log (0.3))) : 1.0;
  g_autofree char *what = g_strdup_printf ("%s (%s P %.2f duty %.2f black %.2f, %u bits, N %u%s)", name,
                                           ds_scene_pattern_is_sine (scene) ? "sine" : "square",
                                           ds_scene_period_px (scene), ds_scene_duty (scene),
                                           ds_scene_black_level (scene), ds_scene_bit_depth (scene), n,
                                           dim < 1 ? ", dim" : "");
  Scene s = { .renderer = renderer, .n = n, .exposure_us = dim * ds_scene_default_exposure_us (scene),
              .seed = seed * 1000003u, .name = what };
  for (guint k = 0; k < n; k++) {
    DsRenderRequest req = { .phase = k, .n_phases = n, .illuminator_on = TRUE, .exposure_us = s.exposure_us };
    s.light[k] = ds_renderer_render_photons (s.renderer, &req, &error);
    g_assert_no_error (error);
  }
  /* Whether the scene shows stripes at all: the first harmonic of each phase's noise-free
   * frame (the renderer's expectation) against the noise of a measured one, from the pixel
   * noise of two rendered frames' difference and the rows and columns the check fits (at least
   * 256 rows, evenly spread). A scene whose stripes stand less than 10 noise sigmas out at some
   * phase is one the stripes cannot verify: the check refuses its frames in a first set (no
   * evidence yet that the scene hides the projected stripes), as it must refuse a frame of an
   * illuminator switched off; counted apart, not run. */
  {
    DsRenderRequest req = { .phase = 0, .n_phases = n, .illuminator_on = TRUE, .exposure_us = s.exposure_us };
    g_autoptr (DsImage) f1 = expose (&s, 0);
    g_autoptr (DsImage) f2 = expose (&s, 0);
    double sum2 = 0;
    for (guint y = 0; y < f1->height; y++) {
      const void *r1 = ds_image_row (f1, y), *r2 = ds_image_row (f2, y);
      for (guint x = 0; x < f1->width; x++) {
        double d = ds_image_sample (f1, r1, x) - ds_image_sample (f2, r2, x);
        sum2 += d * d;
      }
    }
    /* integer samples: no finer than their quantisation (a clipped frame has no noise) */
    double pixel_sigma = MAX (sqrt (sum2 / (2.0 * f1->width * f1->height)), 1.0 / sqrt (12.0));
    guint rows = f1->height / MAX (1u, f1->height / 256);
    double weakest = INFINITY, sigma_c = 0;
    for (guint k = 0; k < n; k++) {
      req.phase = k;
      g_autoptr (DsImage) expected = ds_renderer_render_expected (renderer, &req, &error);
      g_assert_no_error (error);
      /* clipped as the sensor clips, at its full well or its top code, whichever comes first:
       * saturated stripes are no stripes */
      double clip = MIN (floor (ds_scene_system_gain (scene) * ds_scene_spec (scene)->full_well_e + 0.5),
                         (double) ((1u << ds_scene_bit_depth (scene)) - 1));
      for (guint y = 0; y < expected->height; y++) {
        float *row = ds_image_row (expected, y);
        for (guint x = 0; x < expected->width; x++)
          row[x] = (float) CLAMP (row[x], 0.0, clip);
      }
      DsStripePhase sp;
      g_assert_true (ds_stripe_phase_measure (expected, ds_scene_period_px (scene), NULL, &sp, NULL));
      sigma_c = pixel_sigma * sqrt (2.0 / ((double) rows * sp.columns_used));
      weakest = MIN (weakest, sp.amplitude / sigma_c);
    }
    if (!(weakest >= 10.0)) {
      g_test_message ("%s: its stripes stand %.1f noise sigmas out at the weakest phase: not verifiable, not run",
                      what, weakest);
      t->no_stripes_scenes++;
      for (guint k = 0; k < n; k++)
        ds_image_free (s.light[k]);
      return;
    }
  }
  Tally before = *t;
  DsPhaseCheck c;
  ds_phase_check_init (&c, ds_scene_period_px (scene), ds_phase_check_default_tolerance_deg (n));
  ds_phase_check_set_pattern (&c, !ds_scene_pattern_is_sine (scene), ds_scene_duty (scene));
  for (guint i = 0; i < 3; i++)
    correct_set (&c, &s, t);
  /* Later sets (against the last set's frames), then first sets (checked as a whole). */
  guint ats[] = { 0, 1 + g_rand_int_range (r, 0, (gint32) n - 1) };
  for (guint whole = 0; whole < 2; whole++)
    for (guint ai = 0; ai < G_N_ELEMENTS (ats); ai++)
      for (int dir = -1; dir <= 2; dir++) {
        if (whole)
          ds_phase_check_abandon (&c);
        else
          correct_set (&c, &s, t); /* templates again */
        wrong_set (&c, &s, ats[ai], dir, t);
      }
  g_test_message ("%s: %u of %u correct frames unverified, %u taken again, %u false refusals; %u trials: %u caught, "
                  "%u cannot verify, %u missed; illuminator off: %u of %u caught",
                  what, t->unverified_frames - before.unverified_frames, t->frames - before.frames,
                  t->retried_frames - before.retried_frames, t->false_refusals - before.false_refusals,
                  t->trials - before.trials, t->caught - before.caught, t->cannot_verify - before.cannot_verify,
                  t->missed - before.missed, t->blank_caught - before.blank_caught,
                  t->blank_trials - before.blank_trials);
  g_clear_pointer (&s.last, ds_image_free);
  for (guint k = 0; k < n; k++)
    ds_image_free (s.light[k]);
  t->scenes++;
}

static guint64 test_first = 1, test_count = 50;

static void
test_generated (void)
{
  Tally t = { 0 };
  for (guint64 seed = test_first; seed < test_first + test_count; seed++)
    run_scene (seed, &t);
  guint verifiable = t.trials - t.cannot_verify;
  g_test_message ("seeds %" G_GUINT64_FORMAT "-%" G_GUINT64_FORMAT ", generator 2: %u scenes, %u sets, %u correct "
                  "frames: %u false refusals, %u taken again, %u frames and %u sets unverified; %u wrong-frame "
                  "trials: %u caught, %u cannot verify, %u missed (%.2f %% of the verifiable ones); illuminator "
                  "off: %u of %u caught; %u scenes without stripes 10 noise sigmas out at every phase, not run",
                  test_first, test_first + test_count - 1, t.scenes, t.sets, t.frames, t.false_refusals,
                  t.retried_frames, t.unverified_frames, t.unverified_sets, t.trials, t.caught, t.cannot_verify,
                  t.missed, verifiable ? 100.0 * t.missed / verifiable : 0.0, t.blank_caught, t.blank_trials,
                  t.no_stripes_scenes);
  g_assert_cmpuint (t.false_refusals, ==, 0);
  g_assert_cmpfloat (t.missed, <=, MISS_BOUND * verifiable);
  g_assert_cmpuint (t.blank_caught, ==, t.blank_trials);
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  /* test_phase_check_scenes [FIRST_SEED [COUNT]]: the generator's (version 2) scene 0 of the
   * seeds FIRST_SEED to FIRST_SEED + COUNT - 1. */
  if (argc > 1)
    test_first = g_ascii_strtoull (argv[1], NULL, 10);
  if (argc > 2)
    test_count = g_ascii_strtoull (argv[2], NULL, 10);
  g_test_add_func ("/phase-check/generated-scenes", test_generated);
  return g_test_run ();
}
