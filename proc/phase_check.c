#include "proc/phase_check.h"

#include <math.h>
#include <string.h>

#include "proc/stripe_phase.h"

/* How many noise sigmas a correct frame may deviate before the check could reject it: noise
 * alone moves a phase past 5 sigma with probability 6e-7 (two-sided Gaussian), the same 5 the
 * single-frame measurement asks of a stripe (DS_STRIPE_PHASE_MIN_SNR). A tolerance narrower
 * than that cannot be checked: the frame is "unverifiable", not "wrong". */
#define PHASE_CHECK_SIGMAS 5.0

void
ds_phase_check_init (DsPhaseCheck *check, double period_px, double tolerance_deg)
{
  memset (check, 0, sizeof *check);
  check->period_px = period_px;
  check->tolerance_cycles = tolerance_deg / 360.0;
  check->min_confidence = DS_STRIPE_PHASE_MIN_SNR;
}

void
ds_phase_check_set_pattern (DsPhaseCheck *check, gboolean square, double duty)
{
  if (check->pattern_known && check->pattern_square == square && check->pattern_duty == duty)
    return;
  check->pattern_known = TRUE;
  check->pattern_square = square;
  check->pattern_duty = duty;
  check->bend_n = 0; /* computed again when needed */
}

void
ds_phase_check_begin_set (DsPhaseCheck *check)
{
  check->set_n = 0;
  memset (check->set_sum, 0, sizeof check->set_sum);
  memset (check->set_count, 0, sizeof check->set_count);
  memset (check->set_sumsq, 0, sizeof check->set_sumsq);
  check->set_noise2 = 0;
  check->set_frames = 0;
  check->set_by_template = FALSE;
  check->set_unverified = 0;
  memset (check->set_refused_as, 0, sizeof check->set_refused_as);
  check->set_refused_bare = check->set_deferred = 0;
  memset (check->set_level, 0, sizeof check->set_level);
  check->profile_width = 0;
  check->profile_frames = 0;
  check->pending = FALSE;
  check->provisional = TRUE;
}

/* Rows kept for the measurement: the stripes vary along x only, so the rows are averaged into
 * one profile, and beyond a few hundred rows more of them only buy noise margin the check does
 * not need, at a cost (a pass over a 4 MP frame) that sits between the last frame and the
 * result. A view of every step-th row: no copy. */
#define PHASE_CHECK_MIN_ROWS 256

/* The rows' column profile: each column's mean over the rows (its finite samples; NAN where
 * there are none), one row of floats. The stripes vary along x only, so everything the check
 * measures at a period (the stripes', or another) is in it; measured once per frame and kept
 * for the set (profile_sum). The sums are the stripe phase's own (vectorised, exact for
 * integer samples). */
static DsImage *
column_profile (const DsImage *rows)
{
  DsImage *profile = ds_image_new (DS_SAMPLE_F32, rows->width, 1, NULL);
  if (!profile)
    return NULL;
  g_autofree double *sum = g_new (double, rows->width);
  g_autofree guint32 *count = g_new (guint32, rows->width);
  ds_stripe_phase_column_sums (rows, 0, 0, rows->width, rows->height, sum, count);
  float *out = ds_image_row (profile, 0);
  for (guint x = 0; x < rows->width; x++)
    out[x] = count[x] ? (float) (sum[x] / count[x]) : NAN;
  return profile;
}

/* The stripe period a profile does show, when the configured one finds nothing: the first
 * harmonic is fitted at candidate periods 2 % apart, from just above Nyquist to a quarter of
 * the width. The best one, if it is reliable, else NAN. A failure path only (a frame that
 * could not be verified): a few hundred fits of one row. */
static double
dominant_period (const DsImage *profile, double *best_snr)
{
  *best_snr = 0;
  if (profile->width < 16)
    return NAN;
  double best = NAN;
  for (double p = 2.2; p <= profile->width / 4.0; p *= 1.02) {
    DsStripePhase sp;
    if (ds_stripe_phase_measure (profile, p, NULL, &sp, NULL) && sp.reliable && sp.snr > *best_snr) {
      *best_snr = sp.snr;
      best = p;
    }
  }
  return best;
}

/* The harmonics of the configured stripes taken out of a difference of profiles before it is
 * measured at another period: square stripes' harmonics up to the eighth carry more than
 * 2 / (pi 8) of the first's amplitude at most, and the projector's blur and the scattering take
 * the higher ones further down. */
#define OWN_HARMONICS 8

/* The period of stripes that moved between the set's frames, judged on `d`: one frame's profile
 * less what the set's other frames share (their mean profile). The object's texture is lit by
 * the same mean light at every phase, so it is the same in every frame and cancels in d; what
 * is left is how the frame's light changed against the others': the illuminator's stripes
 * moving on (their period and its harmonics, as the pixels fold them), the noise, and what
 * should not be there, another illuminator's stripes (a wrong period-px, another pattern) that
 * the other frames lack or show elsewhere. The stripes' own change is fitted and taken out of
 * d, and the strongest other period of what is left (reliable: 5 sigmas out of the rest) is
 * another pattern's when it changed more than the stripes did (the largest of their harmonics'
 * changes): the object's texture under the moving stripes also changes, at its own periods
 * beside the stripes', but at most by the stripes' change times the texture's contrast, never
 * more than the stripes' change itself. Returns that period, else NAN; d is changed. */
static double
moving_period (const DsPhaseCheck *check, DsImage *d, double *moved_snr)
{
  *moved_snr = 0;
  float *v = ds_image_row (d, 0);
  double own_change = 0;
  for (guint m = 1; m <= OWN_HARMONICS; m++) {
    double f = m / check->period_px;
    f = fabs (f - floor (f + 0.5)); /* as sampled on pixels: folded into [0, 1/2] */
    if (!(f * d->width >= 2.0) || !(1.0 / f > 2.0))
      continue; /* fewer than two periods across (the mean's), or Nyquist */
    DsStripePhase sp;
    if (!ds_stripe_phase_measure (d, 1.0 / f, NULL, &sp, NULL))
      continue;
    own_change = MAX (own_change, sp.amplitude);
    for (guint x = 0; x < d->width; x++)
      v[x] -= (float) (sp.amplitude * cos (2.0 * G_PI * (x * f - sp.phase)));
  }
  double snr = 0, other = dominant_period (d, &snr);
  DsStripePhase moved;
  if (!isfinite (other) || !ds_stripe_phase_measure (d, other, NULL, &moved, NULL) || !(moved.amplitude > own_change))
    return NAN;
  *moved_snr = snr;
  return other;
}

