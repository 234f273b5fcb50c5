/* Does the configured stripe pattern match the pilot frames (pattern_check.h)? */
#include "daemon/operating/pattern_check.h"

#include <math.h>
#include <stdarg.h>
#include <string.h>

#include "proc/calibration_scatter.h"
#include "proc/image_stats.h"
#include "proc/calibration_sine.h"
#include "proc/clip_level.h"
#include "proc/column_stats.h"
#include "proc/harmonic_gain.h"
#include "proc/stripe_profile.h"
#include "proc/stripe_replica.h"

#define N_BINS 40u
/* The duty is judged against what the configured pattern would show through the same
 * measurement, not against the configured number: where square stripes are a few pixels wide,
 * the fit's duty trades against its blur and level (with the blur free, a duty 0.24 at 7 px under
 * a 0.94 px edge blur reads 0.15; a duty 1/2 at 2.75 px reads 0.54). So the configured duty, with
 * the blur and off-stripe level the frames show, integrated over the pixel and sampled on the
 * pilot's columns and phases, is rendered with the pilot's noise and read by the same fit
 * (expected_duty ()). The tolerance is DUTY_SPREADS of the spread of the difference (the frames'
 * own reading's, band_spread () with read_duty (), and the rendering's) plus DUTY_MODEL, what the rendering
 * leaves out: the true edge's shape against a Gaussian, and scattered light that keeps the
 * stripes blurred wider than the edge (readings 0.01-0.02 off on clear scenes and under
 * scattering, tests/daemon/test_pattern_check.c). */
#define DUTY_MODEL 0.03
#define DUTY_SPREADS 2.0
#define DUTY_REPLICAS 2
#define DUTY_BANDS 4u
/* The kernel-free reading's own error (mean_position ()): its peak and trough are read at bins
 * a fortieth of a period wide, on pixels a pixel wide. */
#define MEAN_POSITION_MODEL 0.02
/* The same for the off-stripe level against the black level where the stripes reach it. The
 * level is read from the troughs, whose depth the blur and the pixel scale by the first
 * harmonic's factor g1 = exp (-2 pi^2 sigma^2 / P^2) sinc (1 / P) (stripe_model.h): the fit
 * extrapolates the rest, so a misfit of the pattern's shape (a Gaussian for the true edge, a
 * pixel of the whole pitch) moves the level by its share of the trough divided by g1. The
 * tolerance at a period is LEVEL_TOLERANCE / g1 there. */
#define LEVEL_TOLERANCE 0.03
/* A pair in which more than this share of the pixels has a sample at the clip level shows the
 * stripes only where the scene is dim and at their edges (the lit centres of the bright parts
 * are gone): the profile's positions are then unevenly sampled and neither the duty nor the
 * level can be read from it, so the pair is not measured. */
#define CLIPPED_SHARE_MAX 0.02
/* Dim and bright stripe centres (relative to their surroundings) must differ this much in
 * brightness for the off-stripe fraction to tell a black level from scattered light. */
#define MIN_BRIGHTNESS_RATIO 1.5

const char *
ds_pattern_verdict_name (DsPatternVerdict v)
{
  switch (v) {
  case DS_PATTERN_MATCHES:
    return "matches";
  case DS_PATTERN_OFF_LEVEL_ASSUMED:
    return "off-stripe light taken as scattered";
  case DS_PATTERN_WRONG_DUTY:
    return "wrong duty";
  case DS_PATTERN_WRONG_BLACK_LEVEL:
    return "wrong black level";
  }
  return "?";
}

typedef struct {
  double duty, level, blur, rms;
  double ms; /* rms before the square root: what bounds the scan (best_level ()) */
} Fit;

/* The bins that hold pixels (in r or in t), in order: the others weigh nothing in a fit, and an
 * integer period fills only P of them. */
typedef struct {
  guint j[N_BINS], n;
} UsedBins;

static void
used_bins (const DsStripeProfile *p, UsedBins *used)
{
  used->n = 0;
  for (guint j = 0; j < N_BINS; j++)
    if (p->n[j] || p->nt[j])
      used->j[used->n++] = j;
}

/* The pattern without black level (s in [0, 1]) at the used bins' positions, for phase 0 and
 * 1/2 (the rest of s0 and s1 is left as it is). */
static void
pattern_at_bins (DsPatternKind kind, double period, double duty, double blur, const DsStripeProfile *p,
                 const UsedBins *used, double *s0, double *s1)
{
  DsStripeModel m = { .kind = kind, .period_px = period, .duty = duty, .black_level = 0, .blur_px = blur };
  for (guint i = 0; i < used->n; i++) {
    guint j = used->j[i];
    s0[j] = ds_stripe_value (&m, p->u[j] * period, 0);
    s1[j] = ds_stripe_value (&m, p->u[j] * period, 0.5);
  }
}

