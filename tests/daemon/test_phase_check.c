/* The daemon's per-frame phase check (proc/phase_check.c) on synthetic frames whose
 * stripe phase is known in closed form: the stripes are a Fourier series (sine: one term;
 * square of duty D: 2 sin(pi m D) / (pi m) per harmonic m), integrated over a 1-px pixel (a
 * factor sinc(m/P)) and blurred by a Gaussian (exp(-2 pi^2 s^2 m^2 / P^2)), lit onto an
 * object, plus scattered light and Gaussian noise. The sweep covers pattern, duty, period, N,
 * blur, heavy scattering and an object whose texture sits exactly at the stripe period (a grid
 * of pitch 2P: the case that made correct frames fail), and asserts:
 * - no correct frame is rejected: not in the first set (checked as a whole), not in a later one
 *   (checked frame by frame against the last set), not after the scene changed;
 * - the learned offset is the rendered one;
 * - a frame one step wrong (stale: the previous phase; early: the next one) is caught wherever
 *   it falls in the set, including the set's first frame;
 * - a frame too noisy to tell the phases apart is unverifiable, not wrong.
 * Each sweep runs every scenario (528 each: 1056 in all, about 25 s of CPU; the noise comes from
 * a bank of deviates drawn once, which made the whole sweep cheaper than half of it was). */
#include <glib.h>
#include <math.h>
#include <stdlib.h>

#include "proc/phase_check.h"
#include "proc/stripe_phase.h"

#define W 256
#define H 32

typedef struct {
  gboolean square;
  double duty, period, blur, offset;
  double direct, scattered; /* DN */
  guint grid_pitch;         /* 0: no object */
  guint grid_shift;
  double noise_scale; /* sigma = noise_scale * sqrt(signal) */
} Scene;

/* The stripes at pixel centre x, phase k of n, as the pixel sees them (0..1). Unblurred square
 * stripes: the overlap of the pixel [x - 1/2, x + 1/2] with the lit intervals, exactly;
 * blurred: the Fourier series until the blur has taken the harmonics below 1e-9. */
static double
stripe (const Scene *s, double x, guint k, guint n)
{
  double centre = ((double) k / n + s->offset) * s->period;
  if (s->square && s->blur == 0) {
    double half = 0.5 * s->duty * s->period, lit = 0;
    double j0 = floor ((x - 0.5 - centre - half) / s->period);
    for (double j = j0; (j * s->period + centre - half) < x + 0.5; j++) {
      double a = MAX (x - 0.5, j * s->period + centre - half), b = MIN (x + 0.5, j * s->period + centre + half);
      lit += MAX (0.0, b - a);
    }
    return lit;
  }
  double u = x / s->period - ((double) k / n + s->offset);
  double v = s->square ? s->duty : 0.5;
  for (int m = 1; m <= (s->square ? 1000 : 1); m++) {
    double f = m / s->period; /* cycles per pixel */
    double g = exp (-2.0 * G_PI * G_PI * s->blur * s->blur * f * f);
    if (g < 1e-9)
      break;
    double sinc = sin (G_PI * f) / (G_PI * f);
    double amp = s->square ? 2.0 * sin (G_PI * m * s->duty) / (G_PI * m) : 0.5;
    v += amp * sinc * g * cos (2.0 * G_PI * m * u);
  }
  return v;
}

static double
object (const Scene *s, guint x, guint y)
{
  if (s->grid_pitch == 0)
    return 1.0;
  guint px = (x + s->grid_shift) % s->grid_pitch, py = (y + s->grid_shift) % s->grid_pitch;
  return (px < 3 || py < 3) ? 0.05 : 1.0;
}

/* Gaussian deviates: a bank of 2^21 drawn once by Box-Muller, read from a random offset per row
 * (2^21 against the 8192 a frame needs: rows of two frames rarely share deviates). Drawing
 * each pixel's deviate afresh took three quarters of the test's time. */
#define BANK_BITS 21
#define BANK_MASK ((1u << BANK_BITS) - 1)
static double *bank;

static void
bank_init (void)
{
  GRand *rng = g_rand_new_with_seed (3);
  bank = g_new (double, 1u << BANK_BITS);
  for (guint i = 0; i < (1u << BANK_BITS); i += 2) {
    double r = sqrt (-2.0 * log (g_rand_double_range (rng, 1e-12, 1.0))), t = 2.0 * G_PI * g_rand_double (rng);
    bank[i] = r * cos (t);
    bank[i + 1] = r * sin (t);
  }
  g_rand_free (rng);
}

static DsImage *
render (const Scene *s, guint k, guint n, double scale, GRand *rng)
{
  DsImage *img = ds_image_new (DS_SAMPLE_U16, W, H, NULL);
  img->bit_depth = 12;
  double profile[W];
  for (guint x = 0; x < W; x++)
    profile[x] = stripe (s, x, k, n);
  for (guint y = 0; y < H; y++) {
    guint16 *row = ds_image_row (img, y);
    guint32 at = g_rand_int (rng);
    for (guint x = 0; x < W; x++) {
      double t = object (s, x, y);
      double v = scale * (s->direct * t * profile[x] + s->scattered * (0.5 + 0.5 * t));
      v += s->noise_scale * sqrt (MAX (v, 1.0)) * bank[(at + x) & BANK_MASK];
      /* rounded to the nearest DN (halves up) and clipped to 12 bits */
      row[x] = (guint16) floor (CLAMP (v, 0.0, 4095.0) + 0.5);
    }
  }
  return img;
}