/* The temporal noise of one pixel, from the differences of adjacent rows: the stripes vary
 * along x only, the object mostly slowly along y, so the median absolute difference of row
 * pairs is noise (edges along x, a few per cent of the pairs, do not move a median). The
 * single-frame fit's own residual would count the object's texture and the square stripes'
 * harmonics as noise, which they are not to a model that holds them fixed. Up to 32 pairs of
 * rows and 256 columns of each: 8192 differences put the median within about 1.4 %, and
 * 64 x 1024 made the verify stage 0.52-0.57 ms per 1 MP frame on the acquisition thread
 * instead of 0.28-0.32 (bench-daemon-rate's stage means); a bounded cost whatever the frame. */
#define NOISE_ROW_PAIRS 32
#define NOISE_COLUMNS 256

/* The k-th smallest (0-based) of n doubles, by selection (Wirth's): O(n); reorders d. */
static double
kth_smallest (double *d, gsize n, gsize k)
{
  gssize l = 0, m = (gssize) n - 1, mid = (gssize) k;
  while (l < m) {
    double pivot = d[mid];
    gssize i = l, j = m;
    do {
      while (d[i] < pivot)
        i++;
      while (pivot < d[j])
        j--;
      if (i <= j) {
        double t = d[i];
        d[i] = d[j];
        d[j] = t;
        i++;
        j--;
      }
    } while (i <= j);
    if (j < mid)
      l = i;
    if (mid < i)
      m = j;
  }
  return d[mid];
}

/* Shot noise makes a pixel's noise grow with its light, and the first harmonic's noise is the
 * mean of the pixels' variances, not the variance of a typical pixel: under square stripes of
 * duty 0.64 over a dark gap the median row difference comes from the gaps' read noise and the
 * harmonic's noise is twice what it says. So the differences are split into classes by the
 * pair's level (its quantiles: equal counts), each class's median gives its variance, and the
 * variances are averaged over the pixels. */
#define NOISE_LEVEL_CLASSES 4

double
ds_phase_check_pixel_noise (const DsImage *frame)
{
  if (frame->height < 2)
    return INFINITY;
  guint pairs = MIN (NOISE_ROW_PAIRS, frame->height / 2);
  guint xstep = MAX (1u, frame->width / NOISE_COLUMNS);
  guint cols = (frame->width + xstep - 1) / xstep;
  gsize cap = (gsize) pairs * cols, n = 0;
  g_autofree double *d = g_new (double, 3 * cap);
  double *level = d + cap, *work = d + 2 * cap;
  for (guint i = 0; i < pairs; i++) {
    guint y = (guint) (((guint64) i * (frame->height - 1)) / pairs);
    const void *r0 = ds_image_row (frame, y), *r1 = ds_image_row (frame, y + 1);
    for (guint x = 0; x < frame->width; x += xstep) {
      double a = ds_image_sample (frame, r0, x), b = ds_image_sample (frame, r1, x);
      if (isfinite (a) && isfinite (b)) {
        d[n] = fabs (b - a);
        level[n++] = a + b;
      }
    }
  }
  if (n == 0)
    return INFINITY;
  /* The class bounds: levels at the quantiles j / NOISE_LEVEL_CLASSES; a pair is in the class
   * of the bounds at or below its level. */
  double bound[NOISE_LEVEL_CLASSES];
  memcpy (work, level, n * sizeof *work);
  for (guint j = 1; j < NOISE_LEVEL_CLASSES; j++)
    bound[j] = kth_smallest (work, n, j * n / NOISE_LEVEL_CLASSES);
  double sum_var = 0;
  for (guint cls = 0; cls < NOISE_LEVEL_CLASSES; cls++) {
    gsize m = 0;
    for (gsize i = 0; i < n; i++) {
      guint of = 0;
      for (guint j = 1; j < NOISE_LEVEL_CLASSES; j++)
        of += level[i] >= bound[j];
      if (of == cls)
        work[m++] = d[i];
    }
    if (m == 0)
      continue;
    /* |N(0, 2 s^2)| has median 0.6745 sqrt(2) s. */
    double s = kth_smallest (work, m, m / 2) / (0.6745 * G_SQRT2);
    sum_var += s * s * (double) m;
  }
  double sigma = sqrt (sum_var / (double) n);
  /* Integer samples are no finer than their quantisation (1/sqrt(12) DN). */
  if (frame->type != DS_SAMPLE_F32)
    sigma = MAX (sigma, 1.0 / sqrt (12.0));
  return sigma;
}

/* The message for a frame without stripes at the configured period; returns the period the
 * frame does show (stripes of another period: a wrong period-px, or another pattern lit), NAN
 * when none stands out. */
static double
no_stripes (const DsPhaseCheck *check, const DsImage *profile, const DsStripePhase *sp, guint k, char **why)
{
  /* Say what to check: a wrong period-px shows as stripes at another period. */
  double found_snr = 0;
  double found = dominant_period (profile, &found_snr);
  if (isfinite (found))
    *why = g_strdup_printf ("no stripes at the configured period of %.1f px to verify phase %u (snr %.1f < %.1f), "
                            "but the frame shows stripes with a period of about %.1f px (snr %.0f): "
                            "check [illuminator] period-px (the period as the camera sees it)",
                            check->period_px, k, sp->snr, check->min_confidence, found, found_snr);
  else
    *why = g_strdup_printf ("no stripes in the frame to verify phase %u (snr %.1f < %.1f at the configured "
                            "period of %.1f px, and no other period stands out): check that the illuminator "
                            "lights the camera's field of view, and the exposure (too much scattering or "
                            "too little light leaves no measurable stripes)",
                            k, sp->snr, check->min_confidence, check->period_px);
  return found;
}

static double
cycles_of (const double c[2])
{
  double p = atan2 (c[1], c[0]) / (2.0 * G_PI);
  return p - floor (p);
}

static void
set_mean (const DsPhaseCheck *check, guint k, double m[2])
{
  m[0] = check->set_sum[k][0] / check->set_count[k];
  m[1] = check->set_sum[k][1] / check->set_count[k];
}

/* The margin a separation must have over the noise for a frame equal (within the noise) to
 * another phase's to be called a repeat of it: the decision threshold is halfway between the
 * two hypotheses ("repeat": distance 0; "correct": the expected separation), and a correct
 * frame must not cross it by noise, so the separation must be 2 x PHASE_CHECK_SIGMAS noise.
 * Known from the templates (the same scene's frames of each phase), that is the margin. Known
 * only from the pairs of adjacent phases the set has shown so far, it is doubled: the object's
 * texture at twice the stripe frequency moves the other way (DFT bin -1 over the phases) and
 * makes the separation of adjacent phases vary as |b1| +- |b-1| along the set, a ratio of 2
 * for |b-1| = |b1| / 3 (the texture of a transmittance in [0, 1] that dims a third of the
 * light at that frequency). */