/* The mean square misfit of a level from the bins' sums of squares (cost over r, cost_t over t). */
static double
misfit (double cost, double total, double cost_t, double total_t)
{
  return cost / total + (total_t > 0 ? 0.25 * cost_t / total_t : 0);
}

/* The best off-stripe level at least level_min for the patterns s0, s1 (a 1-D scan). Two
 * profiles: r, and t, the sum of the phases against its mean over about two periods, since r
 * cannot tell duty a from 1 - a once b > 0 (overlaps and gaps both give r = 1/2), nor see the
 * gaps at b = 0 (no light there); the sum is high where the phases overlap and low in the gaps.
 * t carries the scene's own detail as noise, so it weighs a quarter.
 *
 * A level whose misfit reaches `beat` (the caller's best so far, before the square root) cannot
 * be the caller's pick, nor one whose misfit reaches the scan's own best: its sums only grow with
 * more bins (every term is a square times a count, and rounding is monotonic), so its scan stops
 * there. What is picked is what the whole scan picks; fit->rms stays infinite when no level
 * beats `beat`. */
static void
best_level (const DsStripeProfile *p, const UsedBins *used, const double *s0, const double *s1, double duty,
            double level_min, double step, double beat, Fit *fit)
{
  double total = 0, total_t = 0;
  for (guint i = 0; i < used->n; i++) {
    total += (double) p->n[used->j[i]];
    total_t += (double) p->nt[used->j[i]];
  }
  fit->rms = fit->ms = INFINITY;
  for (double b = level_min; b <= 0.98 + 1e-9; b += step) {
    double cost = 0, cost_t = 0, mean = 2 * b + (1 - b) * 2 * duty, bound = MIN (beat, fit->ms);
    guint i = 0;
    for (; i < used->n; i++) {
      guint j = used->j[i];
      if (i % 8 == 7 && misfit (cost, total, cost_t, total_t) >= bound)
        break;
      double a = b + (1 - b) * s0[j], c = b + (1 - b) * s1[j];
      if (p->nt[j]) {
        double d = p->t[j] - (a + c) / mean;
        cost_t += (double) p->nt[j] * d * d;
      }
      if (!p->n[j])
        continue;
      double d = p->r[j] - (a + c > 0 ? a / (a + c) : 0.5);
      cost += (double) p->n[j] * d * d;
    }
    if (i < used->n)
      continue;
    double ms = misfit (cost, total, cost_t, total_t), rms = sqrt (ms);
    if (rms < fit->rms) {
      fit->rms = rms;
      fit->ms = ms;
      fit->level = b;
    }
  }
}

/* Least squares over duty (fixed when duty_fixed >= 0), blur >= blur_min and off-stripe level >=
 * level_min: a grid, then a finer grid about its best. The blur's floor is the calibrated edge
 * blur where it is known: nothing between the illuminator and the pixel sharpens the stripes,
 * and a fit free to sharpen them trades the blur against the duty where the stripes are a few
 * pixels wide. */
static Fit
fit_profile (const DsStripeProfile *p, DsPatternKind kind, double period, double duty_fixed, double level_min,
             double blur_min)
{
  Fit best = { .rms = INFINITY, .ms = INFINITY };
  double blur_max = MAX (blur_min, MIN (0.3 * period, 4.0)), s0[N_BINS], s1[N_BINS];
  gboolean duty_free = kind == DS_PATTERN_SQUARE && duty_fixed < 0;
  double fixed = kind == DS_PATTERN_SQUARE ? duty_fixed : 0.5;
  UsedBins used;
  used_bins (p, &used);
  for (int pass = 0; pass < 2; pass++) {
    double a_lo = duty_free ? (pass ? best.duty - 0.01 : 0.04) : fixed;
    double a_hi = duty_free ? (pass ? best.duty + 0.01 : 0.96) : fixed;
    double a_step = pass ? 0.002 : 0.01;
    double s_lo = pass ? MAX (blur_min, best.blur - 0.15) : blur_min, s_hi = pass ? MIN (blur_max, best.blur + 0.15) : blur_max;
    double s_step = pass ? 0.03 : 0.15;
    Fit round = best;
    for (double a = a_lo; a <= a_hi + 1e-9; a += a_step) {
      if (a <= 0.01 || a >= 0.99)
        continue;
      for (double s = s_lo; s <= s_hi + 1e-9; s += s_step) {
        pattern_at_bins (kind, period, a, s, p, &used, s0, s1);
        Fit f = { .duty = a, .blur = s };
        best_level (p, &used, s0, s1, a, pass ? MAX (level_min, best.level - 0.02) : level_min, pass ? 0.002 : 0.01,
                    round.ms, &f);
        if (f.rms < round.rms)
          round = f;
      }
    }
    best = round;
  }
  return best;
}