static DsPhaseVerdict
check (DsPhaseCheck *c, const Scene *s, guint shows, guint as, guint n, double scale, GRand *rng, char **why)
{
  g_autoptr (DsImage) img = render (s, shows, n, scale, rng);
  double measured;
  g_clear_pointer (why, g_free);
  return ds_phase_check_frame (c, img, as, n, &measured, why);
}

/* A whole set of correct frames: every one OK or unverified (it passes: the caller folds it),
 * and the set confirmed. A refused frame (WRONG or NO_STRIPES) is taken again, as the
 * sequencer does (phase k applied afresh, a new exposure), up to RETRIES times: refused on
 * every try is a false rejection; refused once, then passed, a retry (counted: the check may
 * refuse the second frame of a first set that repeats the first within the noise until the
 * retry shows the scene moves its stripes that little). */
#define RETRIES 3
static guint unverified_frames, retried_frames;

static guint
correct_set (DsPhaseCheck *c, const Scene *s, guint n, double scale, GRand *rng, const char *what)
{
  guint rejected = 0;
  g_autofree char *why = NULL;
  ds_phase_check_begin_set (c);
  for (guint k = 0; k < n; k++) {
    DsPhaseVerdict v = DS_PHASE_VERDICT_WRONG;
    for (guint t = 0; t <= RETRIES && (v == DS_PHASE_VERDICT_WRONG || v == DS_PHASE_VERDICT_NO_STRIPES); t++) {
      if (t > 0) {
        retried_frames++;
        g_test_message ("%s: correct frame %u of %u refused, taken again: %s", what, k, n, why);
      }
      v = check (c, s, k, k, n, scale, rng, &why);
    }
    unverified_frames += v == DS_PHASE_VERDICT_UNVERIFIABLE;
    if (v == DS_PHASE_VERDICT_WRONG || v == DS_PHASE_VERDICT_NO_STRIPES) {
      g_test_message ("%s: correct frame %u of %u rejected: %s", what, k, n, why);
      rejected++;
    }
  }
  g_clear_pointer (&why, g_free);
  if (rejected > 0) {
    ds_phase_check_abandon (c); /* the set failed, as the sequencer ends it */
    return rejected;
  }
  if (!ds_phase_check_confirm (c, &why)) {
    g_test_message ("%s: correct set rejected: %s", what, why);
    rejected++;
  }
  return rejected;
}

/* A set with the frame for phase `at` showing `shows`: caught at that frame (refused: WRONG or
 * NO_STRIPES), or the
 * set fails as a whole (1). A frame refused is replaced by a correct one, as the sequencer
 * does; one accepted or passed unverified stays. Not caught: -1 when the check said it could
 * not verify some frame or the set, else 0 (a miss). */
static int
wrong_frame_caught (DsPhaseCheck *c, const Scene *s, guint n, guint at, guint shows, GRand *rng, const char *what)
{
  g_autofree char *why = NULL;
  gboolean caught = FALSE, unverified = FALSE;
  ds_phase_check_begin_set (c);
  for (guint k = 0; k < n; k++) {
    if (k == at) {
      DsPhaseVerdict v = check (c, s, shows, k, n, 1.0, rng, &why);
      unverified |= v == DS_PHASE_VERDICT_UNVERIFIABLE;
      if (v != DS_PHASE_VERDICT_WRONG && v != DS_PHASE_VERDICT_NO_STRIPES)
        continue; /* the set goes on with it */
      caught = TRUE;
    }
    DsPhaseVerdict v = check (c, s, k, k, n, 1.0, rng, &why);
    caught |= v == DS_PHASE_VERDICT_WRONG || v == DS_PHASE_VERDICT_NO_STRIPES;
    unverified |= v == DS_PHASE_VERDICT_UNVERIFIABLE;
  }
  g_clear_pointer (&why, g_free);
  guint64 sets_unverified = c->sets_unverified;
  if (!ds_phase_check_confirm (c, &why))
    caught = TRUE;
  unverified |= c->sets_unverified > sets_unverified;
  if (!caught && unverified)
    g_test_message ("%s: frame for phase %u showing phase %u: cannot verify", what, at, shows);
  return caught ? 1 : unverified ? -1 : 0;
}

