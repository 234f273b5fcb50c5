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
ds_phase_check_begin_set (DsPhaseCheck *check)
{
  check->set_n = 0;
  memset (check->set_sum, 0, sizeof check->set_sum);
  memset (check->set_count, 0, sizeof check->set_count);
  memset (check->set_sumsq, 0, sizeof check->set_sumsq);
  check->set_noise2 = 0;
  check->set_frames = 0;
  check->set_by_template = FALSE;
  check->provisional = TRUE;
}

/* Rows kept for the measurement: the stripes vary along x only, so the rows are averaged into
 * one profile, and beyond a few hundred rows more of them only buy noise margin the check does
 * not need, at a cost (a pass over a 4 MP frame) that sits between the last frame and the
 * result. A view of every step-th row: no copy. */
#define PHASE_CHECK_MIN_ROWS 256

/* The stripe period the frame does show, when the configured one finds nothing: the rows are
 * averaged into one profile, and the first harmonic is fitted at candidate periods 2 % apart,
 * from just above Nyquist to a quarter of the width. The best one, if it is reliable, else NAN.
 * A failure path only (a frame that could not be verified): a few hundred fits of one row. */
static double
dominant_period (const DsImage *rows, double *best_snr)
{
  *best_snr = 0;
  g_autoptr (DsImage) profile = ds_image_new (DS_SAMPLE_F32, rows->width, 1, NULL);
  if (!profile || rows->width < 16)
    return NAN;
  float *out = ds_image_row (profile, 0);
  for (guint x = 0; x < rows->width; x++) {
    double sum = 0;
    for (guint y = 0; y < rows->height; y++) {
      const guint8 *row = ds_image_row (rows, y);
      sum += rows->type == DS_SAMPLE_U8    ? ((const guint8 *) row)[x]
             : rows->type == DS_SAMPLE_U16 ? ((const guint16 *) row)[x]
                                           : ((const float *) row)[x];
    }
    out[x] = (float) (sum / rows->height);
  }
  double best = NAN;
  for (double p = 2.2; p <= rows->width / 4.0; p *= 1.02) {
    DsStripePhase sp;
    if (ds_stripe_phase_measure (profile, p, NULL, &sp, NULL) && sp.reliable && sp.snr > *best_snr) {
      *best_snr = sp.snr;
      best = p;
    }
  }
  return best;
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

/* The k-th smallest (0-based) of n values below 65536: a byte histogram of the high bytes,
 * then of the low bytes of the values in the high byte's bin. Exact, in two passes over n
 * values (the selection below takes several on doubles: about a sixth of the verify stage at
 * 1 MP, bench-daemon-rate's fold thread). */
static guint
kth_smallest_u16 (const guint16 *v, gsize n, gsize k)
{
  gsize hist[256] = { 0 };
  for (gsize i = 0; i < n; i++)
    hist[v[i] >> 8]++;
  guint hi = 0;
  while (k >= hist[hi])
    k -= hist[hi++];
  memset (hist, 0, sizeof hist);
  for (gsize i = 0; i < n; i++)
    if ((guint) (v[i] >> 8) == hi)
      hist[v[i] & 0xff]++;
  guint lo = 0;
  while (k >= hist[lo])
    k -= hist[lo++];
  return hi << 8 | lo;
}

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

double
ds_phase_check_pixel_noise (const DsImage *frame)
{
  if (frame->height < 2)
    return INFINITY;
  guint pairs = MIN (NOISE_ROW_PAIRS, frame->height / 2);
  guint xstep = MAX (1u, frame->width / NOISE_COLUMNS);
  guint cols = (frame->width + xstep - 1) / xstep;
  gsize n = 0;
  double median;
  if (frame->type == DS_SAMPLE_U16 || frame->type == DS_SAMPLE_U8) {
    /* Integer samples: their differences are integers below 65536, every one finite. */
    g_autofree guint16 *d = g_new (guint16, (gsize) pairs * cols);
    for (guint i = 0; i < pairs; i++) {
      guint y = (guint) (((guint64) i * (frame->height - 1)) / pairs);
      const void *r0 = ds_image_row (frame, y), *r1 = ds_image_row (frame, y + 1);
      if (frame->type == DS_SAMPLE_U16)
        for (guint x = 0; x < frame->width; x += xstep)
          d[n++] = (guint16) ABS ((int) ((const guint16 *) r1)[x] - (int) ((const guint16 *) r0)[x]);
      else
        for (guint x = 0; x < frame->width; x += xstep)
          d[n++] = (guint16) ABS ((int) ((const guint8 *) r1)[x] - (int) ((const guint8 *) r0)[x]);
    }
    median = kth_smallest_u16 (d, n, n / 2);
  } else {
    g_autofree double *d = g_new (double, (gsize) pairs * cols);
    for (guint i = 0; i < pairs; i++) {
      guint y = (guint) (((guint64) i * (frame->height - 1)) / pairs);
      const void *r0 = ds_image_row (frame, y), *r1 = ds_image_row (frame, y + 1);
      for (guint x = 0; x < frame->width; x += xstep) {
        double v = fabs (ds_image_sample (frame, r1, x) - ds_image_sample (frame, r0, x));
        if (isfinite (v))
          d[n++] = v;
      }
    }
    if (n == 0)
      return INFINITY;
    median = kth_smallest (d, n, n / 2);
  }
  /* |N(0, 2 s^2)| has median 0.6745 sqrt(2) s. Integer samples are no finer than their
   * quantisation (1/sqrt(12) DN). */
  double sigma = median / (0.6745 * G_SQRT2);
  if (frame->type != DS_SAMPLE_F32)
    sigma = MAX (sigma, 1.0 / sqrt (12.0));
  return sigma;
}

static DsPhaseVerdict
no_stripes (const DsPhaseCheck *check, const DsImage *rows, const DsStripePhase *sp, guint k, char **why)
{
  /* Say what to check: a wrong period-px shows as stripes at another period. */
  double found_snr = 0;
  double found = dominant_period (rows, &found_snr);
  if (isfinite (found))
    *why = g_strdup_printf ("no stripes at the configured period of %.1f px to verify phase %u (snr %.1f < %.1f), "
                            "but the frame shows stripes with a period of about %.1f px (snr %.0f): "
                            "check [illuminator] period-px (the period as the camera sees it)",
                            check->period_px, k, sp->snr, check->min_confidence, found, found_snr);
  else
    *why = g_strdup_printf ("no stripes in the frame to verify phase %u (snr %.1f < %.1f at the configured "
                            "period of %.1f px, and no other period stands out): check that the illuminator "
                            "lights the camera's field of view, and the exposure (too much scattering or "
                            "too little light leaves no measurable stripes; verify-phase=false skips the check)",
                            k, sp->snr, check->min_confidence, check->period_px);
  return DS_PHASE_VERDICT_UNVERIFIABLE;
}

static double
cycles_of (const double c[2])
{
  double p = atan2 (c[1], c[0]) / (2.0 * G_PI);
  return p - floor (p);
}

/* |a|, the size of the part of the first harmonic that moves with the phase: from two phases
 * of the set (their difference is a (e^{i 2 pi h/N} - e^{i 2 pi r/N}): the fixed part cancels),
 * else from the templates, else unknown (0). */
static double
moving_amplitude (const DsPhaseCheck *check, guint n)
{
  guint r = n, l = n;
  for (guint h = 0; h < n; h++)
    if (check->set_count[h] > 0) {
      if (r == n)
        r = h;
      l = h;
    }
  if (r < l) {
    double mr[2] = { check->set_sum[r][0] / check->set_count[r], check->set_sum[r][1] / check->set_count[r] };
    double ml[2] = { check->set_sum[l][0] / check->set_count[l], check->set_sum[l][1] / check->set_count[l] };
    return hypot (ml[0] - mr[0], ml[1] - mr[1]) / (2.0 * fabs (sin (G_PI * (double) (l - r) / n)));
  }
  if (check->prior_n == n) {
    double b1[2] = { 0, 0 };
    for (guint h = 0; h < n; h++) {
      double w = -2.0 * G_PI * (double) h / n;
      b1[0] += (check->prior[h][0] * cos (w) - check->prior[h][1] * sin (w)) / n;
      b1[1] += (check->prior[h][0] * sin (w) + check->prior[h][1] * cos (w)) / n;
    }
    return hypot (b1[0], b1[1]);
  }
  return 0;
}

/* A frame equal, within its noise, to the frames already accepted for another phase h is a
 * repeat of them (a duplicated or stale frame), however the scene biases phases: any two
 * different phases differ by at least |a| |e^{i 2 pi / N} - 1| = 2 |a| sin(pi / N); a quarter
 * of that is the radius (|a| is estimated, and may have changed with the exposure since the
 * templates; unknown, the noise decides). Returns h, or n when there is none. */
static guint
repeat_of (const DsPhaseCheck *check, const double c[2], double sigma, guint k, guint n)
{
  if (check->set_n != n)
    return n;
  double radius = 0.5 * moving_amplitude (check, n) * sin (G_PI / n);
  guint nearest = n;
  double best = INFINITY;
  for (guint h = 0; h < n; h++) {
    if (h == k || check->set_count[h] == 0)
      continue;
    double m[2] = { check->set_sum[h][0] / check->set_count[h], check->set_sum[h][1] / check->set_count[h] };
    double noise = sigma * sqrt (1.0 + 1.0 / check->set_count[h]);
    double d = hypot (c[0] - m[0], c[1] - m[1]);
    /* |a| unknown (the first set's second phase): equal within the noise is a repeat (a
     * correct frame that close to another phase's would have no stripes to verify). */
    double r = radius > 0 ? radius : PHASE_CHECK_SIGMAS * noise;
    if (r >= PHASE_CHECK_SIGMAS * noise && d < r && d < best) {
      best = d;
      nearest = h;
    }
  }
  return nearest;
}

static void
set_add (DsPhaseCheck *check, const double c[2], double sigma, guint k)
{
  check->set_frames++;
  check->set_noise2 = MAX (check->set_noise2, sigma * sigma);
  check->set_sum[k][0] += c[0];
  check->set_sum[k][1] += c[1];
  check->set_sumsq[k] += c[0] * c[0] + c[1] * c[1];
  check->set_count[k]++;
}

static void
set_mean (const DsPhaseCheck *check, guint k, double m[2])
{
  m[0] = check->set_sum[k][0] / check->set_count[k];
  m[1] = check->set_sum[k][1] / check->set_count[k];
}

DsPhaseVerdict
ds_phase_check_frame (DsPhaseCheck *check, const DsImage *frame, guint k, guint n,
                      double *measured_cycles, char **why)
{
  DsStripePhase sp;
  g_autoptr (GError) error = NULL;
  *measured_cycles = NAN;
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
    return DS_PHASE_VERDICT_UNVERIFIABLE;
  }
  if (!ds_stripe_phase_measure (&rows, check->period_px, NULL, &sp, &error)) {
    *why = g_strdup_printf ("stripe phase not measurable: %s", error->message);
    return DS_PHASE_VERDICT_UNVERIFIABLE;
  }
  *measured_cycles = sp.phase;
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
  if (sp.amplitude > 0 && sigma > 0 && sp.snr >= 0.3) {
    sp.snr = sp.amplitude / sigma;
    sp.reliable = sp.snr >= DS_STRIPE_PHASE_MIN_SNR;
  }
  if (!sp.reliable || sp.snr < check->min_confidence)
    return no_stripes (check, &rows, &sp, k, why);
  if (check->set_frames > 0 && check->set_n != n) /* a caller that changed N within a set */
    ds_phase_check_begin_set (check);
  check->set_n = n;
  double c[2] = { sp.amplitude * cos (2.0 * G_PI * sp.phase), sp.amplitude * sin (2.0 * G_PI * sp.phase) };
  double sigma_cycles = sigma / sp.amplitude / (2.0 * G_PI);
  double tol = check->tolerance_cycles;
  if (!(PHASE_CHECK_SIGMAS * sigma_cycles <= tol)) {
    *why = g_strdup_printf ("stripes too weak to verify phase %u of %u: the measured phase's noise (%.2f deg) "
                            "times %.0f exceeds the tolerance of %.1f deg (snr %.0f; more light or "
                            "averaging, or fewer phases)",
                            k, n, sigma_cycles * 360.0, PHASE_CHECK_SIGMAS, tol * 360.0, sp.amplitude / sigma);
    return DS_PHASE_VERDICT_UNVERIFIABLE;
  }
  guint rep = repeat_of (check, c, sigma, k, n);
  if (rep < n) {
    *why = g_strdup_printf ("frame for phase %u repeats the set's frame of phase %u (looks like phase %u: "
                            "a duplicated or stale frame)",
                            k, rep, rep);
    return DS_PHASE_VERDICT_WRONG;
  }
  gboolean templates = check->prior_n == n;
  if (check->set_frames == 0)
    check->set_by_template = FALSE;
  if (templates && (check->set_frames == 0 || check->set_by_template)) {
    double err = ds_stripe_phase_diff (sp.phase, cycles_of (check->prior[k]));
    if (fabs (err) <= tol) {
      if (check->set_frames == 0)
        check->set_by_template = TRUE;
    } else {
      /* The phase whose template the frame matches best. */
      guint best_h = k;
      double best = INFINITY;
      for (guint h = 0; h < n; h++) {
        double e = fabs (ds_stripe_phase_diff (sp.phase, cycles_of (check->prior[h])));
        if (e < best) {
          best = e;
          best_h = h;
        }
      }
      /* The set's first frame: wrong only if it is another phase's template within a quarter
       * of the tolerance (a stale or early frame of an unchanged scene); otherwise the scene
       * changed under the templates and the set is checked as a whole. */
      if (check->set_by_template || (best_h != k && best <= tol / 4)) {
        *why = g_strdup_printf ("frame for phase %u looks like phase %u of %u: off by %.1f deg from the last set's "
                                "frame of phase %u, %.1f deg from its frame of phase %u (tolerance %.1f deg)",
                                k, best_h, n, err * 360.0, k, best * 360.0, best_h, tol * 360.0);
        return DS_PHASE_VERDICT_WRONG;
      }
    }
  }
  set_add (check, c, sigma, k);
  return DS_PHASE_VERDICT_OK;
}