/* Sine stripes: r = 1/2 + (c/2) cos (2 pi u) exactly (the phases at 0 and 1/2 sum to a constant),
 * blur or not, so the profile holds one number, the contrast c = k g (proc/calibration_sine.h),
 * and no fit over blur and level can tell them apart. With g as configured at this period (the
 * harmonic gain, or the edge blur, carried to this period in closed form), the black level the
 * pilot shows is the one whose k = c / g: light that does not keep the stripes only raises it,
 * and no blur lowers it. */
static Fit
fit_sine (const DsStripeProfile *p, double gain)
{
  double scc = 0, sss = 0, scs = 0, src = 0, srs = 0, total = 0;
  for (guint j = 0; j < N_BINS; j++) {
    if (!p->n[j])
      continue;
    double w = (double) p->n[j], cs = cos (2 * G_PI * p->u[j]), sn = sin (2 * G_PI * p->u[j]), d = p->r[j] - 0.5;
    scc += w * cs * cs;
    sss += w * sn * sn;
    scs += w * cs * sn;
    src += w * d * cs;
    srs += w * d * sn;
    total += w;
  }
  Fit f = { .duty = 0.5, .rms = INFINITY };
  double det = scc * sss - scs * scs;
  if (!(det > 0))
    return f;
  double a = (src * sss - srs * scs) / det, b = (srs * scc - src * scs) / det, ss = 0;
  for (guint j = 0; j < N_BINS; j++)
    if (p->n[j]) {
      double d = p->r[j] - 0.5 - a * cos (2 * G_PI * p->u[j]) - b * sin (2 * G_PI * p->u[j]);
      ss += (double) p->n[j] * d * d;
    }
  double k = 2 * hypot (a, b) / gain;
  f.level = (1 - k) / (1 + k);
  f.blur = gain < 1 ? p->period_px * sqrt (-log (gain) / 2) / G_PI : 0;
  f.rms = sqrt (ss / total);
  return f;
}

/* Per pixel of the pair at P, for the scattering check (proc/calibration_scatter.h): the sum of
 * the phases, and the off-stripe fraction at the stripe centres (NaN elsewhere). */
typedef struct {
  double *brightness, *off;
} Centres;

/* g1, the first harmonic's factor from the blur sigma and the whole pixel at period P. */
static double
trough_gain (double period, double blur)
{
  double f = 1 / period;
  return exp (-2 * G_PI * G_PI * blur * blur * f * f) * sin (G_PI * f) / (G_PI * f);
}

/* What the duty fit reads on the configured pattern m (with the off-stripe level and blur the
 * frames show under it) seen through the pilot's measurement: m on the pilot's columns at its
 * stripes' offset, phases 0 and 1/2 (ds_stripe_value integrates over the pixel), at the lit
 * pixels' mean level with the pilot's noise, on as many rows as the pilot had lit pixels; each
 * replica shifts the stripes by a fraction of a pixel within the offset's half-pixel and draws
 * new noise (proc/stripe_replica.h renders the frames). The mean and the standard deviation of
 * the replicas' duties. A fixed seed keeps the check a function of its frames. */
static void
expected_duty (const DsStripeModel *m, const DsStripeProfile *real, double noise_dn, double blur_min, double *mean,
               double *sd)
{
  guint64 n;
  double level = ds_stripe_profile_lit_mean (real, &n);
  /* a phase's level per unit of the pattern's value: the pair's sum over its mean, 2 m */
  double scale = n ? level / (2 * ds_pattern_mean (m->kind, m->duty, m->black_level)) : 1;
  guint w = real->width, h = (guint) MAX (8, (real->pixels + w - 1) / w);
  g_autoptr (GRand) rng = g_rand_new_with_seed (0x5eed);
  g_autoptr (DsImage) dark = ds_image_new (DS_SAMPLE_F32, w, h, NULL);
  g_autoptr (DsImage) l0 = ds_image_new (DS_SAMPLE_F32, w, h, NULL);
  g_autoptr (DsImage) l1 = ds_image_new (DS_SAMPLE_F32, w, h, NULL);
  g_autofree double *v = g_new (double, 2 * (gsize) w);
  double duty[DUTY_REPLICAS], sum = 0, ss = 0;
  for (guint k = 0; k < DUTY_REPLICAS; k++) {
    double offset = real->offset_cycles + ((k + 0.5) / DUTY_REPLICAS - 0.5) * 0.5 / real->period_px;
    for (guint x = 0; x < w; x++) {
      v[x] = scale * ds_stripe_value (m, x, offset);
      v[w + x] = scale * ds_stripe_value (m, x, offset + 0.5);
    }
    /* the frames are float and of one shape: this cannot fail */
    ds_stripe_replica_render (v, v + w, noise_dn, rng, dark, l0, l1);
    g_autoptr (DsStripeProfile) p = ds_stripe_profile_bin (dark, l0, l1, real->period_px, offset, 0, N_BINS, NULL);
    duty[k] = p ? fit_profile (p, m->kind, real->period_px, -1, 0, blur_min).duty : m->duty;
    sum += duty[k];
  }
  *mean = sum / DUTY_REPLICAS;
  for (guint k = 0; k < DUTY_REPLICAS; k++)
    ss += (duty[k] - *mean) * (duty[k] - *mean);
  *sd = sqrt (ss / (DUTY_REPLICAS - 1));
}