static void
test_sweep (gconstpointer data)
{
  gboolean templates_off = GPOINTER_TO_INT (data);
  static const struct {
    gboolean square;
    double duty;
  } patterns[] = { { FALSE, 0.5 }, { TRUE, 0.25 }, { TRUE, 0.5 }, { TRUE, 0.75 } };
  static const double periods[] = { 4, 6, 8, 12, 16, 24 };
  static const guint phases[] = { 4, 8, 16 };
  static const double blurs[] = { 0, 1.5 };
  GRand *rng = g_rand_new_with_seed (11);
  guint scenarios = 0, false_rejects = 0, missed = 0, wrong_tested = 0, moved_once = 0, cannot_verify = 0;
  unverified_frames = retried_frames = 0;
  for (guint pi = 0; pi < G_N_ELEMENTS (patterns); pi++)
    for (guint qi = 0; qi < G_N_ELEMENTS (periods); qi++)
      for (guint ni = 0; ni < G_N_ELEMENTS (phases); ni++)
        for (guint bi = 0; bi < G_N_ELEMENTS (blurs); bi++)
          for (guint heavy = 0; heavy < 2; heavy++)
            for (guint grid = 0; grid < 2; grid++) {
              guint n = phases[ni];
              double p = periods[qi];
              /* A 1-px stripe blurred by 1.5 px is gone: no scene projects that. */
              if (p < 8 && blurs[bi] > 0 && heavy)
                continue;
              Scene s = { .square = patterns[pi].square, .duty = patterns[pi].duty, .period = p,
                          .blur = blurs[bi], .offset = 0.137, .direct = heavy ? 500 : 2000,
                          .scattered = heavy ? 3000 : 200, .grid_pitch = grid ? (guint) (2 * p) : 0,
                          .noise_scale = 0.5 };
              g_autofree char *what = g_strdup_printf ("%s duty %.2f period %.0f N %u blur %.1f %s%s",
                                                       s.square ? "square" : "sine", s.duty, p, n, s.blur,
                                                       heavy ? "heavy scattering" : "clear",
                                                       grid ? ", grid at the stripe period" : "");
              scenarios++;
              DsPhaseCheck c;
              ds_phase_check_init (&c, p, ds_phase_check_default_tolerance_deg (n));
              guint rejected = correct_set (&c, &s, n, 1.0, rng, what);
              /* The offset the first set learned is the rendered one (an eighth of a step:
               * square stripes' harmonics that alias onto bin 1 move it a little), unless the
               * set said it could not tell its phases apart (then it learns nothing). */
              double off_err = fabs (remainder (c.offset_cycles - s.offset, 1.0));
              if (c.sets_unverified == 0 && (!c.offset_known || off_err > 0.125 / n)) {
                g_test_message ("%s: learned offset %.4f, rendered %.4f", what, c.offset_cycles, s.offset);
                rejected++;
              }
              /* Later sets: frame by frame against the templates, at another exposure. */
              rejected += correct_set (&c, &s, n, 0.8, rng, what);
              rejected += correct_set (&c, &s, n, 1.0, rng, what);
              if (templates_off) {
                /* The scene moves under the templates: the set's first frame may still look
                 * like its template, and a later one then fails the set once (the templates
                 * are dropped with it); the next set is checked as a whole: no deadlock. */
                Scene moved = s;
                moved.grid_shift = 5;
                guint retried_before = retried_frames;
                if (correct_set (&c, &moved, n, 1.0, rng, what) > 0) {
                  retried_frames = retried_before; /* that set's frames fail by design */
                  g_test_message ("%s: the set after the move failed (allowed once)", what);
                  moved_once++;
                }
                rejected += correct_set (&c, &moved, n, 1.0, rng, what);
                rejected += correct_set (&c, &moved, n, 1.0, rng, what);
              }
              if (rejected)
                g_test_message ("%s: %u correct sets rejected", what, rejected);
              false_rejects += rejected ? 1 : 0;
              /* One step wrong at the first, a middle and the last frame: stale (shows the
               * previous phase) and early (shows the next). */
              guint at[] = { 0, n / 2, n - 1 };
              for (guint ai = 0; ai < G_N_ELEMENTS (at); ai++)
                for (int dir = -1; dir <= 1; dir += 2) {
                  guint shows = (at[ai] + n + dir) % n;
                  if (templates_off)
                    ds_phase_check_abandon (&c);
                  wrong_tested++;
                  int got = wrong_frame_caught (&c, &s, n, at[ai], shows, rng, what);
                  cannot_verify += got < 0;
                  if (got == 0) {
                    g_test_message ("%s: frame for phase %u showing phase %u not caught%s", what, at[ai], shows,
                                    templates_off ? " (checked as a whole)" : "");
                    missed++;
                  }
                  if (templates_off)
                    ds_phase_check_abandon (&c);
                  correct_set (&c, &s, n, 1.0, rng, what); /* templates again for the next case */
                }
            }
  g_rand_free (rng);
  g_test_message ("%u scenarios: %u with a false rejection, %u correct frames unverified, %u taken again; %u of %u "
                  "one-step errors missed, %u cannot verify; a set lost to the scene moving in %u",
                  scenarios, false_rejects, unverified_frames, retried_frames, missed, wrong_tested, cannot_verify,
                  moved_once);
  g_assert_cmpuint (false_rejects, ==, 0);
  g_assert_cmpuint (missed, ==, 0);
}

/* Stripes drowned in noise: the check never calls a frame wrong. A frame whose stripes stand out
 * of the noise but cannot tell the phases apart passes unverified; one without measurable stripes
 * in a first set, where nothing shows that the scene hides the projected stripes, is refused as
 * showing none (NO_STRIPES), never as another phase. */
static void
test_too_noisy (void)
{
  Scene s = { .period = 12, .offset = 0.3, .direct = 20, .scattered = 3000, .noise_scale = 2.0 };
  GRand *rng = g_rand_new_with_seed (5);
  DsPhaseCheck c;
  ds_phase_check_init (&c, s.period, ds_phase_check_default_tolerance_deg (16));
  ds_phase_check_begin_set (&c);
  g_autofree char *why = NULL;
  guint unverifiable = 0, none = 0;
  for (guint k = 0; k < 16; k++) {
    DsPhaseVerdict v = check (&c, &s, k, k, 16, 1.0, rng, &why);
    g_assert_cmpint (v, !=, DS_PHASE_VERDICT_WRONG);
    g_assert_cmpint (v, !=, DS_PHASE_VERDICT_OK);
    unverifiable += v == DS_PHASE_VERDICT_UNVERIFIABLE;
    none += v == DS_PHASE_VERDICT_NO_STRIPES;
  }
  g_test_message ("%u unverifiable, %u without stripes", unverifiable, none);
  g_assert_cmpuint (unverifiable + none, ==, 16);
  g_assert_nonnull (strstr (why, "too weak") ? why : strstr (why, "no stripes"));
  g_rand_free (rng);
}

/* A repeat of the previous phase's frame is caught even where the phase alone could not tell:
 * in the first set (no offset, no templates). */