#define REPEAT_MARGIN_TEMPLATES (2.0 * PHASE_CHECK_SIGMAS)
#define REPEAT_MARGIN_SET (4.0 * PHASE_CHECK_SIGMAS)

/* The least separation expected between the first harmonics of correct frames of phases k and
 * h, in units of the noise margin it needs: >= 1 means a frame as close to h's as the noise is
 * not a correct frame of k. From the templates, scaled to the frame's exposure (|c| / |T_k|);
 * else from the closest pair of adjacent phases the set holds, scaled to the distance between
 * k and h as a first harmonic moves (2 |a| sin(pi dk / N)). When neither is known (the set's
 * second phase, or N = 2, in a first set), INFINITY: the illuminator moves its stripes with the
 * phase, so a correct frame differs from another phase's unless the scene is known to hide
 * that (check->still: 0). */
static double
separation_margin (const DsPhaseCheck *check, const double c[2], guint k, guint h, guint n, double noise)
{
  if (check->prior_n == n) {
    double tk = hypot (check->prior[k][0], check->prior[k][1]);
    if (!(tk > 0))
      return 0; /* the template shows no stripes at k: known not to move */
    double sep = hypot (c[0], c[1]) / tk * hypot (check->prior[k][0] - check->prior[h][0], check->prior[k][1] - check->prior[h][1]);
    return sep / (REPEAT_MARGIN_TEMPLATES * noise);
  }
  double closest = INFINITY;
  for (guint g = 0; g < n && n > 2; g++) {
    guint g1 = (g + 1) % n;
    if (check->set_count[g] == 0 || check->set_count[g1] == 0)
      continue;
    double a[2], b[2];
    set_mean (check, g, a);
    set_mean (check, g1, b);
    closest = MIN (closest, hypot (a[0] - b[0], a[1] - b[1]));
  }
  if (!isfinite (closest))
    return check->still ? 0 : INFINITY;
  guint dk = (k + n - h) % n;
  dk = MIN (dk, n - dk);
  return closest * sin (G_PI * dk / n) / sin (G_PI / n) / (REPEAT_MARGIN_SET * noise);
}

/* Two exposures differ by their noise, a duplicated buffer (the same exposure delivered twice)
 * not at all: first harmonics closer than this fraction of the noise of their difference are
 * the same exposure whatever the stripes, and a repeat. Two independent exposures come that
 * close with probability 1 - exp (-f^2 / 2) = 5e-5 (Rayleigh), and the re-acquired frame is
 * a new exposure: no correct frame is refused twice for it. */
#define IDENTICAL_FRACTION 0.01

typedef enum { REPEAT_NONE, REPEAT_UNDECIDED, REPEAT_DECIDED } RepeatKind;

/* A frame equal, within its noise, to the frames already accepted for another phase h: a
 * duplicated or stale frame unless correct frames of k and h are known to lie closer than the
 * noise can tell (separation_margin), in which case the frames cannot tell k from h. Returns
 * the kind and *h. */
static RepeatKind
repeat_of (const DsPhaseCheck *check, const double c[2], double sigma, guint k, guint n, guint *h_out,
           gboolean *by_prior)
{
  *by_prior = FALSE;
  if (check->set_n != n)
    return REPEAT_NONE;
  RepeatKind kind = REPEAT_NONE;
  double best = INFINITY;
  for (guint h = 0; h < n; h++) {
    if (h == k || check->set_count[h] == 0)
      continue;
    double m[2];
    set_mean (check, h, m);
    double noise = sigma * sqrt (1.0 + 1.0 / check->set_count[h]);
    double d = hypot (c[0] - m[0], c[1] - m[1]);
    if (d > PHASE_CHECK_SIGMAS * noise)
      continue;
    double margin = separation_margin (check, c, k, h, n, noise);
    gboolean identical = d <= IDENTICAL_FRACTION * noise;
    RepeatKind this = margin >= 1.0 || identical ? REPEAT_DECIDED : REPEAT_UNDECIDED;
    /* A decided repeat outranks an undecided one; among equals, the nearest. */
    if (this > kind || (this == kind && d < best)) {
      kind = this;
      best = d;
      *h_out = h;
      *by_prior = isinf (margin) && !identical;
    }
  }
  return kind;
}

static void
set_add (DsPhaseCheck *check, const double c[2], double sigma, guint k, gboolean verified, const DsImage *profile,
         double level)
{
  guint pw = MIN (profile->width, DS_PHASE_CHECK_PROFILE_MAX);
  if (check->profile_frames > 0 && check->profile_width != pw) {
    /* frames of another size in one set: what the earlier ones share says nothing of it */
    check->profile_frames = 0;
    check->pending = FALSE;
  }
  check->level_sum = (check->profile_frames ? check->level_sum : 0.0) + level;
  check->level_min = check->profile_frames ? MIN (check->level_min, level) : level;
  check->level_max = check->profile_frames ? MAX (check->level_max, level) : level;
  const float *v = ds_image_row (profile, 0);
  for (guint x = 0; x < pw; x++)
    check->profile_sum[x] = (check->profile_frames ? check->profile_sum[x] : 0.0) + v[x];
  check->profile_width = pw;
  check->profile_frames++;
  check->set_frames++;
  check->set_noise2 = MAX (check->set_noise2, sigma * sigma);
  check->set_sum[k][0] += c[0];
  check->set_sum[k][1] += c[1];
  check->set_sumsq[k] += c[0] * c[0] + c[1] * c[1];
  check->set_level[k] += level;
  check->set_count[k]++;
  if (!verified) {
    check->set_unverified++;
    check->unverified++;
  }
}

/* The frame against the last set's frames (the templates), as a classifier between "phase k"
 * and the other phases: each phase's template carries the scene's bias, so the frame's phase is
 * compared with theirs, and the boundary of k is halfway to the nearest other template (half a
 * step for a pure first harmonic; less where the fixed part crowds them), or the configured
 * tolerance if narrower. The angle is scale-free: a set at another exposure keeps it. The noise
 * is the frame's and the template's. Returns OK (k fits), WRONG (k does not, the templates can
 * tell), or UNVERIFIABLE (they cannot: the boundary is within PHASE_CHECK_SIGMAS of the noise);
 * *best_h the nearest template, *err the distance to k's, *tol_k the boundary (cycles). */
