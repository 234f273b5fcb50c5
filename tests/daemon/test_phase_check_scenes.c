/* The per-frame phase check (proc/phase_check.c) on scenes the project's generator draws
 * (daemon/ctl/scene_gen.c, `descatterctl generate-scenes`), widened here to what labs have:
 * sine and square stripes of any duty (0.2-0.8), periods from 2.5 px, black levels up to 0.4,
 * 8- to 16-bit sensors, N from 2 to 16 and a quarter of the scenes in dim light (its media reach
 * g = 0.95 already).
 * Every frame is rendered by the scene simulator (drivers/sim: the light of each phase once,
 * then the sensor's noise per frame), so the expectation is the simulator's: the frame was
 * lit with the phase it is labelled with, or, in the trials, with the phase next to it.
 *
 * Asserted over all scenes:
 * - no false refusal: every correct frame of three sets (the first checked as a whole, the
 *   others against the last set) is OK or "cannot verify", and every set is confirmed;
 * - a frame one step wrong (it shows phase k - 1 or k + 1) or a repeated frame (the buffer of
 *   the frame before it again) is caught, in a first set and in a later one, except where the
 *   check said "cannot verify" (counted apart); the misses stay below MISS_BOUND.
 * The counts are printed (--verbose); docs/reliability.md, "Phase check", states them. */
#include <glib.h>
#include <math.h>
#include <string.h>

#include "daemon/ctl/scene_gen.h"
#include "drivers/sim/renderer.h"
#include "drivers/sim/scene.h"
#include "proc/phase_check.h"

/* Misses (a wrong frame accepted where the check claimed it could tell) allowed, as a share of
 * the trials that were verifiable. */
#define MISS_BOUND 0.02

typedef struct {
  guint scenes, frames, sets, false_refusals, unverified_frames, unverified_sets;
  guint trials, caught, missed, cannot_verify;
} Tally;

static double
uniform (GRand *r, double lo, double hi)
{
  return lo + (hi - lo) * g_rand_double (r);
}

/* The generator's scene with the draw widened where it is narrower than labs are (it is being
 * widened itself; the values drawn here are the ranges). */