static void
test_repeat_in_first_set (void)
{
  Scene s = { .period = 16, .offset = 0.6, .direct = 2000, .scattered = 200, .grid_pitch = 32, .noise_scale = 0.5 };
  GRand *rng = g_rand_new_with_seed (7);
  DsPhaseCheck c;
  ds_phase_check_init (&c, s.period, ds_phase_check_default_tolerance_deg (8));
  ds_phase_check_begin_set (&c);
  g_autofree char *why = NULL;
  g_assert_cmpint (check (&c, &s, 0, 0, 8, 1.0, rng, &why), ==, DS_PHASE_VERDICT_OK);
  g_assert_cmpint (check (&c, &s, 1, 1, 8, 1.0, rng, &why), ==, DS_PHASE_VERDICT_OK);
  g_assert_cmpint (check (&c, &s, 1, 2, 8, 1.0, rng, &why), ==, DS_PHASE_VERDICT_WRONG);
  g_test_message ("%s", why);
  g_assert_nonnull (strstr (why, "looks like phase 1"));
  g_rand_free (rng);
}

/* The pixel noise read from integer frames equals the definition computed another way: every
 * difference of the sampled row pairs in doubles with its pair's level, the levels sorted to
 * find the quartile bounds, each quartile class's differences sorted and the element at half
 * its count scaled to a Gaussian's sigma, the classes' variances averaged over the pairs (at
 * least the quantisation's). Frames of u8 and u16, widths that do and do not divide into the
 * sampled columns, differences up to 65535 and Gaussian noise whose sigma the estimate must
 * find within its 1.4 % (and 2 % for the sampling). */
static int
cmp_double (const void *a, const void *b)
{
  double x = *(const double *) a, y = *(const double *) b;
  return (x > y) - (x < y);
}

static double
reference_noise (const DsImage *f)
{
  guint pairs = MIN (32u, f->height / 2);
  guint xstep = MAX (1u, f->width / 256u);
  GArray *d = g_array_new (FALSE, FALSE, sizeof (double)), *lv = g_array_new (FALSE, FALSE, sizeof (double));
  for (guint i = 0; i < pairs; i++) {
    guint y = (guint) (((guint64) i * (f->height - 1)) / pairs);
    for (guint x = 0; x < f->width; x += xstep) {
      double a = ds_image_sample (f, ds_image_row (f, y), x), b = ds_image_sample (f, ds_image_row (f, y + 1), x);
      double v = fabs (b - a), l = a + b;
      g_array_append_val (d, v);
      g_array_append_val (lv, l);
    }
  }
  guint n = d->len;
  double *sorted = g_memdup2 (lv->data, n * sizeof (double));
  qsort (sorted, n, sizeof (double), cmp_double);
  double bound[4];
  for (guint j = 1; j < 4; j++)
    bound[j] = sorted[j * n / 4];
  g_free (sorted);
  double sum = 0;
  for (guint cls = 0; cls < 4; cls++) {
    GArray *in = g_array_new (FALSE, FALSE, sizeof (double));
    for (guint i = 0; i < n; i++) {
      double l = g_array_index (lv, double, i);
      guint of = (l >= bound[1]) + (l >= bound[2]) + (l >= bound[3]);
      if (of == cls)
        g_array_append_val (in, g_array_index (d, double, i));
    }
    if (in->len > 0) {
      qsort (in->data, in->len, sizeof (double), cmp_double);
      double s = g_array_index (in, double, in->len / 2) / (0.6745 * G_SQRT2);
      sum += s * s * in->len;
    }
    g_array_unref (in);
  }
  g_array_unref (d);
  g_array_unref (lv);
  return MAX (sqrt (sum / n), 1.0 / sqrt (12.0));
}

/* Signal-dependent noise (shot noise): half the pixels dark with read noise 1 DN, half bright
 * with 20 DN. The first harmonic's noise is the mean variance, sqrt((1 + 400) / 2) = 14.2 DN;
 * the median difference of all pixels would say about 6. */
static void
test_pixel_noise_shot (void)
{
  g_autoptr (DsImage) f = ds_image_new (DS_SAMPLE_F32, 512, 128, NULL);
  for (guint y = 0; y < f->height; y++) {
    float *row = ds_image_row (f, y);
    for (guint x = 0; x < f->width; x++) {
      gboolean lit = (x / 4) % 2;
      row[x] = (float) ((lit ? 3000 : 100) + (lit ? 20.0 : 1.0) * bank[(y * f->width + x) & BANK_MASK]);
    }
  }
  double got = ds_phase_check_pixel_noise (f), want = sqrt ((1.0 + 400.0) / 2.0);
  g_test_message ("noise %.2f DN, mean variance's sigma %.2f", got, want);
  g_assert_cmpfloat (fabs (got / want - 1.0), <, 0.05);
}