/* Where the mean of one phase's profile lies between its trough and its peak, (mean - min) /
 * (max - min), over n values at even positions across one period. For square stripes of duty
 * a seen through any kernel K (blur, the pixel, scattered light that keeps the stripes), the
 * peak is K's mass over a window of width aP about the stripe's centre and the trough its mass
 * over the same window half a period away, and the mean is a whatever K is. A level and a gain
 * divide out, and so does light any kernel spreads over periods: the reading stays a for sharp
 * stripes plus a kernel as wide as the scene, and a kernel about a period wide moves it
 * towards 1/2 (at a = 1/2 the windows split K's mass, and it is 1/2 exactly). So whatever the
 * kernel's shape, the reading lies between what the calibrated edge blur and the pixel give the
 * configured duty and 1/2. NaN for a flat profile. */
static double
mean_position (const double *v, guint n)
{
  double lo = INFINITY, hi = -INFINITY, sum = 0;
  for (guint i = 0; i < n; i++) {
    lo = MIN (lo, v[i]);
    hi = MAX (hi, v[i]);
    sum += v[i];
  }
  return n && hi > lo ? (sum / n - lo) / (hi - lo) : NAN;
}

/* The kernel-free reading of a measured profile: phase 0's light at bin j, relative to its mean,
 * is r t (r its share of the pair's sum, t that sum against its mean nearby); the bins that hold
 * both. */
static double
profile_mean_position (const DsStripeProfile *p)
{
  double v[N_BINS];
  guint n = 0;
  for (guint j = 0; j < N_BINS; j++)
    if (p->n[j] && p->nt[j])
      v[n++] = p->r[j] * p->t[j];
  return n >= 4 ? mean_position (v, n) : NAN;
}

/* The same reading on the configured pattern m through its blur and the pixel, noise-free. */
static double
model_mean_position (const DsStripeModel *m)
{
  double v[200];
  for (guint i = 0; i < G_N_ELEMENTS (v); i++)
    v[i] = ds_stripe_value (m, (i + 0.5) / G_N_ELEMENTS (v) * m->period_px, 0);
  return mean_position (v, G_N_ELEMENTS (v));
}

/* How a reading of the pair spreads: the pair cut into DUTY_BANDS bands of rows, each read the
 * same way at the same offset; the whole pair's reading spreads by their standard deviation over
 * sqrt (DUTY_BANDS). It holds everything the reading varies with that the frames carry: noise,
 * and the scene's own detail, which the reading takes with the stripes. The standard deviation
 * of the bands' readings (read () gives NaN for a band it cannot read); NaN when fewer than two
 * bands can be read. */
typedef struct {
  double (*read) (const DsStripeProfile *p, gconstpointer data);
  gconstpointer data;
} BandReading;

static double
band_spread (const DsImage *dark, const DsImage *l0, const DsImage *l1, double period, double offset,
             double saturation, const BandReading *how)
{
  double reading[DUTY_BANDS], sum = 0, ss = 0;
  guint n = 0, rows = l0->height / DUTY_BANDS;
  for (guint k = 0; k < DUTY_BANDS && rows >= 4; k++) {
    const DsImage *f[3] = { dark, l0, l1 };
    DsImage band[3];
    gboolean ok = TRUE;
    for (guint i = 0; i < 3 && ok; i++)
      ok = ds_image_view_init (&band[i], f[i]->type, f[i]->bit_depth, f[i]->width, rows, f[i]->stride,
                               ds_image_row (f[i], k * rows), (rows - 1) * f[i]->stride + f[i]->width * ds_sample_size (f[i]->type), NULL);
    if (!ok)
      continue;
    g_autoptr (DsStripeProfile) p = ds_stripe_profile_bin (&band[0], &band[1], &band[2], period, offset, saturation, N_BINS, NULL);
    if (!p || p->pixels < 64)
      continue;
    double r = how->read (p, how->data);
    if (!isfinite (r))
      continue;
    reading[n] = r;
    sum += reading[n++];
  }
  if (n < 2)
    return NAN;
  for (guint k = 0; k < n; k++)
    ss += (reading[k] - sum / n) * (reading[k] - sum / n);
  return sqrt (ss / (n - 1));
}

