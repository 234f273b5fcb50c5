#include "daemon/operating/scene_probe.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

#include "daemon/operating/scene_probe_determined.h"
#include "daemon/operating/scene_probe_hidden.h"
#include "daemon/operating/scene_probe_loss.h"
#include "daemon/operating/scene_probe_pairs.h"
#include "daemon/operating/scene_probe_transfer.h"
#include "daemon/operating/scene_probe_wide.h"
#include "daemon/operating/operating_error.h"
#include "proc/clip_level.h"
#include "proc/column_stats.h"
#include "proc/harmonic_gain.h"
#include "proc/image_stats.h"

const char *
ds_blur_source_name (DsBlurSource s)
{
  switch (s) {
  case DS_BLUR_CALIBRATED:
    return "calibrated";
  case DS_BLUR_MEASURED:
    return "measured";
  default:
    return "assumed sharp";
  }
}

/* The probe's narrow kernel's MTF at the frequency 1 / x; 0 where it has none. */
static double
narrow_kernel_mtf (const DsSceneProbe *p, double x)
{
  switch (p->narrow.form) {
  case DS_PROBE_KERNEL_POWER:
    return ds_probe_kernel_mtf (p->narrow.kernel_px, p->narrow.shape, x);
  case DS_PROBE_KERNEL_CONE:
    return ds_cone_kernel_mtf (p->narrow.kernel_px, x);
  case DS_PROBE_KERNEL_NONE:
  default:
    return 0.0;
  }
}

double
ds_scene_probe_leak (const DsSceneProbe *p, double period_px, guint n)
{
  if (!p->leak.measured)
    return 0.0;
  double x = period_px / n;
  double leak = exp (p->leak.per_px * x) * (1 + p->narrow.fraction * narrow_kernel_mtf (p, x)) - 1;
  return p->leak.bounded ? MIN (leak, MAX (0.0, p->leak.max)) : leak;
}

double
ds_scene_probe_finest_period (double blur_px)
{
  return MAX (DS_PROBE_FINEST_PERIOD_PX, DS_PROBE_FINEST_BLUR_RATIO * MAX (blur_px, 0.0));
}

guint
ds_scene_probe_finer_periods (double period_px, double blur_px, double out[DS_PROBE_FINER_MAX])
{
  double finest = ds_scene_probe_finest_period (blur_px);
  guint n = 0;
  for (double q = period_px / 2; n < DS_PROBE_FINER_MAX; q /= 2) {
    double rounded = round (q * 100) / 100;
    if (!(rounded >= finest - 1e-9))
      break;
    out[n++] = rounded;
  }
  return n;
}

/* Whether phase 0 and phase 1/2 of the pattern sum to a constant: sine stripes, and square ones of
 * duty 1/2 (their blur keeps the sum flat). */
static gboolean
opposite_phases_sum_flat (const DsStripeModel *g)
{
  return g->kind == DS_PATTERN_SINE || fabs (g->duty - 0.5) < 1e-3;
}

/* Whether a kernel narrower than the periods measured could hide scattered light in Ld (then the
 * prediction is a lower bound), and why. Only a scene that shows scattered light at all (Lg or
 * the leak at P at 1 % of Ld) is suspected: without any, a medium whose every scattered photon
 * stays within a pixel or two is indistinguishable from no medium, and flagging every clear scene
 * would make the flag say nothing. But "none seen" needs a pilot that could have seen 1 %: Lg is
 * the mean less Ld, and Ld is the first harmonic at P over its gain, which the blur's uncertainty
 * (DS_PROBE_BLUR_UNCERTAINTY_PX) and the harmonic's noise move by ds_probe_ld_uncertainty (a share of Ld).
 * Where that is above 1 % (fine periods, wide blur: 2.5 % at P = 7 px, 0.6 px), Lg under 1 % does
 * not tell a clear scene from one whose medium keeps the stripes at P and 2P (a kernel of about a
 * pixel holding most of the scattered light leaves Lg, the mean less an Ld that absorbed that
 * light, at a fraction of the truth): the scene is suspected unless Lg plus that
 * uncertainty stays under 1 %. Where the finer periods saw no kernel, the mean's scattered light that the
 * coarsest period keeps and the fit's leak at P does not (hidden, scene_probe_hidden.h) makes it a lower
 * bound too, with the leak at P bounded by what that period keeps (narrow.hidden_leak). Called once
 * light.ld_mean, light.lg_mean and the leak are known. */