static DsPhaseVerdict
template_verdict (const DsPhaseCheck *check, const double c[2], double sigma, guint k, guint n, guint *best_h,
                  double *err, double *tol_k)
{
  double phase = cycles_of (c), amp = hypot (c[0], c[1]);
  double tk = hypot (check->prior[k][0], check->prior[k][1]);
  double gap = INFINITY, best = INFINITY;
  *best_h = k;
  for (guint h = 0; h < n; h++) {
    double e = fabs (ds_stripe_phase_diff (phase, cycles_of (check->prior[h])));
    if (e < best) {
      best = e;
      *best_h = h;
    }
    if (h != k)
      gap = MIN (gap, fabs (ds_stripe_phase_diff (cycles_of (check->prior[k]), cycles_of (check->prior[h]))));
  }
  *err = fabs (ds_stripe_phase_diff (phase, cycles_of (check->prior[k])));
  *tol_k = MIN (check->tolerance_cycles, 0.5 * gap);
  /* The template is the mean of the last set's frames of phase k: its noise is at most one
   * frame's (at the templates' own exposure, sigma scaled by |c| / |T_k|). */
  double noise_cycles = sigma / amp * G_SQRT2 / (2.0 * G_PI);
  if (!(tk > 0) || !(PHASE_CHECK_SIGMAS * noise_cycles <= *tol_k))
    return DS_PHASE_VERDICT_UNVERIFIABLE;
  return *err <= *tol_k ? DS_PHASE_VERDICT_OK : DS_PHASE_VERDICT_WRONG;
}

/* b and a fitted to the set's frames (the phases it holds but `skip`, at least two; skip >= n:
 * none left out): FALSE when they do not determine them. */
static gboolean
set_fit (const DsPhaseCheck *check, guint n, guint skip, double a[2], double b[2])
{
  if (check->set_n != n)
    return FALSE;
  /* Normal equations of min sum_h |m_h - b - a z_h|^2 over the phases the set holds, z_h on the
   * unit circle: b K + a S = M, b conj(S) + a K = Z, with S = sum z_h, M = sum m_h,
   * Z = sum conj(z_h) m_h. */
  double K = 0, S[2] = { 0, 0 }, M[2] = { 0, 0 }, Z[2] = { 0, 0 };
  for (guint h = 0; h < n; h++) {
    if (check->set_count[h] == 0 || h == skip)
      continue;
    double m[2], w = 2.0 * G_PI * (double) h / n;
    set_mean (check, h, m);
    K += 1;
    S[0] += cos (w);
    S[1] += sin (w);
    M[0] += m[0];
    M[1] += m[1];
    Z[0] += cos (w) * m[0] + sin (w) * m[1];
    Z[1] += cos (w) * m[1] - sin (w) * m[0];
  }
  double det = K * K - (S[0] * S[0] + S[1] * S[1]);
  if (K < 2 || !(det > 1e-9 * K * K))
    return FALSE;
  /* a = (K Z - conj(S) M) / det, b = (M - a S) / K */
  a[0] = (K * Z[0] - (S[0] * M[0] + S[1] * M[1])) / det;
  a[1] = (K * Z[1] - (S[0] * M[1] - S[1] * M[0])) / det;
  b[0] = (M[0] - (a[0] * S[0] - a[1] * S[1])) / K;
  b[1] = (M[1] - (a[0] * S[1] + a[1] * S[0])) / K;
  return TRUE;
}

/* How strong the first harmonic of a correct frame of phase k is expected to be at least, from
 * what is known of the scene, in the DN of the frames; INFINITY when nothing is known yet.
 *
 * The physics: a frame's first harmonic at the stripe period is c_k = b + a e^{i 2 pi k / N}
 * + the smaller bins: a moves with the illuminator (the projected stripes on the object's mean),
 * b does not (the object's own texture at the stripe period under the stripes' mean). A correct
 * frame shows no stripes only where b cancels a e^{i 2 pi k / N}, or where the scene lets no
 * stripes through at all; the illuminator projects stripes at every phase, so without evidence
 * of either, stripes are expected (INFINITY). The evidence:
 * - templates (the last verified set's frames): |T_k|, phase k's own, which carries b;
 * - else the set's frames of at least two phases: b and a fitted to them by least squares,
 *   |b + a e^{i 2 pi k / N}| less |a| / 2 for the bins the fit leaves out (the texture at twice
 *   the stripe frequency, bin -1, reaches a third of |a| for a transmittance in [0, 1]; the
 *   square stripes' aliased harmonics less) and for its own error. */
static double
expected_stripes (const DsPhaseCheck *check, guint k, guint n)
{
  if (check->prior_n == n)
    return hypot (check->prior[k][0], check->prior[k][1]);
  double a[2], b[2];
  if (!set_fit (check, n, n, a, b))
    return INFINITY;
  double w = 2.0 * G_PI * (double) k / n;
  double pred[2] = { b[0] + a[0] * cos (w) - a[1] * sin (w), b[1] + a[0] * sin (w) + a[1] * cos (w) };
  return MAX (0.0, hypot (pred[0], pred[1]) - 0.5 * hypot (a[0], a[1]));
}

/* The illuminator's light in the profile's mean is at least half the amplitude of the part of
 * its first harmonic that moves with the phase: light is never negative, and a non-negative
 * profile's first harmonic is at most twice its mean (a comb of narrow stripes; sine stripes
 * of full contrast, once). So a frame lit without the illuminator lies at least |a| / 2 below
 * the set's frames, and a correct one only by its noise and how the light varies between the
 * set's frames: the decision is taken at |a| / 4, halfway, and never within 5 noise sigmas of
 * the set's level or twice the spread of the set's own levels. Returns how far below the set
 * the frame lies beyond that threshold (> 0: unlit), with the figures for the message. */
static double
unlit_margin (const DsPhaseCheck *check, guint n, double level, double sigma, double *drop, double *moving)
{
  *drop = *moving = 0;
  if (check->profile_frames == 0 || !(sigma > 0) || !isfinite (level))
    return -INFINITY;
  double a[2], b[2];
  if (set_fit (check, n, n, a, b))
    *moving = hypot (a[0], a[1]);
  else if (check->prior_n == n) {
    double b1[2] = { 0, 0 };
    for (guint h = 0; h < n; h++) {
      double w = -2.0 * G_PI * (double) h / n;
      b1[0] += (check->prior[h][0] * cos (w) - check->prior[h][1] * sin (w)) / n;
      b1[1] += (check->prior[h][0] * sin (w) + check->prior[h][1] * cos (w)) / n;
    }
    *moving = hypot (b1[0], b1[1]);
  } else
    return -INFINITY;
  *drop = check->level_sum / check->profile_frames - level;
  double threshold = MAX (0.25 * *moving, MAX (PHASE_CHECK_SIGMAS * sigma * sqrt (1.0 + 1.0 / check->profile_frames),
                                               2.0 * (check->level_max - check->level_min)));
  return *drop - threshold;
}