static void
test_pixel_noise_integer (void)
{
  GRand *rng = g_rand_new_with_seed (11);
  static const guint sizes[][2] = { { 1024, 1024 }, { 1000, 77 }, { 300, 2 }, { 257, 9 }, { 64, 3 } };
  for (guint t = 0; t < 2; t++) {
    DsSampleType type = t ? DS_SAMPLE_U8 : DS_SAMPLE_U16;
    guint max = t ? 255 : 65535;
    for (guint si = 0; si < G_N_ELEMENTS (sizes); si++)
      for (guint kind = 0; kind < 3; kind++) {
        g_autoptr (DsImage) f = ds_image_new (type, sizes[si][0], sizes[si][1], NULL);
        double sigma = t ? 3.0 : 40.0;
        for (guint y = 0; y < f->height; y++)
          for (guint x = 0; x < f->width; x++) {
            double v;
            if (kind == 0) /* Gaussian noise about mid-range */
              v = max / 2.0 + sigma * bank[(y * f->width + x) & BANK_MASK];
            else if (kind == 1) /* uniform over the whole range: differences up to max */
              v = g_rand_int_range (rng, 0, (gint32) max + 1);
            else /* the extremes only */
              v = g_rand_boolean (rng) ? max : 0;
            v = CLAMP (round (v), 0, max);
            if (t)
              ((guint8 *) ds_image_row (f, y))[x] = (guint8) v;
            else
              ((guint16 *) ds_image_row (f, y))[x] = (guint16) v;
          }
        double got = ds_phase_check_pixel_noise (f), want = reference_noise (f);
        g_assert_cmpfloat (got, ==, want);
        if (kind == 0 && f->height >= 64)
          g_assert_cmpfloat (fabs (got / sigma - 1.0), <, 0.05);
      }
  }
  g_autoptr (DsImage) one_row = ds_image_new (DS_SAMPLE_U16, 16, 1, NULL);
  g_assert_true (isinf (ds_phase_check_pixel_noise (one_row)));
  g_rand_free (rng);
}

/* The pattern's bend (ds_phase_check_pattern_bend) against a reference written differently: a
 * direct DFT at the period over whole periods of the square pattern, each pixel the lit share
 * of its width in closed form (the overlap of the pixel with the lit intervals), where the fit
 * the check uses reduces to that DFT (an integer period, over whole periods). Sine stripes
 * have no harmonic to fold and no bend. */
static double
lit_share (double duty, double period, double phi, guint x)
{
  /* the lit intervals [c - duty P / 2, c + duty P / 2] around the centres c = (j + phi) P */
  double lo = x - 0.5, hi = x + 0.5, lit = 0;
  for (int j = (int) floor (lo / period - phi) - 1; j <= (int) ceil (hi / period - phi) + 1; j++) {
    double c = (j + phi) * period, a = MAX (lo, c - duty * period / 2), b = MIN (hi, c + duty * period / 2);
    lit += MAX (0.0, b - a);
  }
  return lit;
}

static double
reference_bend (double duty, guint period, guint width, guint n)
{
  double worst = 0;
  for (guint o = 0; o < 8; o++) {
    double prev = NAN;
    for (guint h = 0; h <= n; h++) {
      double phi = (double) o / (8.0 * n) + (double) (h % n) / n, re = 0, im = 0;
      for (guint x = 0; x < width / period * period; x++) { /* whole periods, as the fit takes */
        double v = lit_share (duty, period, phi, x);
        re += v * cos (2.0 * G_PI * x / period);
        im += v * sin (2.0 * G_PI * x / period);
      }
      double ph = atan2 (im, re) / (2.0 * G_PI);
      if (h > 0) {
        double d = ph - prev - 1.0 / n;
        d -= floor (d + 0.5);
        worst = MAX (worst, fabs (d));
      }
      prev = ph;
    }
  }
  return worst;
}

static void
test_pattern_bend (void)
{
  g_assert_cmpfloat (ds_phase_check_pattern_bend (FALSE, 0.5, 16.0, 512, 8), <, 1e-6);
  static const struct { double duty; guint period, width, n; } cases[] = {
    { 0.65, 3, 96, 12 }, { 0.5, 6, 256, 8 }, { 0.25, 4, 128, 16 }, { 0.5, 64, 1024, 8 },
  };
  for (guint i = 0; i < G_N_ELEMENTS (cases); i++) {
    double got = ds_phase_check_pattern_bend (TRUE, cases[i].duty, cases[i].period, cases[i].width, cases[i].n);
    double ref = reference_bend (cases[i].duty, cases[i].period, cases[i].width, cases[i].n);
    g_test_message ("square P %u duty %.2f N %u: bend %.3f steps (reference %.3f)", cases[i].period, cases[i].duty,
                    cases[i].n, got * cases[i].n, ref * cases[i].n);
    g_assert_cmpfloat (fabs (got - ref) * cases[i].n, <, 1e-3);
  }
  /* At 3 px the second harmonic folds back onto the first, moving backwards, at about half its
   * size for duty 0.65 (|sin (2 pi d)| / (2 |sin (pi d)|) = 0.45 before the pixel's width): a
   * step bends by about asin of that, half a step or more at N = 12. A long period folds
   * nothing back. */
  g_assert_cmpfloat (reference_bend (0.65, 3, 96, 12) * 12, >, 0.4);
  g_assert_cmpfloat (reference_bend (0.5, 64, 1024, 8) * 8, <, 0.01);
}

/* Static texture at another period over weak stripes. The frames are written in closed form as
 * their column profile plus Gaussian pixel noise: the object's texture under the stripes' mean
 * light is the same in every frame (a strong component at TEX_PERIOD, and one at the stripe
 * period that cancels the stripes at phase N / 2 exactly: b = -a e^{i pi}), the stripes move
 * with the phase (amplitude a, 4 noise sigmas of the first harmonic: too weak to verify a
 * phase, the set is checked as a whole). The product of the stripes with the texture is left
 * out: it is not what is tested. Correct frame k shows, at the stripe period,
 * |b + a e^{i 2 pi k / N}| = 2 a sin (pi |k - N/2| / N): none at N / 2, where only the
 * texture's period stands out. Physics says every frame of the set is correct: none may be
 * refused. The same set with frame N / 2 lit by an illuminator of another period, whose stripes
 * move between phases, or lit by the ambient light alone, is not a correct set: refused. */