static void
narrow_verdict (const DsProbeFrames *fr, gboolean finer_used, double ld_uncertainty, const DsConeFit *cone,
                const DsProbeHiddenLight *hidden, DsSceneProbe *out, GString *note)
{
  double P = fr->geometry.period_px;
  out->narrow.unresolved = FALSE;
  if (cone && cone->told) {
    g_string_printf (note,
      "the harmonics over the pilot's periods resolve a kernel of the lens's acceptance cone (radius %.2f px): "
      "the leak at %g px is %.1f %% of Ld, %.1f to %.1f %% within the fit's noise (a second kernel narrower "
      "than every period would not show)",
      cone->radius_px, P, 100 * cone->leak, 100 * cone->leak_low, 100 * cone->leak_high);
    return;
  }
  if (finer_used && cone) {
    out->narrow.unresolved = TRUE;
    g_string_printf (note,
      "a kernel of the lens's acceptance cone (radius %.2f px) keeps the stripes at every period measured (%g px "
      "and up), and the harmonics read its leak at %g px between %.1f and %.1f %% of Ld (%.1f %% taken), not "
      "within a factor %.1f, so the prediction is a lower bound",
      cone->radius_px, out->transfer.finest_period_px, P, 100 * cone->leak_low, 100 * cone->leak_high, 100 * cone->leak,
      DS_CONE_TOLD_FACTOR);
    return;
  }
  if (finer_used && out->narrow.beyond) {
    out->narrow.unresolved = TRUE;
    g_string_printf (note,
      "scattered light keeps more than %.0f %% of Ld modulated even at the finest period the pilot "
      "resolves (%g px): its kernel is narrower than the periods show and passes for direct light, so "
      "the prediction is a lower bound",
      100 * DS_PROBE_NARROW_MAX_AT_FINEST, out->transfer.finest_period_px);
    return;
  }
  if (finer_used && out->narrow.fraction <= 0 && hidden->suspect) {
    out->narrow.unresolved = TRUE;
    out->narrow.hidden_leak = hidden->kept;
    g_string_printf (note, "periods down to %g px: no kernel narrower than the period "
      "seen, but %s", out->transfer.finest_period_px, hidden->note);
    return;
  }
  if (finer_used) {
    if (out->narrow.fraction > 0)
      g_string_printf (note,
        "periods down to %g px: a narrow kernel (%.2f px) holds %.1f %% of Ld and keeps %.1f %% of it "
        "modulated at %g px",
        out->transfer.finest_period_px, out->narrow.kernel_px, 100 * out->narrow.fraction,
        100 * narrow_kernel_mtf (out, P), P);
    else
      g_string_printf (note,
        "periods down to %g px: no kernel narrower than the period seen", out->transfer.finest_period_px);
    return;
  }
  if (!out->leak.measured)
    return; /* the leak's note already makes the prediction a lower bound */
  gboolean seen = out->light.lg_mean >= 0.01 * out->light.ld_mean || ds_scene_probe_leak (out, P, 1) >= 0.01;
  if (!seen && out->light.lg_mean + ld_uncertainty * out->light.ld_mean < 0.01 * out->light.ld_mean) {
    g_string_printf (note,
      "no finer period measured, and no scattered light seen (Lg and the leak at %g px under 1 %% of Ld, "
      "Ld known to %.1f %%)", P, 100 * ld_uncertainty);
    return;
  }
  double finer[DS_PROBE_FINER_MAX];
  guint n = ds_scene_probe_finer_periods (P, out->geometry.blur_px, finer);
  char why[160];
  if (n == 0)
    g_snprintf (why, sizeof why, "%g px (P/2) is finer than the pilot resolves (%g px: 4 px, and %.2f x the blur %.2f px)",
                P / 2, ds_scene_probe_finest_period (out->geometry.blur_px), DS_PROBE_FINEST_BLUR_RATIO,
                out->geometry.blur_px);
  else if (fr->n_finer == 0)
    g_snprintf (why, sizeof why, "no pilot at %g px: %s", finer[0],
                fr->finer_missing ? fr->finer_missing : "not taken");
  else if (fr->finer[0].period_px < ds_scene_probe_finest_period (out->geometry.blur_px) - 1e-9)
    g_snprintf (why, sizeof why, "the pilot at %g px is finer than the blur of %.2f px resolves",
                fr->finer[0].period_px, out->geometry.blur_px);
  else
    g_snprintf (why, sizeof why, "the pilot at %g px shows no stripes above the noise", fr->finer[0].period_px);
  out->narrow.unresolved = TRUE;
  if (cone)
    g_string_printf (note,
      "a kernel of the lens's acceptance cone (radius %.2f px) keeps the stripes at every period measured, and "
      "the harmonics read its leak at %g px between %.1f and %.1f %% of Ld (%.1f %% taken), not within a "
      "factor %.1f, so the prediction is a lower bound: %s",
      cone->radius_px, P, 100 * cone->leak_low, 100 * cone->leak_high, 100 * cone->leak, DS_CONE_TOLD_FACTOR, why);
  else if (seen)
    g_string_printf (note,
      "scattered light whose kernel is narrower than the period keeps the stripes at every period measured "
      "(%g px and up) and passes for direct light, so the prediction is a lower bound: %s",
      P, why);
  else
    g_string_printf (note,
      "scattered light whose kernel is narrower than the period would keep the stripes at every period "
      "measured (%g px and up) and pass for direct light, and the pilot cannot rule it out (Lg %.1f %% of Ld, "
      "Ld known to %.1f %% for the blur's uncertainty and the noise), so the prediction is a lower bound: %s",
      P, 100 * out->light.lg_mean / out->light.ld_mean, 100 * ld_uncertainty, why);
}

/* The shot noise of the dark frame's own signal, DN^2: ambient light and dark current reach the
 * sensor with the illuminator off, and their photons are as Poisson as the stripes' (with ambient
 * light of a few hundred DN, most of the dark frame's variance is that shot noise, not read
 * noise). That part scales with the exposure, read noise and quantisation do not: counted as read
 * noise, it would stay whole at a quarter of the pilot's exposure, four times what that exposure
 * gets. The dark level is taken as signal over a sensor zero (the simulated sensor has no black
 * offset; a camera whose black offset B is not subtracted would have g B of its read noise
 * counted here), at the lit frames' shot-noise gain, and no more than the dark frame's variance
 * leaves over its quantisation. */
static double
dark_shot_noise (const DsImage *dark, double dark_dn, double var0, double gain)
{
  double quantisation = dark->type == DS_SAMPLE_F32 ? 0.0 : 1.0 / 12.0;
  return CLAMP (gain * MAX (0.0, dark_dn), 0.0, MAX (0.0, var0 - quantisation));
}