typedef struct {
  DsPatternKind kind;
  double period, blur_min;
} DutyFit;

/* The duty fit's reading of a band (the whole pair's fit). */
static double
read_duty (const DsStripeProfile *p, gconstpointer data)
{
  const DutyFit *d = data;
  Fit fit = fit_profile (p, d->kind, d->period, -1, 0, d->blur_min);
  return isfinite (fit.rms) ? fit.duty : NAN;
}

static double
read_mean_position (const DsStripeProfile *p, gconstpointer data)
{
  (void) data;
  return profile_mean_position (p);
}

/* One pair: the binned profile (proc/stripe_profile.h) and its fits; with centres, also the
 * stripe-centre pixels. */
static void
check_pair (const DsImage *dark, const DsImage *l0, const DsImage *l1, double period, double saturation,
            const DsStripeModel *conf, double sine_gain, double known_blur, DsPatternPair *out, Centres *centres)
{
  memset (out, 0, sizeof *out);
  out->period_px = period;
  double offset;
  if (period <= 2 || period > l0->width || !ds_stripe_profile_offset (l0, l1, period, &offset))
    return;
  DsClipLevel clip;
  const DsImage *lit[2] = { l0, l1 };
  ds_clip_level_find (dark, lit, 2, saturation, &clip);
  saturation = clip.level;
  out->clipped_share = (double) ds_clip_count (l0, l1, saturation) / ((double) l0->width * l0->height);
  if (out->clipped_share > CLIPPED_SHARE_MAX)
    return;
  /* The frames' shapes were checked (ds_probe_frames_check): this cannot fail. */
  g_autoptr (DsStripeProfile) prof = ds_stripe_profile_bin (dark, l0, l1, period, offset, saturation, N_BINS, NULL);
  if (!prof)
    return;
  out->pixels = prof->pixels;
  /* an integer period puts the pixels at P positions in it */
  if (prof->bins_used < MIN (N_BINS / 2, (guint) period - 2) || out->pixels < 256)
    return;
  Fit free, configured;
  if (conf->kind == DS_PATTERN_SINE) {
    free = fit_sine (prof, ds_sine_gain_at_period (sine_gain, conf->period_px, period));
    configured = free; /* one number: the configured contrast's misfit is the level's */
  } else {
    free = fit_profile (prof, conf->kind, period, -1, 0, known_blur);
    configured = fit_profile (prof, conf->kind, period, conf->duty, conf->black_level, known_blur);
  }
  out->expected_duty = conf->kind == DS_PATTERN_SQUARE ? conf->duty : 0.5;
  if (conf->kind == DS_PATTERN_SQUARE && isfinite (free.rms)) {
    /* the configured duty seen through the blur and off-stripe level the frames show (the free
     * fit's: the configured fit bends them to the configured duty, and a single blur and level
     * then render stripes that scattered light keeps, blurred wider, as another pattern) */
    DsStripeModel m = { .kind = conf->kind, .period_px = period, .duty = conf->duty, .black_level = free.level,
                        .blur_px = free.blur };
    /* one frame's noise: half the difference's variance, and the dark frame's */
    double noise = ds_column_stats_noise_dn (l0, l1, saturation), noise_dark = ds_column_stats_noise_dn (dark, NULL, 0);
    noise = sqrt ((isfinite (noise) ? noise * noise / 2 : 0) + (isfinite (noise_dark) ? noise_dark * noise_dark : 0));
    double sd;
    expected_duty (&m, prof, noise, known_blur, &out->expected_duty, &sd);
    /* the difference's spread: the pair's reading's and the replicas' mean's. The bands' fits
     * only widen the tolerance beyond DUTY_MODEL: a reading within it needs none */
    DutyFit how_fit = { conf->kind, period, known_blur };
    BandReading how = { read_duty, &how_fit };
    double spread = fabs (free.duty - out->expected_duty) > DUTY_MODEL
                      ? band_spread (dark, l0, l1, period, offset, saturation, &how)
                      : NAN;
    double var = (isfinite (spread) ? spread * spread : DUTY_BANDS * sd * sd) + sd * sd / DUTY_REPLICAS;
    out->duty_tolerance = DUTY_MODEL + DUTY_SPREADS * sqrt (var);
    /* the kernel-free reading and what any kernel leaves the configured duty at (mean_position ()) */
    DsStripeModel edge = { .kind = conf->kind, .period_px = period, .duty = conf->duty, .blur_px = known_blur };
    double at_edge = model_mean_position (&edge);
    BandReading how_position = { read_mean_position, NULL };
    double position_spread = band_spread (dark, l0, l1, period, offset, saturation, &how_position);
    double allow = MEAN_POSITION_MODEL + DUTY_SPREADS * position_spread;
    out->mean_position = isfinite (allow) ? profile_mean_position (prof) : NAN;
    out->mean_position_lo = MIN (at_edge, 0.5) - allow;
    out->mean_position_hi = MAX (at_edge, 0.5) + allow;
  } else {
    out->mean_position = NAN;
  }
  out->measured = isfinite (free.rms);
  if (!out->measured)
    return;
  out->duty = conf->kind == DS_PATTERN_SQUARE ? free.duty : 0.5;
  out->off_level = free.level;
  out->blur_px = free.blur;
  out->fit_rms = free.rms;
  out->configured_rms = configured.rms;
  /* g1 below 0.1 leaves the troughs too shallow to read a level at all; the floor keeps a
   * black level far off (a few tenths) refused there */
  out->level_tolerance = LEVEL_TOLERANCE / MAX (0.1, trough_gain (period, free.blur));
  gsize npix = (gsize) l0->width * l0->height;
  Centres own = { g_new (double, npix), g_new (double, npix) };
  /* the narrower window of the fitted and the configured duty: the pixels nearest the centres */
  double window_duty = conf->kind == DS_PATTERN_SQUARE ? MIN (out->duty, conf->duty) : 0.5;
  ds_stripe_profile_centres (prof, dark, l0, l1, window_duty, own.brightness, own.off);
  /* the median of the centres' off fractions; too few (under 64) leave it unknown */
  out->centre_off = ds_finite_quantile (own.off, npix, 0.5, 64);
  if (centres) {
    ds_stripe_profile_centres (prof, dark, l0, l1, out->duty, own.brightness, own.off);
    *centres = own;
  } else {
    g_free (own.brightness);
    g_free (own.off);
  }
}