#define TEX_N 8
#define TEX_PERIOD 25.6
#define TEX_STRIPE_PERIOD 16.0
#define TEX_WRONG_PERIOD 21.3
#define TEX_SIGMA 64.0 /* DN per pixel: the first harmonic's noise is 64 sqrt (2 / (32 256)) = 1 DN */

typedef enum { TEX_CORRECT, TEX_WRONG_PERIOD_AT_HALF, TEX_UNLIT_AT_HALF } TexCase;

/* A 16-bit frame whose every row is `profile` (W values) plus Gaussian noise of TEX_SIGMA DN
 * per pixel (Box-Muller), rounded to the nearest DN and clipped. */
static DsImage *
noisy_frame (const double *profile, GRand *rng)
{
  DsImage *img = ds_image_new (DS_SAMPLE_U16, W, H, NULL);
  img->bit_depth = 16;
  for (guint y = 0; y < H; y++) {
    guint16 *row = ds_image_row (img, y);
    for (guint x = 0; x < W; x++) {
      double u1 = g_rand_double_range (rng, 1e-12, 1.0), u2 = g_rand_double (rng);
      double v = profile[x] + TEX_SIGMA * sqrt (-2.0 * log (u1)) * cos (2.0 * G_PI * u2);
      row[x] = (guint16) floor (CLAMP (v, 0.0, 65535.0) + 0.5);
    }
  }
  return img;
}

static DsImage *
render_texture_frame (guint k, TexCase what, GRand *rng)
{
  const double level = 2000, ambient = 500, texture = 30, a = 4, wrong = 30;
  gboolean at_half = k == TEX_N / 2;
  double light = what == TEX_UNLIT_AT_HALF && at_half ? ambient / (level + ambient) : 1.0;
  double profile[W];
  for (guint x = 0; x < W; x++) {
    /* the static part, under the light that reaches the object */
    double v = light * (level + ambient + texture * cos (2.0 * G_PI * x / TEX_PERIOD + 0.7) -
                        a * cos (2.0 * G_PI * (x / TEX_STRIPE_PERIOD - 0.5)));
    if (what == TEX_WRONG_PERIOD_AT_HALF && at_half)
      v += wrong * cos (2.0 * G_PI * (x / TEX_WRONG_PERIOD - (double) k / TEX_N));
    else if (light == 1.0)
      v += a * cos (2.0 * G_PI * (x / TEX_STRIPE_PERIOD - (double) k / TEX_N));
    profile[x] = v;
  }
  return noisy_frame (profile, rng);
}

/* One set (a first set: nothing known yet), a refused frame taken again up to 3 times as the
 * sequencer does (phase-retries' default: a correct frame's noise may hide weak stripes once);
 * TRUE when every frame passed and the set was confirmed. */
static gboolean
texture_set_passes (TexCase what, guint32 seed, char **why)
{
  GRand *rng = g_rand_new_with_seed (seed);
  DsPhaseCheck c;
  ds_phase_check_init (&c, TEX_STRIPE_PERIOD, ds_phase_check_default_tolerance_deg (TEX_N));
  ds_phase_check_set_pattern (&c, FALSE, 0.5);
  ds_phase_check_begin_set (&c);
  gboolean passed = TRUE;
  for (guint k = 0; k < TEX_N && passed; k++) {
    passed = FALSE;
    for (guint i = 0; i <= 3 && !passed; i++) {
      g_autoptr (DsImage) img = render_texture_frame (k, what, rng);
      double measured;
      g_clear_pointer (why, g_free);
      DsPhaseVerdict v = ds_phase_check_frame (&c, img, k, TEX_N, &measured, why);
      passed = v == DS_PHASE_VERDICT_OK || v == DS_PHASE_VERDICT_UNVERIFIABLE;
    }
  }
  if (passed) {
    g_clear_pointer (why, g_free);
    passed = ds_phase_check_confirm (&c, why);
  }
  g_rand_free (rng);
  return passed;
}

static void
test_static_texture (void)
{
  /* The premise, from the closed form: at phase N / 2 the frame's first harmonic at the stripe
   * period is b + a e^{i pi} = 0 while the texture's is 30 DN: only another period shows. */
  {
    GRand *rng = g_rand_new_with_seed (1);
    g_autoptr (DsImage) img = render_texture_frame (TEX_N / 2, TEX_CORRECT, rng);
    DsStripePhase at_stripes, at_texture;
    g_assert_true (ds_stripe_phase_measure (img, TEX_STRIPE_PERIOD, NULL, &at_stripes, NULL));
    g_assert_true (ds_stripe_phase_measure (img, TEX_PERIOD, NULL, &at_texture, NULL));
    g_assert_cmpfloat (at_stripes.amplitude, <, 1.0 * 5);  /* 5 noise sigmas of 1 DN */
    g_assert_cmpfloat (fabs (at_texture.amplitude - 30.0), <, 5.0);
    g_rand_free (rng);
  }
  g_autofree char *why = NULL;
  for (guint32 seed = 1; seed <= 20; seed++) {
    if (!texture_set_passes (TEX_CORRECT, seed, &why))
      g_error ("seed %u: a correct set over static texture refused: %s", seed, why);
    if (texture_set_passes (TEX_WRONG_PERIOD_AT_HALF, seed, &why))
      g_error ("seed %u: a frame lit with stripes of %.1f px instead of %.1f px passed", seed, TEX_WRONG_PERIOD,
               TEX_STRIPE_PERIOD);
    if (seed == 1)
      g_test_message ("wrong period: %s", why);
    if (texture_set_passes (TEX_UNLIT_AT_HALF, seed, &why))
      g_error ("seed %u: a frame without the illuminator's light passed", seed);
    if (seed == 1)
      g_test_message ("unlit: %s", why);
  }
}