/* What one stage of ds_scene_probe_measure () hands on to the next, beside the fields of the
 * probe it fills: each stage below fills one of these. */

/* The pilot pairs' column statistics and harmonics (stage_pairs). */
typedef struct {
  DsImage *masked[4];                 /* the lit frames with their clipping places left out; NULL: none */
  const DsImage *stat[4];             /* what the statistics read: masked, or the frame itself */
  DsProbeClippedPlaces places;        /* the places left out, counted back into the light later */
  DsProbePairFit fine, coarse, finer[DS_PROBE_FINER_MAX];
} ProbePairs;

/* The harmonics the transfer is fitted to (stage_harmonics, stage_finer, select_line_harmonics). */
typedef struct {
  DsProbeEquation eq[DS_PROBE_MAX_EQUATIONS];      /* the line's: x <= P where those suffice */
  guint n_eq;
  DsProbeEquation all[DS_PROBE_MAX_EQUATIONS];     /* every period's, light wide against P left out */
  guint n_all;
  DsProbeEquation seen[DS_PROBE_MAX_EQUATIONS];    /* every period's as measured */
  guint n_seen;
  gboolean two;                       /* a second period (2P or finer) has harmonics above the noise */
  gboolean finer_used;                /* a finer period's harmonics joined */
  DsProbeWideRise wide;
} ProbeHarmonics;

/* The transfer's fit (stage_transfer). */
typedef struct {
  DsProbeSolution solution;           /* the fit kept: the line, the narrow term or the cone */
  gboolean narrow_won, cone_used;
  DsConeFit cone;
  char undetermined[200];             /* why a narrow term was not taken (scene_probe_determined.h) */
  double total;                       /* the light the pilot's mean holds, Ld + Lg, DN */
  double ld_fit, total_fit;           /* Ld and Ld + Lg as fitted, before the clipped places count */
} ProbeTransfer;

static void
probe_pairs_clear (ProbePairs *pairs)
{
  for (guint i = 0; i < 4; i++)
    g_clear_pointer (&pairs->masked[i], ds_image_free);
  ds_column_stats_clear (&pairs->fine.stats);
  ds_column_stats_clear (&pairs->coarse.stats);
  for (guint i = 0; i < DS_PROBE_FINER_MAX; i++)
    ds_column_stats_clear (&pairs->finer[i].stats);
}

/* Dark: the frame with the illuminator off holds every offset the lit frames carry (black level,
 * ambient light, dark current) and, having no stripes, its own temporal noise is the noise floor
 * of one frame without signal. */
static void
stage_dark (const DsProbeFrames *fr, DsSceneProbe *out)
{
  out->noise.dark_dn = ds_image_mean (fr->dark);
  double noise_dark = ds_column_stats_noise_dn (fr->dark, NULL, 0);
  out->noise.var0 = isfinite (noise_dark) ? noise_dark * noise_dark : 0;
}

/* Clip level: the given one, or a pile-up of samples at one value below it (a sensor's full
 * well reached before the ADC's top): proc/clip_level.h. */
static void
stage_clip (const DsProbeFrames *fr, DsSceneProbe *out)
{
  DsClipLevel clip;
  ds_clip_level_find (fr->dark, fr->lit, 2, fr->saturation_dn, &clip);
  out->clip.known = (fr->saturation_known && fr->saturation_dn > 0) || clip.piled;
  out->clip.saturation_dn = clip.level;
  out->clip.flagged = fr->saturation_dn > 0 && clip.level >= fr->saturation_dn;
  out->clip.bright_dn =
    MAX (ds_image_percentile (fr->lit[0], 99.9), ds_image_percentile (fr->lit[1], 99.9)) - out->noise.dark_dn;
}

/* Pairs: each pair of opposite phases gives per column the mean difference (the stripes times
 * the direct light plus the scattered light that keeps them), its mean square and the mean sum
 * (the scene under the pattern's mean), and the difference profile's harmonics. A place whose
 * stripes' peak clips is left out whole, at every phase and both periods alike, so that every
 * pair is read on one population of places (ds_probe_mask_clipped_places ()). The harmonics are
 * fitted on the scene's envelope for sine stripes only: square stripes of duty 1/2 sum flat too,
 * but their higher harmonics carry the blur when it is fitted to P and 2P, and the envelope, a
 * smooth division of the difference profile, moves them against the first (under a wide
 * scattered shadow the blur would read low and the modulation's drop between periods as a
 * kernel). The finer pairs are not masked: a place that clips there clips at P too, and is left
 * out of the column statistics at the clip level all the same. */
static gboolean
stage_pairs (const DsProbeFrames *fr, DsSceneProbe *out, ProbePairs *pairs, GError **error)
{
  double ceiling = out->clip.saturation_dn, period = fr->geometry.period_px;
  const DsImage *lit[4] = { fr->lit[0], fr->lit[1], fr->coarse[0], fr->coarse[1] };
  ds_probe_mask_clipped_places (lit, fr->coarse[0] ? 4 : 2, ceiling, period, pairs->masked, &pairs->places);
  for (guint i = 0; i < 4; i++)
    pairs->stat[i] = pairs->masked[i] ? pairs->masked[i] : lit[i];
  double envelope_dn = fr->geometry.kind == DS_PATTERN_SINE ? out->noise.dark_dn : -1;
  gboolean ok = ds_probe_pair_fit (lit[0], lit[1], pairs->stat[0], pairs->stat[1], ceiling, period, envelope_dn,
                                   &pairs->fine, error);
  if (ok && fr->coarse[0])
    ok = ds_probe_pair_fit (lit[2], lit[3], pairs->stat[2], pairs->stat[3], ceiling, 2 * period, envelope_dn,
                            &pairs->coarse, error);
  for (guint i = 0; ok && i < fr->n_finer; i++) {
    const DsProbePair *f = &fr->finer[i];
    ok = ds_probe_pair_fit (f->frame[0], f->frame[1], f->frame[0], f->frame[1], ceiling, f->period_px, envelope_dn,
                            &pairs->finer[i], error);
  }
  if (!ok) {
    g_prefix_error (error, "pilot frames: ");
    return FALSE;
  }
  guint64 n_px = (guint64) out->width * out->height;
  out->clip.saturated_fraction = (double) pairs->fine.clipped / (double) n_px;
  out->phase_offset = pairs->fine.fit.phase[1];
  return TRUE;
}