/* The frame's profile against the set's accepted frames (moving_period): FALSE when the set
 * holds none of its size to compare with; else *moved the period of another pattern's stripes
 * that changed, NAN when none did. */
static gboolean
against_set (const DsPhaseCheck *check, const DsImage *profile, double *moved, double *moved_snr)
{
  *moved = NAN;
  *moved_snr = 0;
  guint pw = MIN (profile->width, DS_PHASE_CHECK_PROFILE_MAX);
  if (check->profile_frames == 0 || check->profile_width != pw)
    return FALSE;
  g_autoptr (DsImage) d = ds_image_new (DS_SAMPLE_F32, pw, 1, NULL);
  if (!d)
    return FALSE;
  float *dv = ds_image_row (d, 0);
  const float *pv = ds_image_row (profile, 0);
  for (guint x = 0; x < pw; x++)
    dv[x] = (float) (pv[x] - check->profile_sum[x] / check->profile_frames);
  *moved = moving_period (check, d, moved_snr);
  return TRUE;
}

DsPhaseVerdict
ds_phase_check_frame (DsPhaseCheck *check, const DsImage *frame, guint k, guint n,
                      double *measured_cycles, char **why)
{
  DsStripePhase sp;
  g_autoptr (GError) error = NULL;
  *measured_cycles = NAN;
  check->frame_width = frame->width;
  DsImage rows = *frame;
  guint step = frame->height / PHASE_CHECK_MIN_ROWS;
  if (step > 1) {
    rows.stride = frame->stride * step;
    rows.height = frame->height / step;
    rows.allocation = NULL;
  }
  if (n > DS_PHASE_CHECK_MAX_PHASES || k >= n) {
    *why = g_strdup_printf ("phase %u of %u: the phase check handles up to %u phases", k, n,
                            DS_PHASE_CHECK_MAX_PHASES);
    check->unverified++;
    return DS_PHASE_VERDICT_UNVERIFIABLE;
  }
  g_autoptr (DsImage) profile = column_profile (&rows);
  if (!profile || !ds_stripe_phase_measure (profile, check->period_px, NULL, &sp, &error)) {
    /* Nothing measured is nothing known: refused like a frame without stripes. */
    *why = g_strdup_printf ("stripe phase not measurable: %s", error ? error->message : "no column profile of the frame");
    return DS_PHASE_VERDICT_NO_STRIPES;
  }
  *measured_cycles = sp.phase;
  if (check->set_frames > 0 && check->set_n != n) /* a caller that changed N within a set */
    ds_phase_check_begin_set (check);
  check->set_n = n;
  /* The noise of c per component: a profile of R rows fitted over C columns has
   * var = 2 sigma_pixel^2 / (R C); the fit's own residual, which counts the object's texture
   * and the square stripes' harmonics as noise, is the upper bound. */
  double sigma = MIN (sp.amplitude / sp.snr,
                      ds_phase_check_pixel_noise (frame) * sqrt (2.0 / ((double) rows.height * sp.columns_used)));
  /* Stripes are there when the first harmonic stands 5 sigma above the pixel noise and is not
   * lost in the rest of the frame's structure it was fitted against (the fit's own snr >= 0.3:
   * a wrong period-px leaves a harmonic of snr 0.1 that the pixel noise alone would pass; the
   * object's texture on heavily scattered square stripes brings a right one down to 0.7,
   * tests/daemon/test_phase_check.c). */
  /* Below that fit snr, the harmonic still counts when it stands out of the pixel noise and no
   * other period stands out of the frame (dominant_period: the structure the fit met is the
   * object's, not another pattern's): fine stripes on a textured object (periods near 2.5 px
   * under a black level leave a fit snr of 0.05 with the stripes at 10 noise sigmas). */
  double noise_snr = sigma > 0 ? sp.amplitude / sigma : 0;
  double fit_snr = sp.snr;
  double other_snr = 0;
  if (sp.amplitude > 0 && sigma > 0 &&
      (sp.snr >= 0.3 || (noise_snr >= DS_STRIPE_PHASE_MIN_SNR && !isfinite (dominant_period (profile, &other_snr))))) {
    sp.snr = noise_snr;
    sp.reliable = sp.snr >= DS_STRIPE_PHASE_MIN_SNR;
  }
  double c[2] = { sp.amplitude * cos (2.0 * G_PI * sp.phase), sp.amplitude * sin (2.0 * G_PI * sp.phase) };
  /* A frame without stripes at the configured period. Another pattern's stripes (a wrong
   * period-px, another pattern lit) are never a correct frame's: refused; but another period
   * that stays put between the set's frames is the object's texture, and says nothing of the
   * illuminator (moving_period). A frame whose light fell by what the illuminator adds is
   * unlit: refused (unlit_margin). Otherwise it is refused
   * where the scene is expected to show stripes at phase k at 2 x PHASE_CHECK_SIGMAS of the
   * frame's noise (a correct frame then falls below the PHASE_CHECK_SIGMAS that make stripes
   * with probability 3e-7): an illuminator switched off, a frame of the dark, a surplus frame.
   * It passes unverified (joins the set, checked as a whole) only where the scene is known to
   * show no stripes there (expected_stripes). */
  if (!sp.reliable || sp.snr < check->min_confidence || !(sigma > 0)) {
    double noise = isfinite (sigma) && sigma > 0 ? sigma : sp.amplitude;
    double other = no_stripes (check, profile, &sp, k, why);
    gboolean pend = FALSE;
    if (isfinite (other)) {
      /* Another period. Another illuminator's stripes (a wrong period-px, another pattern)
       * move between the set's frames; the object's texture, lit by the same mean light at
       * every phase, does not: judged against the frames the set holds, or, when it holds none
       * yet of this size, by ds_phase_check_confirm against those that follow. */
      double moved_snr = 0, moved = NAN;
      if (!against_set (check, profile, &moved, &moved_snr))
        pend = TRUE;
      else {
        if (isfinite (moved)) {
          char *said = *why;
          *why = g_strdup_printf ("%s; against the set's other frames, stripes of about %.1f px changed more than "
                                  "the configured ones (snr %.0f): another pattern's, not the object's texture, "
                                  "which stays put",
                                  said, moved, moved_snr);
          g_free (said);
          return DS_PHASE_VERDICT_NO_STRIPES;
        }
        /* The object's: the frame is one without stripes at the configured period. */
        g_free (*why);
        *why = g_strdup_printf ("no stripes at the configured period of %.1f px to verify phase %u (snr %.1f < %.1f); "
                                "the structure of about %.1f px the frame shows is the same in the set's other "
                                "frames (the object's)",
                                check->period_px, k, sp.snr, check->min_confidence, other);
      }
    }
    double drop, moving;
    if (unlit_margin (check, n, sp.mean, noise, &drop, &moving) > 0) {
      g_free (*why);
      *why = g_strdup_printf ("no stripes at the configured period of %.1f px to verify phase %u (snr %.1f < %.1f), "
                              "and the frame's light lies %.1f DN below the set's other frames, where the "
                              "illuminator's is at least %.1f DN: a frame without the illuminator's light",
                              check->period_px, k, sp.snr, check->min_confidence, drop, 0.5 * moving);
      return DS_PHASE_VERDICT_NO_STRIPES;
    }
    double expected = expected_stripes (check, k, n);
    /* Nothing known yet (the set's first phases, no templates): the projected stripes are
     * expected, and a frame without them is refused, so that a frame of the dark costs one
     * retry. But b may cancel a at phase k (the object's texture at the stripe period), and
     * then every frame of k shows none, however often it is taken: judged only against the
     * set's other phases, which fit b and a. So the frame taken again that shows none either
     * joins the set, and ds_phase_check_confirm judges it. */
    gboolean defer = FALSE;
    if (!isfinite (expected)) {
      defer = (check->set_refused_bare >> k & 1) != 0;
      check->set_refused_bare |= G_GUINT64_CONSTANT (1) << k;
    }
    if (!defer && !(expected < 2.0 * PHASE_CHECK_SIGMAS * noise)) {
      char *said = *why;
      *why = isfinite (expected)
                 ? g_strdup_printf ("%s; the scene shows stripes there (%s: %.0f noise sigmas expected at phase %u)", said,
                                    check->prior_n == n ? "the last set's frame of that phase" : "the set's other frames",
                                    expected / noise, k)
                 : g_strdup_printf ("%s; nothing shows yet that the scene hides the projected stripes", said);
      g_free (said);
      return DS_PHASE_VERDICT_NO_STRIPES;
    }
    set_add (check, c, noise, k, FALSE, profile, sp.mean);
    if (defer)
      check->set_deferred |= G_GUINT64_CONSTANT (1) << k;
    if (pend) {
      check->pending = TRUE;
      check->pending_k = k;
      memcpy (check->pending_profile, ds_image_row (profile, 0), check->profile_width * sizeof (float));
    }
    return DS_PHASE_VERDICT_UNVERIFIABLE;
  }
  double sigma_cycles = sigma / sp.amplitude / (2.0 * G_PI);
  double tol = check->tolerance_cycles;
  if (!(PHASE_CHECK_SIGMAS * sigma_cycles <= tol)) {
    /* Stripes too weak to tell the phase: the frame joins the set unverified, so it must at
     * least be the illuminator's. Where the frame holds much more than its stripes and its
     * noise (the fit's residual twice the pixel noise), that may be another pattern's stripes
     * beside a weak first harmonic of the object's texture at the configured period:
     * judged against the set's frames as a frame without stripes is (moving_period). */
    double moved, moved_snr;
    if (fit_snr < 0.5 * noise_snr && against_set (check, profile, &moved, &moved_snr) && isfinite (moved)) {
      *why = g_strdup_printf ("stripes too weak to verify phase %u of %u (snr %.0f), and against the set's other "
                              "frames stripes of about %.1f px changed more than the configured ones (snr %.0f): "
                              "another pattern's: check [illuminator] period-px",
                              k, n, sp.amplitude / sigma, moved, moved_snr);
      return DS_PHASE_VERDICT_NO_STRIPES;
    }
    *why = g_strdup_printf ("stripes too weak to verify phase %u of %u: the measured phase's noise (%.2f deg) "
                            "times %.0f exceeds the tolerance of %.1f deg (snr %.0f; more light or "
                            "averaging, or fewer phases)",
                            k, n, sigma_cycles * 360.0, PHASE_CHECK_SIGMAS, tol * 360.0, sp.amplitude / sigma);
    set_add (check, c, sigma, k, FALSE, profile, sp.mean);
    return DS_PHASE_VERDICT_UNVERIFIABLE;
  }
  guint rep = n;
  gboolean by_prior = FALSE;
  RepeatKind repeat = repeat_of (check, c, sigma, k, n, &rep, &by_prior);
  if (repeat == REPEAT_DECIDED && by_prior) {
    /* Decided by the prior alone (the projected stripes move). A stale frame shows the light
     * lit before the last move; once phase k was applied again for the retry, that light is k
     * itself. So a frame of k that repeats h again after it was refused for it shows that the
     * scene moves its first harmonic less than the noise between these phases (stripes the
     * scattering or the blur took, beside texture at the stripe period): from then on such
     * frames pass unverified and the set is checked as a whole. */
    if (check->set_refused_as[k] == rep + 1) {
      check->still = TRUE;
      repeat = REPEAT_UNDECIDED;
    } else
      check->set_refused_as[k] = (guint8) (rep + 1);
  }
  if (repeat == REPEAT_DECIDED) {
    *why = g_strdup_printf ("frame for phase %u repeats the set's frame of phase %u (looks like phase %u: "
                            "a duplicated or stale frame)",
                            k, rep, rep);
    return DS_PHASE_VERDICT_WRONG;
  }
  if (repeat == REPEAT_UNDECIDED) {
    *why = g_strdup_printf ("frame for phase %u equals the set's frame of phase %u within the noise, and the "
                            "stripes that move with the phase are too weak so far to tell a repeat from a "
                            "correct frame: the set is checked as a whole",
                            k, rep);
    set_add (check, c, sigma, k, FALSE, profile, sp.mean);
    return DS_PHASE_VERDICT_UNVERIFIABLE;
  }
  gboolean templates = check->prior_n == n;
  if (check->set_frames == 0)
    check->set_by_template = FALSE;
  if (templates && (check->set_frames == 0 || check->set_by_template)) {
    guint best_h = k;
    double err = 0, tol_k = tol;
    DsPhaseVerdict tv = template_verdict (check, c, sigma, k, n, &best_h, &err, &tol_k);
    if (tv == DS_PHASE_VERDICT_OK && check->set_frames == 0)
      check->set_by_template = TRUE;
    else if (tv == DS_PHASE_VERDICT_WRONG) {
      /* The set's first frame: wrong only if it fits another phase's template as well as a
       * correct frame fits its own (a stale or early frame of an unchanged scene); otherwise
       * the scene changed under the templates and the set is checked as a whole. */
      double best = fabs (ds_stripe_phase_diff (cycles_of (c), cycles_of (check->prior[best_h])));
      if (check->set_by_template || (best_h != k && best <= tol_k / 4)) {
        *why = g_strdup_printf ("frame for phase %u looks like phase %u of %u: off by %.1f deg from the last set's "
                                "frame of phase %u, %.1f deg from its frame of phase %u (tolerance %.1f deg, "
                                "halfway to the nearest other phase's frame)",
                                k, best_h, n, err * 360.0, k, best * 360.0, best_h, tol_k * 360.0);
        return DS_PHASE_VERDICT_WRONG;
      }
    }
  }
  set_add (check, c, sigma, k, TRUE, profile, sp.mean);
  return DS_PHASE_VERDICT_OK;
}

