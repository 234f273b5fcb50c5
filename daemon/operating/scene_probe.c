#include "daemon/operating/scene_probe.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

#include "daemon/operating/scene_probe_determined.h"
#include "daemon/operating/scene_probe_hidden.h"
#include "daemon/operating/scene_probe_pairs.h"
#include "daemon/operating/scene_probe_transfer.h"
#include "daemon/operating/scene_probe_wide.h"
#include "daemon/protocol/protocol.h"
#include "proc/column_stats.h"
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

double
ds_scene_probe_leak (const DsSceneProbe *p, double period_px, guint n)
{
  if (!p->leak_measured)
    return 0.0;
  double x = period_px / n;
  double leak = exp (p->leak_per_px * x) *
                    (1 + p->narrow_fraction * ds_probe_kernel_mtf (p->narrow_kernel_px, p->narrow_shape, x)) - 1;
  return p->leak_bounded ? MIN (leak, MAX (0.0, p->leak_max)) : leak;
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

/* Whether the noise is read on the two pairs' sums (ds_column_stats_noise_sets_dn) rather than on
 * the fine pair's difference: where the sums are flat, and for square stripes of a duty a near 1/2.
 * Their opposite phases sum to 1 - b but in gaps (a < 1/2) or overlaps (a > 1/2) of width
 * |1/2 - a| P per half period, so the two pairs' sums differ by at most 2 |1/2 - a| (1 - b) of Ld,
 * where the pair's difference is (1 - b) of Ld: scene structure along y (the rows of a grid) enters
 * the sets' combination at that share, its variance at the square (1 % at |1/2 - a| = 0.05), and
 * the second difference along y cannot tell it from noise. On the pair's difference it enters
 * whole, and a grid's rows read as shot noise several times the sensor's gain, which would make
 * every prediction several times too pessimistic. */
static gboolean
noise_on_sets (const DsStripeModel *g)
{
  return opposite_phases_sum_flat (g) || fabs (g->duty - 0.5) <= DS_PROBE_SETS_DUTY;
}

/* The spread of Ld from one column to the next, mean_x (Ld(x)^2) / mean_x (Ld(x))^2 over the
 * columns' mean Ld: the column statistics' mean square holds only the spread within each column
 * (an object that spans the rows, a vertical grid line, is not in it, and the spread would read
 * low). The columns' mean differences are Ld(x) Dp(x); their energy against the
 * fitted harmonics' (a uniform Ld times the pattern) is the spread across columns, once the
 * same ratio for the model's own profile, whose harmonics the fit leaves out (those at or
 * above the Nyquist frequency, aliased), divides out. */
static double
spread_across_columns (const DsProbePairFit *f, const DsStripeModel *geometry, const DsSceneProbe *out)
{
  DsStripeModel g = *geometry;
  guint w = f->stats.width;
  double offset = f->fit.phase[1];
  g_autofree double *model = g_new (double, w);
  for (guint x = 0; x < w; x++)
    model[x] = ds_stripe_value (&g, x, offset) - ds_stripe_value (&g, x, offset + 0.5);
  DsStripeHarmonics mf;
  if (!ds_stripe_harmonics_fit (model, f->stats.count, 0, w, g.period_px, f->fit.n_harmonics, &mf, NULL))
    return 1.0;
  double data = 0, data_fit = 0, model_all = 0, model_fit = 0;
  for (guint x = 0; x < w; x++) {
    guint32 c = f->stats.count[x];
    if (!c)
      continue;
    double v = 2 * out->noise_var0 + out->noise_gain * MAX (0.0, f->stats.mean_sum[x] - 2 * out->dark_dn);
    double d = f->stats.mean_diff[x], df = ds_stripe_harmonics_eval (&f->fit, g.period_px, x) - f->fit.mean;
    double mfit = ds_stripe_harmonics_eval (&mf, g.period_px, x) - mf.mean;
    data += (d * d - v / c) * c;
    data_fit += df * df * c;
    model_all += model[x] * model[x] * c;
    model_fit += mfit * mfit * c;
  }
  if (!(data > 0 && data_fit > 0 && model_all > 0 && model_fit > 0))
    return 1.0;
  return MAX (1.0, (data / data_fit) / (model_all / model_fit));
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
 * bound too, with the leak at P bounded by what that period keeps (hidden_leak). Called once ld_mean,
 * lg_mean and the leak are known. */
static void
narrow_verdict (const DsProbeFrames *fr, gboolean finer_used, double ld_uncertainty, const DsConeFit *cone,
                const DsProbeHiddenLight *hidden, DsSceneProbe *out)
{
  double P = fr->geometry.period_px;
  out->narrow_unresolved = FALSE;
  if (cone && cone->told) {
    g_snprintf (out->narrow_note, sizeof out->narrow_note,
                "the harmonics over the pilot's periods resolve a kernel of the lens's acceptance cone (radius %.2f px): "
                "the leak at %g px is %.1f %% of Ld, %.1f to %.1f %% within the fit's noise (a second kernel narrower "
                "than every period would not show)",
                cone->radius_px, P, 100 * cone->leak, 100 * cone->leak_low, 100 * cone->leak_high);
    return;
  }
  if (finer_used && cone) {
    out->narrow_unresolved = TRUE;
    g_snprintf (out->narrow_note, sizeof out->narrow_note,
                "a kernel of the lens's acceptance cone (radius %.2f px) keeps the stripes at every period measured (%g px "
                "and up), and the harmonics read its leak at %g px between %.1f and %.1f %% of Ld (%.1f %% taken), not "
                "within a factor %.1f, so the prediction is a lower bound",
                cone->radius_px, out->finest_period_px, P, 100 * cone->leak_low, 100 * cone->leak_high, 100 * cone->leak,
                DS_CONE_TOLD_FACTOR);
    return;
  }
  if (finer_used && out->narrow_beyond) {
    out->narrow_unresolved = TRUE;
    g_snprintf (out->narrow_note, sizeof out->narrow_note,
                "scattered light keeps more than %.0f %% of Ld modulated even at the finest period the pilot "
                "resolves (%g px): its kernel is narrower than the periods show and passes for direct light, so "
                "the prediction is a lower bound",
                100 * DS_PROBE_NARROW_MAX_AT_FINEST, out->finest_period_px);
    return;
  }
  if (finer_used && out->narrow_fraction <= 0 && hidden->suspect) {
    out->narrow_unresolved = TRUE;
    out->hidden_leak = hidden->kept;
    g_snprintf (out->narrow_note, sizeof out->narrow_note, "periods down to %g px: no kernel narrower than the period "
                "seen, but %s", out->finest_period_px, hidden->note);
    return;
  }
  if (finer_used) {
    if (out->narrow_fraction > 0)
      g_snprintf (out->narrow_note, sizeof out->narrow_note,
                  "periods down to %g px: a narrow kernel (%.2f px) holds %.1f %% of Ld and keeps %.1f %% of it "
                  "modulated at %g px",
                  out->finest_period_px, out->narrow_kernel_px, 100 * out->narrow_fraction,
                  100 * ds_probe_kernel_mtf (out->narrow_kernel_px, out->narrow_shape, P), P);
    else
      g_snprintf (out->narrow_note, sizeof out->narrow_note,
                  "periods down to %g px: no kernel narrower than the period seen", out->finest_period_px);
    return;
  }
  if (!out->leak_measured)
    return; /* the leak_note already makes the prediction a lower bound */
  gboolean seen = out->lg_mean >= 0.01 * out->ld_mean || ds_scene_probe_leak (out, P, 1) >= 0.01;
  if (!seen && out->lg_mean + ld_uncertainty * out->ld_mean < 0.01 * out->ld_mean) {
    g_snprintf (out->narrow_note, sizeof out->narrow_note,
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
  out->narrow_unresolved = TRUE;
  if (cone)
    g_snprintf (out->narrow_note, sizeof out->narrow_note,
                "a kernel of the lens's acceptance cone (radius %.2f px) keeps the stripes at every period measured, and "
                "the harmonics read its leak at %g px between %.1f and %.1f %% of Ld (%.1f %% taken), not within a "
                "factor %.1f, so the prediction is a lower bound: %s",
                cone->radius_px, P, 100 * cone->leak_low, 100 * cone->leak_high, 100 * cone->leak, DS_CONE_TOLD_FACTOR, why);
  else if (seen)
    g_snprintf (out->narrow_note, sizeof out->narrow_note,
                "scattered light whose kernel is narrower than the period keeps the stripes at every period measured "
                "(%g px and up) and passes for direct light, so the prediction is a lower bound: %s",
                P, why);
  else
    g_snprintf (out->narrow_note, sizeof out->narrow_note,
                "scattered light whose kernel is narrower than the period would keep the stripes at every period "
                "measured (%g px and up) and pass for direct light, and the pilot cannot rule it out (Lg %.1f %% of Ld, "
                "Ld known to %.1f %% for the blur's uncertainty and the noise), so the prediction is a lower bound: %s",
                P, 100 * out->lg_mean / out->ld_mean, 100 * ld_uncertainty, why);
}

/* The upper end where the coarsest period bounds the leak (scene_probe_hidden.h): Ld as read, the
 * leak at every harmonic and period at hidden_leak (a kernel of width 0 keeps every harmonic). */
static gboolean
hidden_worst_case (const DsSceneProbe *p, DsSceneProbe *worst)
{
  if (!p->narrow_unresolved || !(p->hidden_leak > 0) || (p->ld_interval && p->ld_unbounded))
    return FALSE;
  *worst = *p;
  worst->leak_per_px = 0;
  worst->leak_measured = TRUE;
  worst->narrow_fraction = p->hidden_leak;
  worst->narrow_kernel_px = 0;
  worst->narrow_shape = 1;
  worst->leak_bounded = TRUE;
  worst->leak_max = MAX (p->leak_max, p->hidden_leak);
  return TRUE;
}

gboolean
ds_scene_probe_worst_case (const DsSceneProbe *p, DsSceneProbe *worst)
{
  if (hidden_worst_case (p, worst) && !(p->ld_interval && p->ld_lower < p->ld_mean))
    return TRUE;
  if (!p->narrow_unresolved || !p->ld_interval || p->ld_unbounded || !(p->ld_lower < p->ld_mean) ||
      !(p->ld_lower > 0) || !(p->worst_kernel_px > 0))
    return FALSE;
  *worst = *p;
  double total = p->ld_mean + p->lg_mean;
  worst->ld_mean = p->ld_lower;
  worst->lg_mean = total - p->ld_lower;
  worst->leak_per_px = 0;
  worst->leak_measured = TRUE;
  worst->narrow_fraction = worst->lg_mean / worst->ld_mean;
  worst->narrow_kernel_px = p->worst_kernel_px;
  worst->narrow_shape = 0.5;
  worst->leak_max = worst->lg_mean / worst->ld_mean; /* its kernel's MTF <= 1 keeps it there anyway */
  return TRUE;
}

/* The shot noise of the dark frame's own signal, DN^2: ambient light and dark current reach the
 * sensor with the illuminator off, and their photons are as Poisson as the stripes' (with ambient
 * light of a few hundred DN, most of the dark frame's variance is that shot noise, not read
 * noise). That part
 * scales with the exposure, read noise and quantisation do not: counted as read noise, a quarter
 * of the pilot's exposure was predicted with four times the dark frame's shot noise. The dark
 * level is taken as signal over a sensor zero (the simulated sensor has no black offset; a camera
 * whose black offset B is not subtracted would have g B of its read noise counted here), at the
 * lit frames' shot-noise gain, and no more than the dark frame's variance leaves over its
 * quantisation. */
static double
dark_shot_noise (const DsImage *dark, double dark_dn, double var0, double gain)
{
  double quantisation = dark->type == DS_SAMPLE_F32 ? 0.0 : 1.0 / 12.0;
  return CLAMP (gain * MAX (0.0, dark_dn), 0.0, MAX (0.0, var0 - quantisation));
}

gboolean
ds_scene_probe_measure (const DsProbeFrames *fr, DsSceneProbe *out, GError **error)
{
  memset (out, 0, sizeof *out);
  const DsImage *l0 = fr->lit[0], *l1 = fr->lit[1];
  if (!ds_probe_frames_check (fr, error))
    return FALSE;
  out->geometry = fr->geometry;
  out->exposure_us = fr->exposure_us;
  out->width = l0->width;
  out->height = l0->height;
  out->dark_dn = ds_image_mean (fr->dark);
  double noise_dark = ds_column_stats_noise_dn (fr->dark, NULL, 0);
  out->noise_var0 = isfinite (noise_dark) ? noise_dark * noise_dark : 0;

  /* Clip level: the given one, or a pile-up of samples at one value below it (a sensor's full
   * well reached before the ADC's top). Noise spreads unclipped values over many levels, so a
   * pile of 0.02 % of the pixels at the very top means clipping, but only when there is noise:
   * a noise-free frame's flat top is not a clip. The lit frame's own noise below the top
   * counts: a sensor with under 0.5 DN of read noise still has shot noise where it clips. */
  double clip = fr->saturation_dn > 0 ? fr->saturation_dn : INFINITY;
  out->clip_known = fr->saturation_known && fr->saturation_dn > 0;
  for (int i = 0; i < 2; i++) {
    const DsImage *f = fr->lit[i];
    if (f->type == DS_SAMPLE_F32)
      continue;
    double top = ds_image_percentile (f, 100), near = ds_image_percentile (f, 99.98);
    double lit_noise = out->noise_var0 >= 0.25 ? INFINITY : ds_column_stats_noise_dn (f, NULL, top);
    if (top > out->dark_dn && near >= top && top <= clip && lit_noise >= 0.5) {
      clip = top;
      out->clip_known = TRUE;
    }
  }
  out->saturation_dn = isfinite (clip) ? clip : 0;
  out->clip_flagged = fr->saturation_dn > 0 && clip >= fr->saturation_dn;
  double ceiling = out->saturation_dn;
  out->bright_dn = MAX (ds_image_percentile (l0, 99.9), ds_image_percentile (l1, 99.9)) - out->dark_dn;

  const DsImage *lit[4] = { l0, l1, fr->coarse[0], fr->coarse[1] };
  guint n_lit = fr->coarse[0] ? 4 : 2;
  DsImage *masked[4] = { NULL };
  DsProbeClippedPlaces places;
  ds_probe_mask_clipped_places (lit, n_lit, ceiling, fr->geometry.period_px, masked, &places);
  g_autoptr (DsImage) m0 = masked[0];
  g_autoptr (DsImage) m1 = masked[1];
  g_autoptr (DsImage) m2 = masked[2];
  g_autoptr (DsImage) m3 = masked[3];
  const DsImage *stat[4];
  for (guint i = 0; i < 4; i++)
    stat[i] = masked[i] ? masked[i] : lit[i];
  DsProbePairFit fine = { 0 }, coarse = { 0 }, finer[DS_PROBE_FINER_MAX];
  memset (finer, 0, sizeof finer);
  /* On the scene's envelope for sine stripes only. Square ones of duty 1/2 sum flat too, but
   * their higher harmonics carry the blur when it is fitted to P and 2P, and the envelope, a
   * smooth division of the difference profile, moves them against the first: under a wide
   * scattered shadow the blur reads low and the modulation's drop between periods reads as a
   * kernel (tests/daemon/test_ctl.py's automatic capture covers such a scene). */
  double envelope_dn = fr->geometry.kind == DS_PATTERN_SINE ? out->dark_dn : -1;
  gboolean ok =
    ds_probe_pair_fit (l0, l1, stat[0], stat[1], ceiling, fr->geometry.period_px, envelope_dn, &fine, error);
  if (ok && fr->coarse[0])
    ok = ds_probe_pair_fit (fr->coarse[0], fr->coarse[1], stat[2], stat[3], ceiling, 2 * fr->geometry.period_px,
                            envelope_dn, &coarse, error);
  /* The finer pairs are not masked: a place that clips there clips at P too, and is left out of
   * the column statistics at the clip level all the same. */
  for (guint i = 0; ok && i < fr->n_finer; i++)
    ok = ds_probe_pair_fit (fr->finer[i].frame[0], fr->finer[i].frame[1], fr->finer[i].frame[0], fr->finer[i].frame[1],
                            ceiling, fr->finer[i].period_px, envelope_dn, &finer[i], error);
  if (!ok) {
    g_prefix_error (error, "pilot frames: ");
    ds_column_stats_clear (&fine.stats);
    ds_column_stats_clear (&coarse.stats);
    for (guint i = 0; i < DS_PROBE_FINER_MAX; i++)
      ds_column_stats_clear (&finer[i].stats);
    return FALSE;
  }
  for (guint i = 0; i < DS_PROBE_FINER_MAX; i++)
    ds_column_stats_clear (&finer[i].stats);
  guint64 n_px = (guint64) l0->width * l0->height;
  out->saturated_fraction = (double) fine.clipped / (double) n_px;
  out->phase_offset = fine.fit.phase[1];

  /* Noise: one frame's variance is var0 + gain * signal; the difference of the two phases has
   * twice var0 plus the gain times their summed signal. */
  double sum_signal = 0, sum_w = 0;
  for (guint x = 0; x < fine.stats.width; x++) {
    sum_signal += (fine.stats.mean_sum[x] - 2 * out->dark_dn) * fine.stats.count[x];
    sum_w += fine.stats.count[x];
  }
  double mean_sum = sum_w > 0 ? sum_signal / sum_w : 0;
  double var_diff = NAN, noise_signal = mean_sum;
  if (fr->coarse[0] && noise_on_sets (&fr->geometry)) {
    /* The scene cancels between the pairs' sums (ds_column_stats_noise_sets_dn), or nearly
     * (noise_on_sets ()), and the coarse pair's sum has the fine pair's mean: var (a - b) = var a + var b is half of it, over the
     * samples it was read on, whose signal is half their level. */
    double level = NAN, noise_sets = ds_column_stats_noise_sets_dn (stat, stat + 2, ceiling, &level);
    if (isfinite (noise_sets) && isfinite (level)) {
      var_diff = noise_sets * noise_sets / 2;
      noise_signal = level / 2 - 2 * out->dark_dn;
    }
  }
  if (!isfinite (var_diff)) {
    double noise_diff = ds_column_stats_noise_dn (stat[0], stat[1], ceiling);
    var_diff = isfinite (noise_diff) ? noise_diff * noise_diff : 2 * out->noise_var0;
  }
  out->noise_gain = noise_signal > 0 ? MAX (0.0, (var_diff - 2 * out->noise_var0) / noise_signal) : 0;
  out->noise_dark_shot = dark_shot_noise (fr->dark, out->dark_dn, out->noise_var0, out->noise_gain);

  /* Harmonics -> blur, Ld, alpha. */
  DsProbeEquation eq[DS_PROBE_MAX_EQUATIONS];
  guint n_eq = ds_probe_collect_equations (&fine.fit, fr->geometry.period_px, &fr->geometry, l0->width, eq, 0);
  gboolean two = coarse.ok;
  if (two) {
    guint before = n_eq;
    n_eq = ds_probe_collect_equations (&coarse.fit, 2 * fr->geometry.period_px, &fr->geometry, l0->width, eq, n_eq);
    if (n_eq == before)
      two = FALSE;
  }
  if (n_eq == 0) {
    g_set_error (error, DS_PROTOCOL_ERROR, DS_PROTOCOL_ERROR_DEVICE,
                 "pilot frames: no stripe modulation above the noise at period %g px (amplitude %.3g DN, "
                 "noise %.3g DN): no direct light to separate",
                 fr->geometry.period_px, fine.fit.amplitude[1], fine.fit.sigma_amplitude);
    ds_column_stats_clear (&fine.stats);
    ds_column_stats_clear (&coarse.stats);
    return FALSE;
  }
  /* The blur, unless calibrated: it lowers the higher harmonics against the first at a period,
   * the scattered stripes raise the coarse period against the fine one; every harmonic at both
   * periods is needed to tell them apart. */
  double sigma = 0;
  if (fr->blur_known) {
    sigma = CLAMP (fr->calibrated_blur_px, 0.0, fr->geometry.period_px / 2);
    out->blur_source = DS_BLUR_CALIBRATED;
  } else if (fr->calibrated_gain > 0) {
    /* The calibrated gain is the first harmonic as the rig's pixels see it. Above what the sharp
     * pattern integrated over the whole pixel gives, no blur explains it: the pixel integrates
     * less (the simulator samples sine stripes at the pixel centre), and a whole pixel's sinc
     * (1/P) would put the gains of every pilot period too low, the more so the finer the period
     * (so Ld high, and the narrow periods' harmonics read as a kernel) and the sine estimator's
     * error at
     * 1 - sinc (1/P) where it divides by the very gain the pixels see. */
    DsStripeModel matched = fr->geometry;
    ds_stripe_match_gain (&matched, fr->calibrated_gain);
    sigma = matched.blur_px;
    out->geometry.pixel_aperture = matched.pixel_aperture;
    out->blur_source = DS_BLUR_CALIBRATED;
  } else if (n_eq >= (two ? 3u : 2u)) {
    double best = INFINITY, hi = MIN (fr->geometry.period_px / 2, 4.0);
    for (double s = 0; s <= hi + 1e-9; s += 0.025) {
      DsProbeSolution so = ds_probe_solve_at (&fr->geometry, eq, n_eq, s, l0->width, two, FALSE);
      if (so.residual < best) {
        best = so.residual;
        sigma = s;
      }
    }
    out->blur_source = DS_BLUR_MEASURED;
  } else
    out->blur_source = DS_BLUR_ASSUMED_SHARP;
  out->geometry.blur_px = sigma;
  /* The finer periods join after the blur is found: a narrow kernel lowers their harmonics as a
   * wider blur would, and the blur is what P and 2P say it is. A pair at a period the blur has
   * made unresolvable (its first harmonic under half the sharp pattern's) says more about the
   * blur than about the kernel and is left out. */
  out->finest_period_px = fr->geometry.period_px;
  guint before_finer = n_eq;
  for (guint i = 0; i < fr->n_finer; i++) {
    double q = fr->finer[i].period_px;
    if (q < ds_scene_probe_finest_period (sigma) - 1e-9)
      continue;
    guint had = n_eq;
    n_eq = ds_probe_collect_equations (&finer[i].fit, q, &out->geometry, l0->width, eq, n_eq);
    for (guint k = had; k < n_eq; k++)
      if (eq[k].n == 1)
        out->finest_period_px = MIN (out->finest_period_px, q);
  }
  gboolean finer_used = n_eq > before_finer;
  two = two || finer_used;
  /* A rise at 2P that no kernel the flat harmonics at and below P allow is light wide against P:
   * left out of the transfer fit (scene_probe_wide.h) and so of the interval of Ld, whose single
   * kernel with a 1/k tail is one of the forms that rule out; kept for the hidden light's bound
   * (the leak at P is at most what the coarsest period keeps, whatever the kernel). */
  DsProbeEquation eq_seen[DS_PROBE_MAX_EQUATIONS];
  guint n_seen = n_eq;
  memcpy (eq_seen, eq, n_eq * sizeof *eq);
  DsProbeWideRise wide;
  n_eq = ds_probe_drop_wide_rise (&out->geometry, eq, n_eq, sigma, l0->width, fr->geometry.period_px, &wide);
  if (wide.left_out) {
    for (guint i = 0; i < n_seen; i++)
      g_debug ("scene probe: harmonic %u at %g px: x %.3g px, A %.4g +- %.2g DN, A/G %.4g", eq_seen[i].n,
               eq_seen[i].period, eq_seen[i].period / eq_seen[i].n, eq_seen[i].amplitude, eq_seen[i].sigma,
               eq_seen[i].amplitude / ds_probe_model_gain (&out->geometry, eq_seen[i].period, sigma,
                                                           eq_seen[i].offset, l0->width, eq_seen[i].n));
    g_debug ("scene probe: %s", wide.note + 2);
  }
  DsProbeEquation eq_all[DS_PROBE_MAX_EQUATIONS];
  guint n_all = 0;
  /* Then Ld and alpha. The transfer's logarithm is linear in x = Q / n only while x is small
   * against the distance over which forward-scattered light spreads (beyond, it saturates at the
   * whole forward-scattered flux): the line is fitted to the harmonics with x <= P, which
   * bracket the configured period and reach down towards 0, unless that leaves a single x known
   * to 5 % (the fit's noise, and how far the blur's uncertainty moves its gain), or no more
   * equations than the fit's three parameters (Ld, alpha, the blur's error), which they would
   * then fit exactly, noise and all: then the first harmonic at 2P, the most reliable point after
   * the one at P, stays in. */
  {
    guint near = 0;
    double x_min = INFINITY, x_max = 0;
    for (guint i = 0; i < n_eq; i++) {
      double G = ds_probe_model_gain (&out->geometry, eq[i].period, sigma, eq[i].offset, l0->width, eq[i].n);
      gboolean known = eq[i].sigma < 0.05 * eq[i].amplitude &&
                       fabs (ds_probe_gain_shift (&out->geometry, &eq[i], sigma, G, l0->width)) < 0.05;
      if (known && eq[i].period / eq[i].n <= fr->geometry.period_px * 1.001) {
        x_min = MIN (x_min, eq[i].period / eq[i].n);
        x_max = MAX (x_max, eq[i].period / eq[i].n);
        near++;
      }
    }
    guint below = 0;
    for (guint i = 0; i < n_eq; i++)
      below += eq[i].period / eq[i].n <= fr->geometry.period_px * 1.001;
    memcpy (eq_all, eq, n_eq * sizeof *eq);
    n_all = n_eq;
    if (two && near >= 2 && x_max > x_min * 1.05 && below > 3) {
      guint k = 0;
      for (guint i = 0; i < n_eq; i++)
        if (eq[i].period / eq[i].n <= fr->geometry.period_px * 1.001)
          eq[k++] = eq[i];
      n_eq = k;
    }
  }
  out->equations = n_eq;
  DsProbeSolution so = ds_probe_solve_at (&out->geometry, eq, n_eq, sigma, l0->width, two, TRUE);
  /* The narrow kernel shows as a transfer that rises from the finer periods to P and stops: the
   * line through x <= P alone cannot tell it from the small-angle rise, the coarse period
   * (where the line would go on rising) can. So line and narrow term are compared over all
   * the harmonics; the narrow term, when it wins, is the fit. */
  DsProbeNarrowFit narrow = { { 0 }, 0, 0, 0 };
  DsProbeSolution line_all = ds_probe_solve_at (&out->geometry, eq_all, n_all, sigma, l0->width, two, TRUE);
  gboolean narrow_won = finer_used && ds_probe_fit_narrow (&out->geometry, eq_all, n_all, sigma, l0->width,
                                                           fr->geometry.period_px, &line_all, &narrow);
  /* Two checks against a kernel made up from the harmonics' scatter (five parameters fit four first
   * harmonics of sine stripes exactly, and the harmonics' scatter alone can pass for a kernel
   * holding a tenth of Ld on a scene with about no scattered light). The scene must show scattered
   * light in its mean (the line's Lg, at least DS_PROBE_NARROW_MIN_LG of its Ld): a narrow kernel's
   * light is taken from what the line called direct, so a scene whose mean holds next to nothing
   * beyond the line's Ld is not given one. And the kernel must have let go of the stripes at the
   * finest period (its transfer there under DS_PROBE_NARROW_MAX_AT_FINEST): one that still keeps
   * more is narrower than the pilot resolves, and below the finest period only the form would
   * speak; narrow_verdict () then makes the prediction a lower bound. A kernel that keeps more than
   * DS_PROBE_NARROW_MAX_OWN_AT_FINEST of its own stripes at the finest first harmonic is not
   * resolved by the first harmonics at all: only the higher harmonics, whose gain the blur's
   * uncertainty moves by 5-10 %, then carry the term (a single higher harmonic a few % low would
   * read as a sub-pixel kernel holding a large share of Ld, nearly all of it modulated at P), and
   * the line is the fit. */
  double pattern_mean = fr->geometry.kind == DS_PATTERN_SINE
                          ? fr->geometry.black_level + (1 - fr->geometry.black_level) / 2
                          : fr->geometry.duty + fr->geometry.black_level * (1 - fr->geometry.duty);
  double ld_line = exp (line_all.log_ld), lg_line = mean_sum / (2 * pattern_mean) - ld_line;
  gboolean beyond = FALSE;
  if (narrow_won && !(lg_line >= DS_PROBE_NARROW_MIN_LG * ld_line))
    narrow_won = FALSE;
  if (narrow_won) {
    double x = out->finest_period_px;
    double at_finest =
      exp (narrow.s.alpha * x) * (1 + narrow.beta * ds_probe_kernel_mtf (narrow.width, narrow.shape, x)) - 1;
    if (at_finest > DS_PROBE_NARROW_MAX_AT_FINEST)
      narrow_won = FALSE, beyond = TRUE;
    else if (ds_probe_kernel_mtf (narrow.width, narrow.shape, x) > DS_PROBE_NARROW_MAX_OWN_AT_FINEST)
      narrow_won = FALSE;
  }
  /* And where the harmonics do not over-determine the term, only if it passes through them
   * (scene_probe_determined.h: sine stripes at four periods give as many equations as the term's
   * parameters, and it fits differences no kernel makes); a kernel keeping the stripes at the
   * finest period has made the prediction a lower bound above all the same. */
  char undetermined[200] = "";
  if (narrow_won && !ds_probe_narrow_measured (eq_all, n_all, narrow.s.residual, undetermined, sizeof undetermined))
    narrow_won = FALSE;
  out->narrow_beyond = beyond;
  if (narrow_won) {
    so = narrow.s;
    out->equations = n_all;
    out->narrow_fraction = narrow.beta;
    out->narrow_kernel_px = narrow.width;
    out->narrow_shape = narrow.shape;
  }
  out->ld_mean = exp (so.log_ld);
  out->leak_per_px = so.alpha;
  /* The acceptance cone's kernel where the line cannot follow its saturation (scene_probe.h). */
  DsConeFit cone = { 0 };
  gboolean cone_used = two && !narrow_won &&
                       ds_probe_fit_cone (&out->geometry, eq_all, n_all, sigma, l0->width, mean_sum / (2 * pattern_mean),
                                          out->ld_mean, &cone);
  if (cone_used) {
    so.residual = cone.chi2;
    n_eq = out->equations = n_all;
    out->ld_mean = cone.ld;
    out->leak_per_px = 0;
    out->narrow_fraction = (mean_sum / (2 * pattern_mean) - cone.ld) / cone.ld;
    out->narrow_kernel_px = cone.radius_px;
    out->narrow_shape = DS_PROBE_SHAPE_CONE;
  }

  out->leak_measured = two;
  out->fit_rms = n_eq > (two ? 2u : 1u) ? sqrt (so.residual / n_eq) : 0;
  ds_probe_fit_consistency (so.residual, narrow_won ? n_all : n_eq, 1 + (two ? 1 : 0) + (narrow_won ? 2 : 0), out);
  if (two)
    g_snprintf (out->leak_note, sizeof out->leak_note,
                "measured at periods %g and %g px: scattered light keeps %.1f %% of the stripes' "
                "first harmonic at %g px",
                fr->geometry.period_px, 2 * fr->geometry.period_px,
                100 * ds_scene_probe_leak (out, fr->geometry.period_px, 1), fr->geometry.period_px);
  if (two && wide.left_out) {
    gsize len = strlen (out->leak_note);
    g_strlcpy (out->leak_note + len, wide.note, sizeof out->leak_note - len);
  }
  if (cone_used) {
    gsize len = strlen (out->leak_note);
    g_snprintf (out->leak_note + len, sizeof out->leak_note - len, " (the lens's acceptance cone: a kernel of %.2f px)",
                cone.radius_px);
  }
  if (!two)
    g_snprintf (out->leak_note, sizeof out->leak_note,
                "not measured (%s): scattered light that keeps the stripes is not in the prediction, "
                "which is a lower bound",
                fr->coarse[0] ? "no modulation at twice the period"
                              : fr->coarse_missing ? fr->coarse_missing : "no second period");

  /* Lg from the mean: two opposite phases sum to the pattern mean m twice (whole periods). */
  double m = fr->geometry.kind == DS_PATTERN_SINE
               ? fr->geometry.black_level + (1 - fr->geometry.black_level) / 2
               : fr->geometry.duty + fr->geometry.black_level * (1 - fr->geometry.duty);
  out->lg_mean = MAX (0.0, mean_sum / (2 * m) - out->ld_mean);

  /* Spread of Ld across the scene: per column, mean (D^2) - noise = mean (Ld^2) Dp(x)^2 and
   * the column's mean D = mean (Ld) Dp(x), whose square carries the noise over count rows. */
  double num = 0, den = 0;
  for (guint x = 0; x < fine.stats.width; x++) {
    guint32 c = fine.stats.count[x];
    if (!c)
      continue;
    double v = 2 * out->noise_var0 + out->noise_gain * MAX (0.0, fine.stats.mean_sum[x] - 2 * out->dark_dn);
    double d = fine.stats.mean_diff[x];
    num += (fine.stats.mean_sq_diff[x] - v) * c;
    den += (d * d - v / c) * c;
  }
  out->ld_spread = den > 0 && num > den ? MIN (num / den, 25.0) : 1.0;
  out->ld_spread = MIN (out->ld_spread * spread_across_columns (&fine, &out->geometry, out), 25.0);
  DsProbeDirectInterval interval;
  ds_probe_direct_interval (eq_all, n_all, &out->geometry, sigma, l0->width, out->ld_mean, out->ld_mean + out->lg_mean,
                            &interval);
  double ld_fit = out->ld_mean, total_fit = out->ld_mean + out->lg_mean;
  ds_probe_count_clipped_places (out, &places, fr->geometry.black_level, m);
  /* The leak the harmonics read can exceed the scattered light the mean shows, and a scattered
   * stripe is scattered light (A_n = G_n (Ld + S T_n), T_n <= 1): the harmonics' scatter and the
   * blur's uncertainty put a few % on a transfer, the mean knows the light to 0.1 %. */
  out->leak_bounded = out->leak_measured && out->ld_mean > 0;
  out->leak_max = out->leak_bounded ? out->lg_mean / out->ld_mean : 0;
  if (out->leak_bounded) {
    out->leak_bounded = FALSE;
    double read = ds_scene_probe_leak (out, fr->geometry.period_px, 1);
    out->leak_bounded = TRUE;
    gsize len = strlen (out->leak_note);
    if (read > out->leak_max)
      g_snprintf (out->leak_note + len, sizeof out->leak_note - len,
                  ", held to the scattered light the mean shows (%.1f %% of Ld)", 100 * out->leak_max);
  }
  /* Also the prediction's (ds_operating_point_uncertainty ()). */
  out->ld_uncertainty = ds_probe_ld_uncertainty (eq_all, n_all, &out->geometry, sigma, l0->width);
  DsProbeHiddenLight hidden;
  ds_probe_hidden_light (eq_seen, n_seen, &out->geometry, sigma, l0->width, ld_fit, total_fit, out->ld_uncertainty,
                         ds_scene_probe_leak (out, fr->geometry.period_px, 1), &hidden);
  narrow_verdict (fr, finer_used, out->ld_uncertainty, cone_used ? &cone : NULL, &hidden, out);
  if (finer_used && undetermined[0]) {
    gsize len = strlen (out->narrow_note);
    g_strlcpy (out->narrow_note + len, undetermined, sizeof out->narrow_note - len);
  }
  if (out->narrow_unresolved && two && interval.computed) {
    out->ld_interval = TRUE;
    out->ld_unbounded = interval.unbounded;
    out->ld_lower = interval.unbounded ? 0 : interval.ratio * out->ld_mean;
    out->worst_kernel_px = interval.unbounded ? 0 : interval.kernel_px;
    g_strlcpy (out->interval_note, interval.note, sizeof out->interval_note);
  } else
    out->ld_lower = out->ld_mean;
  ds_column_stats_clear (&fine.stats);
  ds_column_stats_clear (&coarse.stats);
  return TRUE;
}