/* The columns where the noise is read on the two pairs' sums (ds_column_stats_noise_sets_dn), as a
 * flag per column, or NULL for all of them (opposite phases that sum flat: sine stripes, square ones
 * of duty 1/2). Square stripes of another duty a sum to 1 - b but in gaps (a < 1/2) or overlaps
 * (a > 1/2) of width |1/2 - a| P per half period, at other columns for P and 2P: where the two
 * pairs' sums differ, the scene's structure along y (the rows of a grid, an object's shading)
 * enters their combination at that share and passes for noise. Kept are the columns where the
 * model's two sums, at the pairs' fitted offsets, agree within DS_PROBE_SETS_MATCH. The one-pair
 * reading that remains where too few are kept cancels the scene less well: a pixel lit by one
 * phase and dark in the other carries almost no shot noise in its combination, so the gain rests
 * on few samples. */
static guint8 *
sets_columns (const DsStripeModel *g, const ProbePairs *pairs, guint width, guint *kept)
{
  *kept = width;
  if (opposite_phases_sum_flat (g))
    return NULL;
  guint8 *keep = g_new0 (guint8, width);
  *kept = ds_stripe_pair_sums_agree (g, pairs->fine.fit.phase[1], pairs->coarse.fit.phase[1], DS_PROBE_SETS_MATCH,
                                     width, keep);
  return keep;
}

/* Noise: one frame's variance is var0 + gain * signal (read noise and quantisation, then the
 * photons' Poisson noise); the difference of the two phases has twice var0 plus the gain times
 * their summed signal. Where the scene cancels between two pairs' sums (sets_columns ()), the
 * noise is read there, since the scene's own structure along y would otherwise pass for noise.
 * Returns the fine pair's mean summed signal over the dark, DN: twice the pattern's mean times the
 * light the scene holds. */
static double
stage_noise (const DsProbeFrames *fr, const ProbePairs *pairs, DsSceneProbe *out)
{
  const DsColumnStats *fine = &pairs->fine.stats;
  double sum_signal = 0, sum_w = 0;
  for (guint x = 0; x < fine->width; x++) {
    sum_signal += (fine->mean_sum[x] - 2 * out->noise.dark_dn) * fine->count[x];
    sum_w += fine->count[x];
  }
  double mean_sum = sum_w > 0 ? sum_signal / sum_w : 0;
  double var_diff = NAN, noise_signal = mean_sum;
  guint kept = 0;
  g_autofree guint8 *columns = fr->coarse[0] ? sets_columns (&fr->geometry, pairs, fine->width, &kept) : NULL;
  if (fr->coarse[0] && kept >= MAX (DS_PROBE_SETS_MIN_COLUMNS, fine->width / 8)) {
    /* The coarse pair's sum has the fine pair's mean: var (a - b) = var a + var b is half of it,
     * over the samples it was read on, whose signal is half their level. */
    double level = NAN;
    double noise_sets =
      ds_column_stats_noise_sets_dn (pairs->stat, pairs->stat + 2, columns, out->clip.saturation_dn, &level);
    if (isfinite (noise_sets) && isfinite (level)) {
      var_diff = noise_sets * noise_sets / 2;
      noise_signal = level / 2 - 2 * out->noise.dark_dn;
    }
  }
  g_debug ("scene probe: noise read on %s (%u of %u columns where the two pairs' sums agree)",
           isfinite (var_diff) ? "the two pairs' sums" : "one pair", fr->coarse[0] ? kept : 0, fine->width);
  if (!isfinite (var_diff) && noise_signal > 0) {
    /* One pair, the scene cancelled column by column (proc/column_stats.h): c's mean square is
     * var0 w2 + gain shot, which gives the gain, and with it what the pair's difference holds. */
    g_autofree double *rho = g_new (double, fine->width);
    double floor_dn = 3 * sqrt (2 * out->noise.var0);
    for (guint x = 0; x < fine->width; x++) {
      double sum = fine->mean_sum[x] - 2 * out->noise.dark_dn;
      rho[x] = fine->count[x] && sum > floor_dn ? fine->mean_diff[x] / sum : NAN;
    }
    double w2 = NAN, shot = NAN;
    double noise_pair = ds_column_stats_noise_pair_dn (pairs->stat[0], pairs->stat[1], rho, out->noise.dark_dn,
                                                       out->clip.saturation_dn, &w2, &shot);
    if (isfinite (noise_pair) && shot > 0)
      var_diff = 2 * out->noise.var0 + MAX (0.0, noise_pair * noise_pair - w2 * out->noise.var0) / shot * noise_signal;
  }
  if (!isfinite (var_diff)) {
    double noise_diff = ds_column_stats_noise_dn (pairs->stat[0], pairs->stat[1], out->clip.saturation_dn);
    var_diff = isfinite (noise_diff) ? noise_diff * noise_diff : 2 * out->noise.var0;
  }
  out->noise.gain = noise_signal > 0 ? MAX (0.0, (var_diff - 2 * out->noise.var0) / noise_signal) : 0;
  out->noise.dark_shot = dark_shot_noise (fr->dark, out->noise.dark_dn, out->noise.var0, out->noise.gain);
  return mean_sum;
}