static char *
widen (const char *text, GRand *r, guint *n_phases)
{
  g_autoptr (GKeyFile) kf = g_key_file_new ();
  g_assert_true (g_key_file_load_from_data (kf, text, (gsize) -1, G_KEY_FILE_NONE, NULL));
  gboolean sine = g_rand_boolean (r);
  double period = round (4 * exp (uniform (r, log (2.5), log (24)))) / 4;
  g_key_file_set_string (kf, "illuminator", "pattern", sine ? "sine" : "square");
  g_key_file_set_double (kf, "illuminator", "period-px", period);
  if (sine)
    g_key_file_remove_key (kf, "illuminator", "duty", NULL);
  else
    g_key_file_set_double (kf, "illuminator", "duty", uniform (r, 0.2, 0.8));
  if (g_rand_boolean (r))
    g_key_file_set_double (kf, "illuminator", "black-level", uniform (r, 0, 0.4));
  if (g_key_file_has_key (kf, "illuminator", "edge-blur-px", NULL))
    g_key_file_set_double (kf, "illuminator", "edge-blur-px",
                           MIN (g_key_file_get_double (kf, "illuminator", "edge-blur-px", NULL), period / 6));
  /* The medium is the generator's: g up to 0.95 already, and its kernels cached by the draw. */
  /* Another ADC: the same electrons, the gain scaled to the new range. */
  guint bits_was = (guint) g_key_file_get_integer (kf, "sensor", "bit-depth", NULL);
  guint bits = (guint) g_rand_int_range (r, 8, 17);
  double gain = g_key_file_get_double (kf, "sensor", "system-gain", NULL);
  g_key_file_set_integer (kf, "sensor", "bit-depth", (gint) bits);
  g_key_file_set_double (kf, "sensor", "system-gain", gain * ((1u << bits) - 1) / ((1u << bits_was) - 1));
  static const guint phases[] = { 2, 3, 4, 6, 8, 12, 16 };
  *n_phases = phases[g_rand_int_range (r, 0, G_N_ELEMENTS (phases))];
  return g_key_file_to_data (kf, NULL, NULL);
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
    DsPhaseVerdict v = send (c, s, expose (s, k), k, &why);
    t->frames++;
    if (v == DS_PHASE_VERDICT_WRONG) {
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

/* One set whose frame for phase `at` is wrong: shows at + dir (dir +-1), or repeats the frame
 * sent before it (dir 0). Caught when a frame of the set is refused or the set is not
 * confirmed; a wrong frame accepted while some frame of the set could not be verified is a
 * "cannot verify", not a miss. */
static void
wrong_set (DsPhaseCheck *c, Scene *s, guint at, int dir, Tally *t)
{
  g_autofree char *why = NULL;
  gboolean caught = FALSE, unverified = FALSE;
  ds_phase_check_begin_set (c);
  for (guint k = 0; k < s->n && !caught; k++) {
    DsImage *img = k != at ? expose (s, k) : dir == 0 && s->last ? s->last : expose (s, (k + s->n + dir) % s->n);
    DsPhaseVerdict v = send (c, s, img, k, &why);
    caught = v == DS_PHASE_VERDICT_WRONG;
    unverified |= v == DS_PHASE_VERDICT_UNVERIFIABLE;
  }
  g_clear_pointer (&why, g_free);
  guint64 sets_unverified = c->sets_unverified;
  if (!caught && !ds_phase_check_confirm (c, &why))
    caught = TRUE;
  unverified |= c->sets_unverified > sets_unverified;
  if (caught)
    ds_phase_check_abandon (c);
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
run_scene (guint64 seed, guint index, Tally *t)
{
  g_autoptr (GError) error = NULL;
  /* version 1, widened here as the test states (version 2 draws as wide itself) */
  g_autofree char *drawn = ds_scene_generate (seed, index, 1, &error);
  g_assert_no_error (error);
  g_autoptr (GRand) r = g_rand_new_with_seed_array ((const guint32[]){ (guint32) seed, index, 36 }, 3);
  guint n = 0;
  g_autofree char *text = widen (drawn, r, &n);
  g_autofree char *name = g_strdup_printf ("scene %" G_GUINT64_FORMAT "-%u", seed, index);
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
              .seed = seed * 1000003u + index * 7919u, .name = what };
  for (guint k = 0; k < n; k++) {
    DsRenderRequest req = { .phase = k, .n_phases = n, .illuminator_on = TRUE, .exposure_us = s.exposure_us };
    s.light[k] = ds_renderer_render_photons (s.renderer, &req, &error);
    g_assert_no_error (error);
  }
  Tally before = *t;
  DsPhaseCheck c;
  ds_phase_check_init (&c, ds_scene_period_px (scene), ds_phase_check_default_tolerance_deg (n));
  for (guint i = 0; i < 3; i++)
    correct_set (&c, &s, t);
  /* Later sets (against the last set's frames), then first sets (checked as a whole). */
  guint ats[] = { 0, 1 + g_rand_int_range (r, 0, (gint32) n - 1) };
  for (guint whole = 0; whole < 2; whole++)
    for (guint ai = 0; ai < G_N_ELEMENTS (ats); ai++)
      for (int dir = -1; dir <= 1; dir++) {
        if (whole)
          ds_phase_check_abandon (&c);
        else
          correct_set (&c, &s, t); /* templates again */
        wrong_set (&c, &s, ats[ai], dir, t);
      }
  g_test_message ("%s: %u of %u correct frames unverified, %u false refusals; %u trials: %u caught, %u cannot verify, "
                  "%u missed",
                  what, t->unverified_frames - before.unverified_frames, t->frames - before.frames,
                  t->false_refusals - before.false_refusals, t->trials - before.trials, t->caught - before.caught,
                  t->cannot_verify - before.cannot_verify, t->missed - before.missed);
  g_clear_pointer (&s.last, ds_image_free);
  for (guint k = 0; k < n; k++)
    ds_image_free (s.light[k]);
  t->scenes++;
}

static guint64 test_seed = 36036;
static guint test_scenes = 40, test_first = 0;

static void
test_generated (void)
{
  Tally t = { 0 };
  for (guint i = test_first; i < test_first + test_scenes; i++)
    run_scene (test_seed, i, &t);
  guint verifiable = t.trials - t.cannot_verify;
  g_test_message ("%u scenes, %u sets, %u correct frames: %u false refusals, %u frames and %u sets unverified; "
                  "%u wrong-frame trials: %u caught, %u cannot verify, %u missed (%.2f %% of the verifiable ones)",
                  t.scenes, t.sets, t.frames, t.false_refusals, t.unverified_frames, t.unverified_sets, t.trials, t.caught,
                  t.cannot_verify, t.missed, verifiable ? 100.0 * t.missed / verifiable : 0.0);
  g_assert_cmpuint (t.false_refusals, ==, 0);
  g_assert_cmpfloat (t.missed, <=, MISS_BOUND * verifiable);
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  /* test_phase_check_scenes [SEED [SCENES [FIRST]]]: another draw, or a part of one (the
   * generator's indices FIRST to FIRST + SCENES - 1). */
  if (argc > 1)
    test_seed = g_ascii_strtoull (argv[1], NULL, 10);
  if (argc > 2)
    test_scenes = (guint) g_ascii_strtoull (argv[2], NULL, 10);
  if (argc > 3)
    test_first = (guint) g_ascii_strtoull (argv[3], NULL, 10);
  g_test_add_func ("/phase-check/generated-scenes", test_generated);
  return g_test_run ();
}