/* The complete set's adjacent phases: a pair whose first harmonics are equal within the noise is
 * a repeat when the set's other adjacent pairs lie REPEAT_MARGIN_SET noise sigmas apart (FALSE
 * with a message), else the set cannot tell its phases apart (*undecided). */
static gboolean
set_has_no_repeat (const DsPhaseCheck *check, guint n, double noise, gboolean *undecided, char **why)
{
  guint suspect = n, pairs = n == 2 ? 1 : n, suspects = 0;
  double closest_other = INFINITY;
  for (guint g = 0; g < pairs; g++) {
    double a[2], b[2];
    set_mean (check, g, a);
    set_mean (check, (g + 1) % n, b);
    double d = hypot (a[0] - b[0], a[1] - b[1]);
    if (d <= PHASE_CHECK_SIGMAS * noise) {
      suspects++;
      if (suspect == n)
        suspect = g;
    } else
      closest_other = MIN (closest_other, d);
  }
  if (suspect == n)
    return TRUE;
  /* Judged against the pairs that do differ, while they are the most: more repeats than
   * differing pairs is a scene whose phases do not move its first harmonic. */
  if (2 * suspects <= pairs && isfinite (closest_other) && closest_other >= REPEAT_MARGIN_SET * noise) {
    *why = g_strdup_printf ("phase check of the whole set: its frame of phase %u repeats its frame of phase %u "
                            "(equal within the noise, where the other adjacent phases are %.0f noise sigmas "
                            "apart: a duplicated or stale frame)",
                            (suspect + 1) % n, suspect, closest_other / noise);
    return FALSE;
  }
  *undecided = TRUE;
  return TRUE;
}