/* Harmonics: each harmonic of the difference profile above its noise at P and 2P is one equation
 * of the transfer's fit. Without any at P there is no modulation, so no direct light to separate
 * from the scattered: the probe fails. A pair at 2P whose harmonics all drown in the noise counts
 * as no second period. */
static gboolean
stage_harmonics (const DsProbeFrames *fr, const ProbePairs *pairs, ProbeHarmonics *h, GError **error)
{
  double period = fr->geometry.period_px;
  guint width = fr->lit[0]->width;
  h->n_eq = ds_probe_collect_equations (&pairs->fine.fit, period, &fr->geometry, width, h->eq, 0);
  h->two = pairs->coarse.ok;
  if (h->two) {
    guint before = h->n_eq;
    h->n_eq = ds_probe_collect_equations (&pairs->coarse.fit, 2 * period, &fr->geometry, width, h->eq, h->n_eq);
    if (h->n_eq == before)
      h->two = FALSE;
  }
  if (h->n_eq == 0) {
    g_set_error (error, DS_OPERATING_ERROR, DS_OPERATING_ERROR_NO_MODULATION,
                 "pilot frames: no stripe modulation above the noise at period %g px (amplitude %.3g DN, "
                 "noise %.3g DN): no direct light to separate",
                 period, pairs->fine.fit.amplitude[1], pairs->fine.fit.sigma_amplitude);
    return FALSE;
  }
  return TRUE;
}

/* Blur, unless calibrated: it lowers the higher harmonics against the first at a period, the
 * scattered stripes raise the coarse period against the fine one; every harmonic at both periods
 * is needed to tell them apart, so the blur is the one whose gains leave the least residual in
 * the transfer's fit at P and 2P. A calibrated gain is the first harmonic as the rig's pixels see
 * it: above what the sharp pattern integrated over the whole pixel gives, no blur explains it,
 * the pixel integrates less (the simulator samples sine stripes at the pixel centre), and a whole
 * pixel's sinc (1/P) would put the gains of every pilot period too low, the more so the finer the
 * period (so Ld high, and the narrow periods' harmonics read as a kernel), and the sine
 * estimator's error at 1 - sinc (1/P) where it divides by the very gain the pixels see: so the
 * pixel's aperture is matched to the gain (ds_stripe_match_gain ()). */
static void
stage_blur (const DsProbeFrames *fr, const ProbeHarmonics *h, DsSceneProbe *out)
{
  double sigma = 0;
  if (fr->blur_known) {
    sigma = CLAMP (fr->calibrated_blur_px, 0.0, fr->geometry.period_px / 2);
    out->blur.source = DS_BLUR_CALIBRATED;
  } else if (fr->calibrated_gain > 0) {
    DsStripeModel matched = fr->geometry;
    ds_stripe_match_gain (&matched, fr->calibrated_gain);
    sigma = matched.blur_px;
    out->geometry.pixel_aperture = matched.pixel_aperture;
    out->blur.source = DS_BLUR_CALIBRATED;
  } else if (h->n_eq >= (h->two ? 3u : 2u)) {
    double best = INFINITY, hi = MIN (fr->geometry.period_px / 2, 4.0);
    for (double s = 0; s <= hi + 1e-9; s += 0.025) {
      DsProbeSolution so = ds_probe_solve_at (&fr->geometry, h->eq, h->n_eq, s, fr->lit[0]->width, h->two, FALSE);
      if (so.residual < best) {
        best = so.residual;
        sigma = s;
      }
    }
    out->blur.source = DS_BLUR_MEASURED;
  } else
    out->blur.source = DS_BLUR_ASSUMED_SHARP;
  out->geometry.blur_px = sigma;
}

/* Finer periods: they join after the blur is found, since a narrow kernel lowers their
 * harmonics as a wider blur would, and the blur is what P and 2P say it is. A pair at a period
 * the blur has made unresolvable (its first harmonic under half the sharp pattern's) says more
 * about the blur than about the kernel and is left out. Then a rise at the coarsest period that
 * no kernel the flat harmonics at and below P allow is light wide against P: left out of the
 * transfer fit (scene_probe_wide.h) and so of the interval of Ld, whose single kernel with a 1/k
 * tail is one of the forms that rule out; kept (seen) for the hidden light's bound, since the
 * leak at P is at most what the coarsest period keeps, whatever the kernel. */
static void
stage_finer (const DsProbeFrames *fr, const ProbePairs *pairs, DsSceneProbe *out, ProbeHarmonics *h)
{
  double sigma = out->geometry.blur_px;
  guint width = fr->lit[0]->width;
  out->transfer.finest_period_px = fr->geometry.period_px;
  guint before_finer = h->n_eq;
  for (guint i = 0; i < fr->n_finer; i++) {
    double q = fr->finer[i].period_px;
    if (q < ds_scene_probe_finest_period (sigma) - 1e-9)
      continue;
    guint had = h->n_eq;
    h->n_eq = ds_probe_collect_equations (&pairs->finer[i].fit, q, &out->geometry, width, h->eq, h->n_eq);
    for (guint k = had; k < h->n_eq; k++)
      if (h->eq[k].n == 1)
        out->transfer.finest_period_px = MIN (out->transfer.finest_period_px, q);
  }
  h->finer_used = h->n_eq > before_finer;
  h->two = h->two || h->finer_used;
  h->n_seen = h->n_eq;
  memcpy (h->seen, h->eq, h->n_eq * sizeof *h->eq);
  h->n_eq = ds_probe_drop_wide_rise (&out->geometry, h->eq, h->n_eq, sigma, width, fr->geometry.period_px, &h->wide);
  if (h->wide.left_out) {
    for (guint i = 0; i < h->n_seen; i++) {
      const DsProbeEquation *e = &h->seen[i];
      g_debug ("scene probe: harmonic %u at %g px: x %.3g px, A %.4g +- %.2g DN, A/G %.4g", e->n, e->period,
               e->period / e->n, e->amplitude, e->sigma,
               e->amplitude / ds_probe_model_gain (&out->geometry, e->period, sigma, e->offset, width, e->n));
    }
    g_debug ("scene probe: %s", h->wide.note + 2);
  }
}