#define REMEDY                                                                                                   \
  "run `descatterctl calibrate` on a clear reference (no scattering medium) and put its pattern=, duty= (square), " \
  "black-level= and harmonic-gain= lines into descatterd.conf's [illuminator]"

/* A verdict other than MATCHES, its message ending with the remedy. */
static void G_GNUC_PRINTF (3, 4)
conclude (DsPatternCheck *out, DsPatternVerdict verdict, const char *format, ...)
{
  va_list ap;
  va_start (ap, format);
  g_autofree char *what = g_strdup_vprintf (format, ap);
  va_end (ap);
  out->verdict = verdict;
  g_snprintf (out->message, sizeof out->message, "%s: " REMEDY, what);
}

/* g, the factor blur and the pixel leave on a sine's first harmonic at the configured period:
 * from the calibrated harmonic gain h = (1 - b) g / 2, else from the calibrated edge blur, else
 * none (sharp: then the check's allowance for blur is nil and only scattered light raises the
 * level). */
static double
configured_sine_gain (const DsProbeFrames *f)
{
  const DsStripeModel *conf = &f->geometry;
  if (f->calibrated_gain > 0)
    return MIN (1.0, 2 * f->calibrated_gain / (1 - conf->black_level));
  if (f->blur_known && f->calibrated_blur_px > 0) {
    DsStripeModel m = *conf;
    m.blur_px = f->calibrated_blur_px;
    return MIN (1.0, 2 * ds_stripe_harmonic (&m, 1) / (1 - conf->black_level));
  }
  return 1.0;
}

static gboolean
duty_differs (const DsPatternPair *pair)
{
  return fabs (pair->duty - pair->expected_duty) > pair->duty_tolerance;
}

/* The fit reads the duty through one Gaussian blur and a level. Where the frames hold light
 * beyond the black level, some of it may be scattered light that keeps the stripes through a
 * kernel of its own shape (a forward-peaked medium's has a sharp core and long tails), which no
 * Gaussian renders. At twice the period such a kernel covers half as much of a stripe, and a
 * reading confirmed there stands; a pair read alone must then be confirmed by the kernel-free
 * reading (mean_position ()): outside what any kernel leaves the configured duty at. */
static gboolean
kernel_free_differs (const DsPatternPair *pair, double black_level)
{
  if (!(pair->off_level > black_level + LEVEL_TOLERANCE) || !isfinite (pair->mean_position))
    return TRUE;
  return pair->mean_position < pair->mean_position_lo || pair->mean_position > pair->mean_position_hi;
}