/* Each phase's moving part (less bin 0) must be one step on from the previous phase's, within
 * 3/4 of a step: the errors a complete set without repeats can still hold are swapped frames
 * (steps of +2, -1, +2: off by a whole step or more), and the bias the scene's other bins leave
 * on a step reaches half a step (1-px stripes of period 4 at N = 16 on a grid at twice the
 * period: tests/daemon/test_phase_check.c). Only where the noise of a step is PHASE_CHECK_SIGMAS
 * inside the quarter step left (*undecided otherwise). */
static gboolean
set_steps_by_one (DsPhaseCheck *check, guint n, const double b0[2], double amp, double noise, double tol,
                  gboolean *undecided, char **why)
{
  /* The projected pattern's own bend of a step (square stripes at short periods) widens what a
   * correct step may show. A wrong frame that is not a repeat (the test before this one) puts a
   * step two or more off somewhere: neighbours swapped give +1, -2, +1; a frame of phase h + j
   * in place of h gives +j, -j. That must still stand out, less the bend, beyond the widened
   * tolerance; where the bend leaves no such margin the set cannot tell its steps apart
   * (*undecided). */
  double bend = 0;
  if (check->pattern_known && check->frame_width > 0) {
    if (check->bend_n != n || check->bend_width != check->frame_width) {
      check->bend_cycles = ds_phase_check_pattern_bend (check->pattern_square, check->pattern_duty,
                                                        check->period_px, check->frame_width, n);
      check->bend_n = n;
      check->bend_width = check->frame_width;
    }
    bend = check->bend_cycles;
  }
  double step_tol = 0.75 / n + bend;
  if (!(2.0 / n - bend > step_tol) || !(PHASE_CHECK_SIGMAS * noise / amp / (2.0 * G_PI) <= 0.25 / n)) {
    *undecided = TRUE;
    return TRUE;
  }
  for (guint h = 0; h < n; h++) {
    double m0[2], m1[2];
    set_mean (check, h, m0);
    set_mean (check, (h + 1) % n, m1);
    double a0[2] = { m0[0] - b0[0], m0[1] - b0[1] }, a1[2] = { m1[0] - b0[0], m1[1] - b0[1] };
    double step = ds_stripe_phase_diff (cycles_of (a1) - cycles_of (a0), 1.0 / n);
    /* A wrong frame among the phase's averages shows as scatter beyond the noise (of one
     * frame's first harmonic, whatever the size of the moving part). */
    double scatter = check->set_count[h] > 1
                         ? sqrt (MAX (0.0, check->set_sumsq[h] / check->set_count[h] - (m0[0] * m0[0] + m0[1] * m0[1])))
                         : 0.0;
    double scatter_cycles = scatter / amp / (2.0 * G_PI);
    gboolean scattered = scatter_cycles > tol && scatter > PHASE_CHECK_SIGMAS * sqrt (2.0 * check->set_noise2);
    if (fabs (step) > step_tol || scattered) {
      *why = g_strdup_printf ("phase check of the whole set: from phase %u to phase %u of %u the stripes move "
                              "%.2f steps, not 1 (off by %.1f deg, tolerance %.1f deg; spread within the phase %.1f deg, "
                              "tolerance %.1f deg)",
                              h, (h + 1) % n, n, 1.0 + step * n, step * 360.0, step_tol * 360.0,
                              scatter_cycles * 360.0, tol * 360.0);
      return FALSE;
    }
  }
  return TRUE;
}

/* A frame of phase k that showed no stripes while nothing was known (set_deferred), against
 * the set's other phases: b and a fitted to them predict |b + a e^{i 2 pi k / N}| at k, less
 * |a| / 2 for the bins the fit leaves out (expected_stripes); at 2 x PHASE_CHECK_SIGMAS of the
 * noise or more the scene shows stripes there, and the frame was not lit by phase k. And its
 * light must not lie below the others' by what the illuminator adds (unlit_margin's rule:
 * |a| / 4, never within PHASE_CHECK_SIGMAS of the noise nor twice the others' spread).
 * Where the other phases do not fit b and a, nothing tells: the set is judged as a whole. */