/* The line's harmonics: the transfer's logarithm is linear in x = Q / n only while x is small
 * against the distance over which forward-scattered light spreads (beyond, it saturates at the
 * whole forward-scattered flux), so the line is fitted to the harmonics with x <= P, which
 * bracket the configured period and reach down towards 0, unless that leaves a single x known to
 * 5 % (the fit's noise, and how far the blur's uncertainty moves its gain), or no more equations
 * than the fit's three parameters (Ld, alpha, the blur's error), which they would then fit
 * exactly, noise and all: then the first harmonic at 2P, the most reliable point after the one
 * at P, stays in. h->all keeps every harmonic for the narrow term and the cone. */
static void
select_line_harmonics (const DsProbeFrames *fr, const DsSceneProbe *out, ProbeHarmonics *h)
{
  double sigma = out->geometry.blur_px, period = fr->geometry.period_px;
  guint width = fr->lit[0]->width, near = 0, below = 0;
  double x_min = INFINITY, x_max = 0;
  for (guint i = 0; i < h->n_eq; i++) {
    const DsProbeEquation *e = &h->eq[i];
    double G = ds_probe_model_gain (&out->geometry, e->period, sigma, e->offset, width, e->n);
    gboolean known = e->sigma < 0.05 * e->amplitude &&
                     fabs (ds_probe_gain_shift (&out->geometry, e, sigma, G, width)) < 0.05;
    if (known && e->period / e->n <= period * 1.001) {
      x_min = MIN (x_min, e->period / e->n);
      x_max = MAX (x_max, e->period / e->n);
      near++;
    }
  }
  for (guint i = 0; i < h->n_eq; i++)
    below += h->eq[i].period / h->eq[i].n <= period * 1.001;
  memcpy (h->all, h->eq, h->n_eq * sizeof *h->eq);
  h->n_all = h->n_eq;
  if (h->two && near >= 2 && x_max > x_min * 1.05 && below > 3) {
    guint k = 0;
    for (guint i = 0; i < h->n_eq; i++)
      if (h->eq[i].period / h->eq[i].n <= period * 1.001)
        h->eq[k++] = h->eq[i];
    h->n_eq = k;
  }
}

/* Whether the narrow term the search found is a measured kernel. It shows as a transfer that
 * rises from the finer periods to P and stops, and it must be more than the harmonics' scatter
 * (five parameters fit four first harmonics of sine stripes exactly, and the scatter alone can
 * pass for a kernel holding a tenth of Ld on a scene with about no scattered light), so:
 * - the scene's mean shows scattered light (the line's Lg at least DS_PROBE_NARROW_MIN_LG of its
 *   Ld): the kernel's light is taken from what the line called direct;
 * - the kernel has let go of the stripes at the finest period (its transfer there under
 *   DS_PROBE_NARROW_MAX_AT_FINEST; otherwise it is narrower than the pilot resolves, *beyond,
 *   and narrow_verdict () makes the prediction a lower bound);
 * - it loses at least 1 - DS_PROBE_NARROW_MAX_OWN_AT_FINEST of its own stripes at the finest
 *   first harmonic: one that keeps more is carried by the higher harmonics alone, whose gain the
 *   blur's uncertainty moves by 5-10 %, and one of them a few % low would read as a sub-pixel
 *   kernel holding a large share of Ld;
 * - where the harmonics do not over-determine it, it passes through them
 *   (scene_probe_determined.h: no kernel's transfer falls with the period). */
static gboolean
narrow_term_holds (const DsProbeNarrowFit *narrow, const DsProbeSolution *line_all, const ProbeHarmonics *h,
                   const DsSceneProbe *out, ProbeTransfer *t, gboolean *beyond)
{
  double ld_line = exp (line_all->log_ld), lg_line = t->total - ld_line;
  if (!(lg_line >= DS_PROBE_NARROW_MIN_LG * ld_line))
    return FALSE;
  double x = out->transfer.finest_period_px;
  double at_finest =
    exp (narrow->s.alpha * x) * (1 + narrow->beta * ds_probe_kernel_mtf (narrow->width, narrow->shape, x)) - 1;
  if (at_finest > DS_PROBE_NARROW_MAX_AT_FINEST) {
    *beyond = TRUE;
    return FALSE;
  }
  if (ds_probe_kernel_mtf (narrow->width, narrow->shape, x) > DS_PROBE_NARROW_MAX_OWN_AT_FINEST)
    return FALSE;
  return ds_probe_narrow_measured (h->all, h->n_all, narrow->s.residual, t->undetermined, sizeof t->undetermined);
}