/* Each measured pair reads the duty away from the configured pattern's reading (a duty the blur
 * at P hides is read at 2P; the configured duty must fit neither); a pair read alone under
 * light beyond the black level, the kernel-free reading too. */
static gboolean
duty_refused (const DsPatternPair *p, const DsPatternPair *q, double black_level)
{
  if (!p->measured || !duty_differs (p))
    return FALSE;
  return q->measured ? duty_differs (q) : kernel_free_differs (p, black_level);
}

/* The pair shows an off-stripe level below the black level b. Every pixel's off-stripe light is
 * at least b times its lit light, whatever blurs or scatters it: blur, the pixel and scattered
 * light only mix the illuminator's light, each part of which is at least b of the lit level, so
 * no pixel's off phase falls below b of its lit phase (noise aside, which the median of the
 * centres' pixels does not move). The fit reads the level through the pattern's shape; where an
 * object removes the direct light of some pixels (opaque at the entry face), these keep only
 * light scattered in from their sides, whose stripes are weaker or shifted, and the profile's
 * bins mix them with the others in shares that vary along the period (the object's pitch beats
 * with the stripes'): at a few pixels per period the free fit trades that mixture's shape for a
 * lower level. So a square fit below b - tolerance refuses the black level only when the
 * pixels nearest the stripe centres show it too (their median off fraction below b -
 * tolerance); too few centre pixels leave the fit alone to decide. A sine's level fits no shape:
 * it is its contrast over the calibrated gain, which such a mixture only lowers (raising the
 * level), and its centres keep the sine's own off light, so the reading decides alone. */
static gboolean
level_low (const DsPatternPair *pair, double black_level, DsPatternKind kind)
{
  double floor = black_level - pair->level_tolerance;
  return pair->off_level < floor && (kind != DS_PATTERN_SQUARE || !(pair->centre_off >= floor));
}