static gboolean
deferred_frame_fits (const DsPhaseCheck *check, guint n, guint k, char **why)
{
  double a[2], b[2];
  if (check->set_count[k] == 0 || !set_fit (check, n, k, a, b))
    return TRUE;
  double noise = sqrt (check->set_noise2), moving = hypot (a[0], a[1]);
  double w = 2.0 * G_PI * (double) k / n;
  double pred[2] = { b[0] + a[0] * cos (w) - a[1] * sin (w), b[1] + a[0] * sin (w) + a[1] * cos (w) };
  double expected = hypot (pred[0], pred[1]) - 0.5 * moving;
  if (expected >= 2.0 * PHASE_CHECK_SIGMAS * noise) {
    *why = g_strdup_printf ("phase check of the whole set: its frame of phase %u showed no stripes, where the "
                            "set's other phases show the scene has them (%.0f noise sigmas expected at phase %u)",
                            k, expected / noise, k);
    return FALSE;
  }
  double sum = 0, lo = INFINITY, hi = -INFINITY;
  guint others = 0;
  for (guint h = 0; h < n; h++) {
    if (h == k || check->set_count[h] == 0)
      continue;
    double level = check->set_level[h] / check->set_count[h];
    sum += level;
    lo = MIN (lo, level);
    hi = MAX (hi, level);
    others++;
  }
  double drop = sum / others - check->set_level[k] / check->set_count[k];
  double threshold = MAX (0.25 * moving, MAX (PHASE_CHECK_SIGMAS * noise * sqrt (1.0 + 1.0 / others), 2.0 * (hi - lo)));
  if (drop > threshold) {
    *why = g_strdup_printf ("phase check of the whole set: its frame of phase %u showed no stripes, and its light "
                            "lies %.1f DN below the set's other phases', where the illuminator's is at least "
                            "%.1f DN: a frame without the illuminator's light",
                            k, drop, 0.5 * moving);
    return FALSE;
  }
  return TRUE;
}

gboolean
ds_phase_check_confirm (DsPhaseCheck *check, char **why)
{
  check->provisional = FALSE;
  guint n = check->set_n;
  if (n == 0 || check->set_frames == 0)
    return TRUE;
  guint fewest = G_MAXUINT;
  for (guint h = 0; h < n; h++) {
    if (check->set_count[h] == 0) {
      *why = g_strdup_printf ("phase check: the set has no verified frame of phase %u", h);
      check->prior_n = 0;
      return FALSE;
    }
    fewest = MIN (fewest, check->set_count[h]);
  }
  for (guint k = 0; k < n; k++)
    if ((check->set_deferred >> k & 1) && !deferred_frame_fits (check, n, k, why)) {
      check->prior_n = 0;
      return FALSE;
    }
  /* A frame that showed another period before the set held a frame to compare it with: the
   * set's other frames now tell whether that structure moved (moving_period). */
  if (check->pending && check->profile_frames > 1) {
    guint pw = check->profile_width;
    g_autoptr (DsImage) d = ds_image_new (DS_SAMPLE_F32, pw, 1, NULL);
    if (d) {
      float *dv = ds_image_row (d, 0);
      for (guint x = 0; x < pw; x++)
        dv[x] = (float) (check->pending_profile[x] -
                         (check->profile_sum[x] - check->pending_profile[x]) / (check->profile_frames - 1));
      double moved_snr = 0, moved = moving_period (check, d, &moved_snr);
      if (isfinite (moved)) {
        *why = g_strdup_printf ("phase check of the whole set: its frame of phase %u shows no stripes at the "
                                "configured period of %.1f px, and against the set's other frames stripes of "
                                "about %.1f px changed more than the configured ones (snr %.0f): check "
                                "[illuminator] period-px",
                                check->pending_k, check->period_px, moved, moved_snr);
        check->prior_n = 0;
        return FALSE;
      }
    }
  }
  /* bin 0 (the fixed part) and bin 1 (the moving part) of the DFT over the phases. */
  double b0[2] = { 0, 0 }, b1[2] = { 0, 0 };
  for (guint h = 0; h < n; h++) {
    double m[2];
    set_mean (check, h, m);
    double w = -2.0 * G_PI * (double) h / n;
    b0[0] += m[0] / n;
    b0[1] += m[1] / n;
    b1[0] += (m[0] * cos (w) - m[1] * sin (w)) / n;
    b1[1] += (m[0] * sin (w) + m[1] * cos (w)) / n;
  }
  double set_offset = cycles_of (b1);
  double tol = check->tolerance_cycles;
  double amp = hypot (b1[0], b1[1]);
  /* The noise per component of one phase's mean, and of bin 1 (N means averaged). */
  double noise_mean = sqrt (check->set_noise2 / fewest);
  double noise_b1 = noise_mean / sqrt ((double) n);
  /* Stripes that move with the phase must stand out of the noise for anything to be learned or
   * judged: a set without them cannot be verified (it passes; no offset, no templates). */
  if (!(amp >= PHASE_CHECK_SIGMAS * noise_b1) || !(PHASE_CHECK_SIGMAS * noise_b1 / amp / (2.0 * G_PI) <= 0.5 / n)) {
    check->sets_unverified++;
    check->prior_n = 0;
    return TRUE;
  }
  gboolean undecided = FALSE;
  /* Checked as a whole: the first set, a set whose scene changed, and a set with frames that
   * could not be verified one by one. */
  if (!check->set_by_template || check->set_unverified > 0) {
    if (!set_has_no_repeat (check, n, noise_mean * G_SQRT2, &undecided, why) ||
        (!undecided && !set_steps_by_one (check, n, b0, amp, noise_mean * G_SQRT2, tol, &undecided, why))) {
      check->prior_n = 0;
      return FALSE;
    }
    if (check->offset_known && fabs (ds_stripe_phase_diff (set_offset, check->offset_cycles)) > tol) {
      double off = ds_stripe_phase_diff (set_offset, check->offset_cycles);
      *why = g_strdup_printf ("phase check of the whole set: its frames agree with each other but show phase 0 "
                              "%.1f deg (%.2f phases) from where the illuminator puts it (tolerance %.1f deg)",
                              off * 360.0, off * n, tol * 360.0);
      check->prior_n = 0;
      return FALSE;
    }
  }
  if (undecided) {
    /* Frames the set could not tell apart are no templates for the next set. */
    check->sets_unverified++;
    check->prior_n = 0;
    return TRUE;
  }
  if (check->set_unverified > 0) {
    /* Nor are frames that passed unverified, though the set as a whole holds together: a
     * wrong frame among them would make every correct frame of the next sets look wrong. */
    check->prior_n = 0;
    return TRUE;
  }
  if (!check->offset_known) {
    check->offset_known = TRUE;
    check->offset_cycles = set_offset;
  }
  for (guint h = 0; h < n; h++)
    set_mean (check, h, check->prior[h]);
  check->prior_n = n;
  return TRUE;
}

void
ds_phase_check_abandon (DsPhaseCheck *check)
{
  check->provisional = FALSE;
  check->prior_n = 0;
  check->still = FALSE;
}