/* Transfer: Ld and the scattered stripes from A_n(Q) = Ld G_n(Q, sigma) T_n(Q) (scene_probe.h).
 * The line (the small-angle law) is fitted to the line's harmonics; the narrow term, where the
 * finer periods were measured, and the acceptance cone's kernel, where the line cannot follow a
 * transfer that saturates between the periods, are compared with it over every harmonic, since
 * only the coarse period (where the line would go on rising and their transfer has stopped)
 * tells them apart. The one kept is the fit, tested for consistency with the harmonics' noise. */
static void
stage_transfer (const DsProbeFrames *fr, ProbeHarmonics *h, DsSceneProbe *out, ProbeTransfer *t)
{
  double sigma = out->geometry.blur_px;
  guint width = fr->lit[0]->width;
  out->transfer.equations = h->n_eq;
  t->solution = ds_probe_solve_at (&out->geometry, h->eq, h->n_eq, sigma, width, h->two, TRUE);
  DsProbeNarrowFit narrow = { { 0 }, 0, 0, 0 };
  DsProbeSolution line_all = ds_probe_solve_at (&out->geometry, h->all, h->n_all, sigma, width, h->two, TRUE);
  gboolean beyond = FALSE;
  t->narrow_won = h->finer_used &&
                  ds_probe_fit_narrow (&out->geometry, h->all, h->n_all, sigma, width, fr->geometry.period_px,
                                       &line_all, &narrow) &&
                  narrow_term_holds (&narrow, &line_all, h, out, t, &beyond);
  out->narrow.beyond = beyond;
  if (t->narrow_won) {
    t->solution = narrow.s;
    out->transfer.equations = h->n_all;
    out->narrow.fraction = narrow.beta;
    out->narrow.kernel_px = narrow.width;
    out->narrow.form = DS_PROBE_KERNEL_POWER;
    out->narrow.shape = narrow.shape;
  }
  out->light.ld_mean = exp (t->solution.log_ld);
  out->leak.per_px = t->solution.alpha;
  t->cone_used = h->two && !t->narrow_won &&
                 ds_probe_fit_cone (&out->geometry, h->all, h->n_all, sigma, width, t->total, out->light.ld_mean, &t->cone);
  guint n_fit = h->n_eq;
  if (t->cone_used) {
    t->solution.residual = t->cone.chi2;
    n_fit = out->transfer.equations = h->n_all;
    out->light.ld_mean = t->cone.ld;
    out->leak.per_px = 0;
    out->narrow.fraction = (t->total - t->cone.ld) / t->cone.ld;
    out->narrow.kernel_px = t->cone.radius_px;
    out->narrow.form = DS_PROBE_KERNEL_CONE;
    out->narrow.shape = 0;
  }
  out->leak.measured = h->two;
  out->transfer.rms = n_fit > (h->two ? 2u : 1u) ? sqrt (t->solution.residual / n_fit) : 0;
  ds_probe_fit_consistency (t->solution.residual, t->narrow_won ? h->n_all : n_fit,
                            1 + (h->two ? 1 : 0) + (t->narrow_won ? 2 : 0), out);
}

/* How the scattered stripes were measured, or why not (the leak note): the leak at P the fit
 * reads, the harmonics left out as light wide against P, the cone's kernel. */
static void
leak_note_measured (const DsProbeFrames *fr, const ProbeHarmonics *h, const ProbeTransfer *t,
                    const DsSceneProbe *out, GString *note)
{
  double period = fr->geometry.period_px;
  if (!h->two) {
    g_string_printf (note,
      "not measured (%s): scattered light that keeps the stripes is not in the prediction, "
      "which is a lower bound",
      fr->coarse[0] ? "no modulation at twice the period"
      : fr->coarse_missing ? fr->coarse_missing : "no second period");
    return;
  }
  g_string_printf (note,
    "measured at periods %g and %g px: scattered light keeps %.1f %% of the stripes' "
    "first harmonic at %g px",
    period, 2 * period, 100 * ds_scene_probe_leak (out, period, 1), period);
  if (h->wide.left_out)
    g_string_append (note, h->wide.note);
  if (t->cone_used)
    g_string_append_printf (note, " (the lens's acceptance cone: a kernel of %.2f px)", t->cone.radius_px);
}

/* Light: the scattered light is what the mean holds beyond the direct light (two opposite phases
 * sum to the pattern's mean twice over whole periods), never negative. The spread of Ld across
 * the scene: per column, mean (D^2) - noise = mean (Ld^2) Dp(x)^2 and the column's mean
 * D = mean (Ld) Dp(x), whose square carries the noise over count rows; times the spread from one
 * column to the next (ds_probe_pair_spread_across_columns ()). Both at most 25. */
static void
stage_light (const ProbePairs *pairs, const ProbeTransfer *t, DsSceneProbe *out)
{
  out->light.lg_mean = MAX (0.0, t->total - out->light.ld_mean);
  const DsColumnStats *fine = &pairs->fine.stats;
  double num = 0, den = 0;
  for (guint x = 0; x < fine->width; x++) {
    guint32 c = fine->count[x];
    if (!c)
      continue;
    double v = 2 * out->noise.var0 + out->noise.gain * MAX (0.0, fine->mean_sum[x] - 2 * out->noise.dark_dn);
    double d = fine->mean_diff[x];
    num += (fine->mean_sq_diff[x] - v) * c;
    den += (d * d - v / c) * c;
  }
  out->light.ld_spread = den > 0 && num > den ? MIN (num / den, 25.0) : 1.0;
  out->light.ld_spread = MIN (out->light.ld_spread * ds_probe_pair_spread_across_columns (&pairs->fine, &out->geometry, out), 25.0);
}