gboolean
ds_phase_check_confirm (DsPhaseCheck *check, char **why)
{
  check->provisional = FALSE;
  guint n = check->set_n;
  if (n == 0 || check->set_frames == 0)
    return TRUE;
  for (guint h = 0; h < n; h++)
    if (check->set_count[h] == 0) {
      *why = g_strdup_printf ("phase check: the set has no verified frame of phase %u", h);
      check->prior_n = 0;
      return FALSE;
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
  if (!check->set_by_template) {
    double amp = hypot (b1[0], b1[1]);
    /* Each phase's moving part (less bin 0) must be one step on from the previous phase's,
     * within 3/4 of a step: the errors a complete set without repeats can still hold are
     * swapped frames (steps of +2, -1, +2: off by a whole step or more), and the bias the
     * scene's other bins leave on a step reaches half a step (1-px stripes of period 4 at
     * N = 16 on a grid at twice the period: tests/daemon/test_phase_check.c). */
    double step_tol = 0.75 / n;
    for (guint h = 0; h < n; h++) {
      double m0[2], m1[2];
      set_mean (check, h, m0);
      set_mean (check, (h + 1) % n, m1);
      double a0[2] = { m0[0] - b0[0], m0[1] - b0[1] }, a1[2] = { m1[0] - b0[0], m1[1] - b0[1] };
      double step = ds_stripe_phase_diff (cycles_of (a1) - cycles_of (a0), 1.0 / n);
      /* A wrong frame among the phase's averages shows as scatter beyond the noise. */
      double scatter = check->set_count[h] > 1
                           ? sqrt (MAX (0.0, check->set_sumsq[h] / check->set_count[h] - (m0[0] * m0[0] + m0[1] * m0[1])))
                           : 0.0;
      double scatter_cycles = scatter / amp / (2.0 * G_PI);
      if (fabs (step) > step_tol || scatter_cycles > tol) {
        *why = g_strdup_printf ("phase check of the whole set: from phase %u to phase %u of %u the stripes move "
                                "%.2f steps, not 1 (off by %.1f deg, tolerance %.1f deg; spread within the phase %.1f deg, "
                                "tolerance %.1f deg)",
                                h, (h + 1) % n, n, 1.0 + step * n, step * 360.0, step_tol * 360.0,
                                scatter_cycles * 360.0, tol * 360.0);
        check->prior_n = 0;
        return FALSE;
      }
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
}