/* A set's first frame that shows another period has nothing in the set yet to compare it
 * with: it must still be refused, by the frame's check (where the scene is expected to show
 * stripes there) or by the set's when it is complete. Stripes of 8 noise sigmas at every phase
 * (no texture at the stripe period), static texture at TEX_PERIOD. After two correct sets, a
 * set whose frame 0 is lit by an illuminator of another period (no stripes at the configured
 * one) is not a correct set: refused, when the set is complete. The correct set after it
 * passes. */
static DsImage *
render_plain_frame (guint k, gboolean wrong, GRand *rng)
{
  const double level = 2000, texture = 30, a = 8, wrong_a = 30;
  double profile[W];
  for (guint x = 0; x < W; x++) {
    double v = level + texture * cos (2.0 * G_PI * x / TEX_PERIOD + 0.7);
    v += wrong ? wrong_a * cos (2.0 * G_PI * (x / TEX_WRONG_PERIOD - (double) k / 4))
               : a * cos (2.0 * G_PI * (x / TEX_STRIPE_PERIOD - (double) k / 4));
    profile[x] = v;
  }
  return noisy_frame (profile, rng);
}

/* One set of n on `c`, frame k rendered by frame (k, data, rng), a refused frame taken again
 * up to 3 times as the sequencer does (phase-retries' default); TRUE when every frame passed
 * and the set was confirmed, else the set is abandoned, as the sequencer does; *at_confirm
 * TRUE when it was refused by ds_phase_check_confirm. */
typedef DsImage *(*FrameRender) (guint k, gconstpointer data, GRand *rng);

static gboolean
set_passes (DsPhaseCheck *c, guint n, FrameRender frame, gconstpointer data, GRand *rng, gboolean *at_confirm,
            char **why)
{
  *at_confirm = FALSE;
  ds_phase_check_begin_set (c);
  for (guint k = 0; k < n; k++) {
    gboolean passed = FALSE;
    for (guint i = 0; i <= 3 && !passed; i++) {
      g_autoptr (DsImage) img = frame (k, data, rng);
      double measured;
      g_clear_pointer (why, g_free);
      DsPhaseVerdict v = ds_phase_check_frame (c, img, k, n, &measured, why);
      passed = v == DS_PHASE_VERDICT_OK || v == DS_PHASE_VERDICT_UNVERIFIABLE;
    }
    if (!passed) {
      ds_phase_check_abandon (c);
      return FALSE;
    }
  }
  g_clear_pointer (why, g_free);
  if (ds_phase_check_confirm (c, why))
    return TRUE;
  *at_confirm = TRUE;
  ds_phase_check_abandon (c);
  return FALSE;
}

static DsImage *
plain_frame (guint k, gconstpointer wrong_first, GRand *rng)
{
  return render_plain_frame (k, *(const gboolean *) wrong_first && k == 0, rng);
}

/* One set of 4 (set_passes). */
static gboolean
plain_set_passes (DsPhaseCheck *c, gboolean wrong_first, GRand *rng, gboolean *at_confirm, char **why)
{
  return set_passes (c, 4, plain_frame, &wrong_first, rng, at_confirm, why);
}

static void
test_other_period_first_frame (void)
{
  g_autofree char *why = NULL;
  guint by_confirm = 0;
  for (guint32 seed = 1; seed <= 20; seed++) {
    GRand *rng = g_rand_new_with_seed (seed);
    DsPhaseCheck c;
    ds_phase_check_init (&c, TEX_STRIPE_PERIOD, ds_phase_check_default_tolerance_deg (4));
    ds_phase_check_set_pattern (&c, FALSE, 0.5);
    gboolean at_confirm;
    for (guint i = 0; i < 2; i++)
      if (!plain_set_passes (&c, FALSE, rng, &at_confirm, &why))
        g_error ("seed %u: correct set %u refused: %s", seed, i, why);
    if (plain_set_passes (&c, TRUE, rng, &at_confirm, &why))
      g_error ("seed %u: a first frame lit with stripes of %.1f px passed", seed, TEX_WRONG_PERIOD);
    by_confirm += at_confirm;
    if (seed == 1)
      g_test_message ("%s", why);
    if (!plain_set_passes (&c, FALSE, rng, &at_confirm, &why))
      g_error ("seed %u: the correct set after it refused: %s", seed, why);
    g_rand_free (rng);
  }
  /* The frame alone cannot tell: nothing is known of the scene at a set's first phase. Refused
   * once, its retry shows no stripes either and joins the set, whose check, complete, finds
   * the other period moving against the set's other frames (ds_phase_check_confirm). */
  g_test_message ("%u of 20 refused when the set was complete", by_confirm);
  g_assert_cmpuint (by_confirm, ==, 20);
}

/* Stripes that cancel at phase 0. The object's texture at the stripe period under the stripes'
 * mean light is b = -a: correct frame k shows b + a e^{i 2 pi k / N}, none at phase 0, the
 * set's first frame, where nothing is known yet of the scene (no set of it completed, no other
 * frame of this one), and 2 |a| sin (pi k / N) at the others, with |a| 40 noise sigmas of the
 * first harmonic. A correct set of this scene is correct, every time: it must pass, set after
 * set. Not correct sets, refused by the frame's check or the set's: frame 0 lit by the ambient
 * light alone (a twentieth of the light, the object's texture with it), frame 0 lit with phase
 * N / 2; and frame 0 lit with phase 1 (a repeat of the next frame), which the set tells where
 * it can (adjacent phases far enough apart against the noise; the retry of the repeated frame
 * shows the same light again, which the check takes for a still scene), else the set passes
 * counted unverified (sets_unverified), never as verified. */