gboolean
ds_pattern_check (const DsProbeFrames *f, DsPatternCheck *out, GError **error)
{
  memset (out, 0, sizeof *out);
  const DsImage *l0 = f->lit[0], *l1 = f->lit[1];
  if (!ds_probe_frames_check (f, error))
    return FALSE;
  const DsStripeModel *conf = &f->geometry;
  double sine_gain = conf->kind == DS_PATTERN_SINE ? configured_sine_gain (f) : 1.0;
  Centres centres = { 0 };
  double known_blur = f->blur_known ? f->calibrated_blur_px : 0;
  check_pair (f->dark, l0, l1, conf->period_px, f->saturation_dn, conf, sine_gain, known_blur, &out->pair[0],
              &centres);
  if (f->coarse[0])
    check_pair (f->dark, f->coarse[0], f->coarse[1], 2 * conf->period_px, f->saturation_dn, conf, sine_gain,
                known_blur, &out->pair[1], NULL);
  DsScatterCheck scatter = { 0 };
  if (centres.off)
    ds_calibration_scatter_check (centres.brightness, centres.off, l0->width, l0->height, conf->period_px, &scatter);
  g_free (centres.brightness);
  g_free (centres.off);
  out->off_dim = scatter.off_dim;
  out->off_bright = scatter.off_bright;
  out->brightness_ratio = scatter.brightness_contrast;
  /* The calibrated blur floors the fit because nothing sharpens the stripes; a calibration that
   * read them wider than these frames show (another focus, another period's fit) makes the
   * floored fit trade the duty for the blur instead. Where the frames alone tell the duty from
   * the blur (the unfloored reading's tolerance within twice what the model leaves out), the
   * duty stands when the fit without the floor reads it as configured: a wrong duty is read
   * wrong at any blur. Where they cannot (stripes of a few pixels), the floor decides. */
  if (conf->kind == DS_PATTERN_SQUARE && known_blur > 0 && duty_refused (&out->pair[0], &out->pair[1], conf->black_level)) {
    DsPatternPair unfloored[2] = { 0 };
    check_pair (f->dark, l0, l1, conf->period_px, f->saturation_dn, conf, sine_gain, 0, &unfloored[0], NULL);
    if (f->coarse[0])
      check_pair (f->dark, f->coarse[0], f->coarse[1], 2 * conf->period_px, f->saturation_dn, conf, sine_gain, 0,
                  &unfloored[1], NULL);
    const DsPatternPair *u = unfloored[1].measured ? &unfloored[1] : &unfloored[0];
    if (unfloored[0].measured && u->duty_tolerance <= 2 * DUTY_MODEL && !duty_refused (&unfloored[0], &unfloored[1], conf->black_level))
      memcpy (out->pair, unfloored, sizeof unfloored);
  }
  const DsPatternPair *p = &out->pair[0], *q = &out->pair[1];
  out->verdict = DS_PATTERN_MATCHES;
  if (!p->measured)
    return TRUE;
  out->duty = q->measured ? q->duty : p->duty;
  /* blur can only raise it (sine: the configured blur is taken out already), and blurs the
   * stripes at 2P a quarter as much */
  out->off_level = q->measured ? MIN (p->off_level, q->off_level) : p->off_level;
  const char *at = q->measured ? "at twice the period" : "at the period";
  g_autofree char *seen =
    conf->kind == DS_PATTERN_SINE
      ? g_strdup_printf ("the sine's contrast the pilot frames show, with the configured harmonic gain's blur "
                         "(%.2f of the first harmonic kept at the period) taken out, gives a black level of %.2f",
                         sine_gain, out->off_level)
      : g_strdup_printf ("the pilot frames show an off-stripe level of %.2f of the lit level", out->off_level);

  /* The duty: each measured pair must read it further from what the configured pattern reads
   * through the same measurement than that reading's spread. */
  if (conf->kind == DS_PATTERN_SQUARE && duty_refused (p, q, conf->black_level)) {
    const DsPatternPair *shown = q->measured ? q : p;
    conclude (out, DS_PATTERN_WRONG_DUTY,
              "the configured stripe pattern does not match the frames: duty %.2f is configured, the pilot frames "
              "show duty %.2f (%s; the configured pattern would read %.2f +- %.2f through the same blur, pixels and "
              "noise) and an off-stripe level %.2f of the lit level (black level %.2f is configured); "
              "scattering cannot change the duty. Predictions and the separation would rest on the wrong pattern",
              conf->duty, out->duty, at, shown->expected_duty, shown->duty_tolerance, out->off_level,
              conf->black_level);
    return TRUE;
  }
  /* Neither blur nor scattered light lowers the level: a pair reading it below the black level
   * by more than its own tolerance (LEVEL_TOLERANCE / g1 at its period), in its fit and in its
   * stripe centres' own fractions (level_low ()), is a wrong one. */
  if (level_low (p, conf->black_level, conf->kind) || (q->measured && level_low (q, conf->black_level, conf->kind))) {
    g_autofree char *low = conf->kind == DS_PATTERN_SINE
                             ? g_strdup (seen)
                             : g_strdup_printf ("the pilot frames show an off-stripe level of only %.2f of the lit level",
                                                out->off_level);
    conclude (out, DS_PATTERN_WRONG_BLACK_LEVEL,
              "the configured stripe pattern does not match the frames: black level %.2f is configured, %s (neither "
              "scattered light nor blur can lower it below the black level)",
              conf->black_level, low);
    return TRUE;
  }
  if (out->off_level > conf->black_level + LEVEL_TOLERANCE) {
    double excess = out->off_level - conf->black_level, tolerance = MAX (0.02, 0.15 * excess);
    /* scattered light shows: a larger fraction on the dim parts */
    if (scatter.spatial)
      return TRUE;
    /* A black level calibrated on a clear reference (its harmonic gain with it) is the
     * illuminator's own, so more off-stripe light in the scene is light the scene scattered.
     * Equal shares on dim and bright parts do not contradict that: an object behind the medium
     * darkens the scattered light with the direct. */
    if (f->calibrated_gain > 0) {
      conclude (out, DS_PATTERN_OFF_LEVEL_ASSUMED,
                "%s where the calibrated black level is %.2f; taken as scattered light (the calibration on a clear "
                "reference measured the illuminator's own). If the illuminator has changed since, calibrate again",
                seen, conf->black_level);
      return TRUE;
    }
    if (out->brightness_ratio >= MIN_BRIGHTNESS_RATIO && fabs (out->off_dim - out->off_bright) <= tolerance) {
      conclude (out, DS_PATTERN_WRONG_BLACK_LEVEL,
                "the configured stripe pattern does not match the frames: black level %.2f is configured, %s, the "
                "same on dim and bright parts of the scene (%.2f and %.2f, brightness x%.1f apart): an "
                "illuminator's black level shows so, and scattered light only where every object lies behind the "
                "medium; a calibration tells the two apart",
                conf->black_level, seen, out->off_dim, out->off_bright, out->brightness_ratio);
      return TRUE;
    }
    conclude (out, DS_PATTERN_OFF_LEVEL_ASSUMED,
              "%s where black level %.2f is configured; taken as scattered light (the scene has too little contrast "
              "to tell it from a black level). If the illuminator's off stripes are not that dark, the transmissive "
              "image is low by up to %.0f %%",
              seen, conf->black_level, 100 * excess / (1 - conf->black_level));
  }
  return TRUE;
}