/* The leak's bound: a scattered stripe is scattered light, A_n = G_n (Ld + S T_n) with T_n <= 1,
 * so no harmonic's leak exceeds S / Ld, the mean's Lg over Ld. The harmonics' scatter and the
 * blur's uncertainty put a few % on a transfer, the mean knows the light to 0.1 %: where the
 * fit reads more, the leak is held there (ds_scene_probe_leak ()). */
static void
stage_leak_bound (const DsProbeFrames *fr, DsSceneProbe *out, GString *leak_note)
{
  out->leak.bounded = out->leak.measured && out->light.ld_mean > 0;
  out->leak.max = out->leak.bounded ? out->light.lg_mean / out->light.ld_mean : 0;
  if (!out->leak.bounded)
    return;
  out->leak.bounded = FALSE;
  double read = ds_scene_probe_leak (out, fr->geometry.period_px, 1);
  out->leak.bounded = TRUE;
  if (read > out->leak.max)
    g_string_append_printf (leak_note, ", held to the scattered light the mean shows (%.1f %% of Ld)",
                            100 * out->leak.max);
}

/* Interval: where a kernel narrower than the periods could hide scattered light in Ld (the
 * verdict's narrow.unresolved), how low the direct light can be (ds_scene_probe_worst_case ()):
 * read from the drop of the modulation between the coarsest period and the finest at the fit's
 * Ld and light, before the clipped places were counted in (scene_probe.h, the interval). */
static void
stage_interval (const DsProbeFrames *fr, const ProbeHarmonics *h, const ProbeTransfer *t, DsSceneProbe *out)
{
  DsProbeDirectInterval interval;
  ds_probe_direct_interval (h->all, h->n_all, &out->geometry, out->geometry.blur_px, fr->lit[0]->width, t->ld_fit,
                            t->total_fit, &interval);
  if (out->narrow.unresolved && h->two && interval.computed) {
    out->interval.set = TRUE;
    out->interval.unbounded = interval.unbounded;
    out->interval.ld_lower = interval.unbounded ? 0 : interval.ratio * out->light.ld_mean;
    out->interval.worst_kernel_px = interval.unbounded ? 0 : interval.kernel_px;
    g_strlcpy (out->interval.note, interval.note, sizeof out->interval.note);
  } else
    out->interval.ld_lower = out->light.ld_mean;
}

gboolean
ds_scene_probe_measure (const DsProbeFrames *fr, DsSceneProbe *out, GError **error)
{
  memset (out, 0, sizeof *out);
  if (!ds_probe_frames_check (fr, error))
    return FALSE;
  out->geometry = fr->geometry;
  out->exposure_us = fr->exposure_us;
  out->width = fr->lit[0]->width;
  out->height = fr->lit[0]->height;
  stage_dark (fr, out);
  stage_clip (fr, out);

  ProbePairs pairs = { .masked = { NULL } };
  g_autofree ProbeHarmonics *h = g_new0 (ProbeHarmonics, 1);
  if (!stage_pairs (fr, out, &pairs, error)) {
    probe_pairs_clear (&pairs);
    return FALSE;
  }
  double mean_sum = stage_noise (fr, &pairs, out);
  if (!stage_harmonics (fr, &pairs, h, error)) {
    probe_pairs_clear (&pairs);
    return FALSE;
  }
  stage_blur (fr, h, out);
  stage_finer (fr, &pairs, out, h);
  select_line_harmonics (fr, out, h);

  double pattern_mean = ds_pattern_mean (fr->geometry.kind, fr->geometry.duty, fr->geometry.black_level);
  ProbeTransfer t = { .total = mean_sum / (2 * pattern_mean) };
  stage_transfer (fr, h, out, &t);
  g_autoptr (GString) leak_note = g_string_new (NULL);
  leak_note_measured (fr, h, &t, out, leak_note);
  stage_light (&pairs, &t, out);
  t.ld_fit = out->light.ld_mean;
  t.total_fit = out->light.ld_mean + out->light.lg_mean;
  ds_probe_count_clipped_places (out, &pairs.places, fr->geometry.black_level, pattern_mean, leak_note);
  stage_leak_bound (fr, out, leak_note);
  g_strlcpy (out->leak.note, leak_note->str, sizeof out->leak.note);

  /* Verdict: Ld's uncertainty (also the prediction's, ds_operating_point_uncertainty ()), the
   * light the coarsest period keeps beyond the fit's leak, and whether a kernel narrower than
   * the periods could pass for direct light. */
  out->light.ld_uncertainty = ds_probe_ld_uncertainty (h->all, h->n_all, &out->geometry, out->geometry.blur_px, out->width);
  DsProbeHiddenLight hidden;
  ds_probe_hidden_light (h->seen, h->n_seen, &out->geometry, out->geometry.blur_px, out->width, t.ld_fit, t.total_fit,
                         out->light.ld_uncertainty, ds_scene_probe_leak (out, fr->geometry.period_px, 1), &hidden);
  g_autoptr (GString) narrow_note = g_string_new (NULL);
  narrow_verdict (fr, h->finer_used, out->light.ld_uncertainty, t.cone_used ? &t.cone : NULL, &hidden, out, narrow_note);
  if (h->finer_used)
    g_string_append (narrow_note, t.undetermined);
  g_strlcpy (out->narrow.note, narrow_note->str, sizeof out->narrow.note);
  stage_interval (fr, h, &t, out);
  out->leak.at_period = ds_scene_probe_leak (out, fr->geometry.period_px, 1);
  out->noise.at_mean_dn = sqrt (out->noise.var0 + out->noise.gain * (out->light.ld_mean + out->light.lg_mean));
  ds_probe_loss_measure (fr, out);
  probe_pairs_clear (&pairs);
  return TRUE;
}