typedef enum { CANCEL_CORRECT, CANCEL_UNLIT_FIRST, CANCEL_HALF_FIRST, CANCEL_NEXT_FIRST } CancelCase;

static DsImage *
render_cancel_frame (guint lit_as, gboolean unlit, GRand *rng)
{
  const double level = 2000, ambient = 100, texture = 30, a = 40;
  double light = unlit ? ambient / (level + ambient) : 1.0;
  double profile[W];
  for (guint x = 0; x < W; x++) {
    double v = light * (level + ambient + texture * cos (2.0 * G_PI * x / TEX_PERIOD + 0.7) -
                        a * cos (2.0 * G_PI * x / TEX_STRIPE_PERIOD));
    if (!unlit)
      v += a * cos (2.0 * G_PI * (x / TEX_STRIPE_PERIOD - (double) lit_as / TEX_N));
    profile[x] = v;
  }
  return noisy_frame (profile, rng);
}

static DsImage *
cancel_frame (guint k, gconstpointer what, GRand *rng)
{
  CancelCase w = *(const CancelCase *) what;
  guint lit_as = k == 0 && w == CANCEL_HALF_FIRST ? TEX_N / 2 : k == 0 && w == CANCEL_NEXT_FIRST ? 1 : k;
  return render_cancel_frame (lit_as, k == 0 && w == CANCEL_UNLIT_FIRST, rng);
}

/* One set of TEX_N (set_passes). */
static gboolean
cancel_set_passes (DsPhaseCheck *c, CancelCase what, GRand *rng, char **why)
{
  gboolean at_confirm;
  return set_passes (c, TEX_N, cancel_frame, &what, rng, &at_confirm, why);
}

static void
test_cancel_at_first_phase (void)
{
  /* The premise, from the closed form: the correct frame 0 shows no stripes at the period. */
  {
    GRand *rng = g_rand_new_with_seed (1);
    g_autoptr (DsImage) img = render_cancel_frame (0, FALSE, rng);
    DsStripePhase sp;
    g_assert_true (ds_stripe_phase_measure (img, TEX_STRIPE_PERIOD, NULL, &sp, NULL));
    g_assert_cmpfloat (sp.amplitude, <, 1.0 * 5); /* 5 noise sigmas of 1 DN */
    g_rand_free (rng);
  }
  const CancelCase wrong[] = { CANCEL_UNLIT_FIRST, CANCEL_HALF_FIRST, CANCEL_NEXT_FIRST };
  const char *wrong_what[] = { "frame 0 without the illuminator's light", "frame 0 lit with phase N/2",
                               "frame 0 lit with phase 1" };
  g_autofree char *why = NULL;
  guint next_unverified = 0;
  for (guint32 seed = 1; seed <= 10; seed++) {
    GRand *rng = g_rand_new_with_seed (seed);
    DsPhaseCheck c;
    ds_phase_check_init (&c, TEX_STRIPE_PERIOD, ds_phase_check_default_tolerance_deg (TEX_N));
    ds_phase_check_set_pattern (&c, FALSE, 0.5);
    for (guint i = 0; i < 3; i++)
      if (!cancel_set_passes (&c, CANCEL_CORRECT, rng, &why))
        g_error ("seed %u: correct set %u of a scene whose stripes cancel at phase 0 refused: %s", seed, i, why);
    for (guint w = 0; w < G_N_ELEMENTS (wrong); w++) {
      guint64 sets_unverified = c.sets_unverified;
      gboolean passed = cancel_set_passes (&c, wrong[w], rng, &why);
      if (passed && (wrong[w] != CANCEL_NEXT_FIRST || c.sets_unverified == sets_unverified))
        g_error ("seed %u: a set with %s passed%s", seed, wrong_what[w],
                 wrong[w] == CANCEL_NEXT_FIRST ? " as verified" : "");
      next_unverified += passed;
      if (seed == 1)
        g_test_message ("%s: %s", wrong_what[w], why ? why : "passed, the set counted unverified");
      if (!cancel_set_passes (&c, CANCEL_CORRECT, rng, &why))
        g_error ("seed %u: the correct set after %s refused: %s", seed, wrong_what[w], why);
    }
    g_rand_free (rng);
  }
  g_test_message ("frame 0 lit with phase 1: %u of 10 passed, the set counted unverified", next_unverified);
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  bank_init ();
  g_test_add_data_func ("/phase-check/sweep/templates", GINT_TO_POINTER (FALSE), test_sweep);
  g_test_add_data_func ("/phase-check/sweep/whole-set", GINT_TO_POINTER (TRUE), test_sweep);
  g_test_add_func ("/phase-check/too-noisy", test_too_noisy);
  g_test_add_func ("/phase-check/pattern-bend", test_pattern_bend);
  g_test_add_func ("/phase-check/repeat-in-first-set", test_repeat_in_first_set);
  g_test_add_func ("/phase-check/pixel-noise-integer", test_pixel_noise_integer);
  g_test_add_func ("/phase-check/pixel-noise-shot", test_pixel_noise_shot);
  g_test_add_func ("/phase-check/static-texture", test_static_texture);
  g_test_add_func ("/phase-check/other-period-first-frame", test_other_period_first_frame);
  g_test_add_func ("/phase-check/cancel-at-first-phase", test_cancel_at_first_phase);
  int status = g_test_run ();
  g_free (bank);
  return status;
}
