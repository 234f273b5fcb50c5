#include "daemon/operating/scene_probe_pairs.h"

#include <math.h>
#include <string.h>

#include "daemon/operating/operating_error.h"
#include "proc/clip_level.h"

/* The scene's level per column relative to its mean, (a + b - 2 dark) over the rows, for stripes
 * whose opposite phases sum to a constant: the columns' Ld + Lg, whatever the stripes. The pair's
 * difference profile is the stripes times the columns' Ld: where objects make Ld vary across the
 * columns at frequencies next to twice the stripes' (a high harmonic of a grid's pitch), the
 * product has components at the stripes' own frequency that a plain fit reads as their
 * amplitude, differently at each period (a first harmonic a few % low at one period reads as
 * scattered stripes several times the kernel's). The harmonics are fitted on this envelope
 * (ds_stripe_harmonics_fit_envelope), which follows Ld as far as Lg is even across the columns.
 * NULL when the level is not positive. */
static double *
scene_envelope (const DsColumnStats *st, double dark_dn)
{
  double sum = 0, n = 0;
  for (guint x = 0; x < st->width; x++) {
    sum += (st->mean_sum[x] - 2 * dark_dn) * st->count[x];
    n += st->count[x];
  }
  if (!(n > 0 && sum > 0))
    return NULL;
  double mean = sum / n;
  double *e = g_new (double, st->width);
  for (guint x = 0; x < st->width; x++)
    e[x] = st->count[x] ? (st->mean_sum[x] - 2 * dark_dn) / mean : 1.0;
  return e;
}

gboolean
ds_probe_pair_check_clipping (const DsImage *a, const DsImage *b, double ceiling, guint64 *clipped_out,
                              GError **error)
{
  guint64 n_px = (guint64) a->width * a->height, clipped = ds_clip_count (a, b, ceiling);
  if (clipped_out)
    *clipped_out = clipped;
  if (clipped * 2 <= n_px)
    return TRUE;
  g_set_error (error, DS_OPERATING_ERROR, DS_OPERATING_ERROR_CLIPPED,
               "%.0f %% of the pixels are at the clip level (%.0f DN) in the pilot frames: lower the exposure "
               "or the gain",
               100.0 * (double) clipped / (double) n_px, ceiling);
  return FALSE;
}

/* a, b: the pair as taken (for the clip count), stat_a, stat_b: what the statistics read (the
 * pair with the clipped places left out, ds_probe_mask_clipped_places ()). envelope_dn >= 0: the harmonics
 * are fitted on the scene's envelope (scene_envelope ()), with this dark level taken off. */
gboolean
ds_probe_pair_fit (const DsImage *a, const DsImage *b, const DsImage *stat_a, const DsImage *stat_b, double ceiling,
                   double period, double envelope_dn, DsProbePairFit *out, GError **error)
{
  guint64 clipped = 0;
  if (!ds_probe_pair_check_clipping (a, b, ceiling, &clipped, error))
    return FALSE;
  if (!ds_column_stats_compute (stat_a, stat_b, ceiling, &out->stats, error))
    return FALSE;
  out->clipped = clipped;
  guint32 *weight = out->stats.count;
  g_autofree double *envelope = envelope_dn >= 0 ? scene_envelope (&out->stats, envelope_dn) : NULL;
  g_autoptr (GError) local = NULL;
  if (!(envelope && ds_stripe_harmonics_fit_envelope (out->stats.mean_diff, weight, envelope, 0, out->stats.width,
                                                      period, DS_STRIPE_MAX_HARMONICS, &out->fit, NULL)) &&
      !ds_stripe_harmonics_fit (out->stats.mean_diff, weight, 0, out->stats.width, period,
                                DS_STRIPE_MAX_HARMONICS, &out->fit, &local)) {
    ds_probe_pair_refuse_unfitted (&out->stats, clipped, ceiling, period, local, error);
    return FALSE;
  }
  out->ok = TRUE;
  return TRUE;
}

void
ds_probe_pair_refuse_unfitted (const DsColumnStats *stats, guint64 clipped, double ceiling, double period,
                               const GError *fit_error, GError **error)
{
  /* Columns drop out of the fit only where every sample of theirs is left out: at the clip
   * level, or with the places that clip (ds_probe_mask_clipped_places ()). */
  guint empty = 0;
  for (guint x = 0; x < stats->width; x++)
    empty += stats->count[x] == 0;
  if (clipped > 0 || stats->excluded > 0) {
    g_set_error (error, DS_OPERATING_ERROR, DS_OPERATING_ERROR_CLIPPED,
                 "the places at the clip level (%.0f DN) leave %u of %u columns of the pilot frames with no "
                 "sample to fit the stripes at %g px on: lower the exposure or the gain",
                 ceiling, stats->width - empty, stats->width, period);
    return;
  }
  if (fit_error)
    g_propagate_error (error, g_error_copy (fit_error));
  else
    g_set_error (error, DS_OPERATING_ERROR, DS_OPERATING_ERROR_NO_STRIPES, "the stripes at %g px could not be fitted",
                 period);
}

/* The pilot frames with every sample within half the coarsest period (along x, the stripes'
 * direction of change) of a clipped sample in any lit frame set to NAN, which the column
 * statistics leave out. A sample clips where the light reaches the clip level at that stripe
 * phase: leaving out only the clipped samples keeps, at the stripes' peaks, only the places dim
 * enough not to clip there, but every place between the peaks, so the kept population depends
 * on the phase and the difference profile loses its first harmonic (Ld, and with it Lg, read far
 * off). A place whose peak clips goes whole, at every phase and at both periods alike
 * (one population for the scattered stripes' fit), and is counted back by
 * ds_probe_count_clipped_places () from the clip level and its trough: the lowest sample of the pair at
 * P within half a period, a whole period of either phase, which does not clip. NULL copies when
 * nothing clips. */
void
ds_probe_mask_clipped_places (const DsImage *const *lit, guint n_lit, double ceiling, double period_px,
                              DsImage **masked, DsProbeClippedPlaces *places)
{
  memset (places, 0, sizeof *places);
  for (guint i = 0; i < n_lit; i++)
    masked[i] = NULL;
  if (!(ceiling > 0) || !isfinite (ceiling))
    return;
  const DsImage *l = lit[0];
  guint w = l->width, h = l->height;
  guint half = (guint) ceil ((n_lit / 2) * period_px / 2), half_fine = (guint) ceil (period_px / 2);
  g_autofree guint8 *out = g_new0 (guint8, w);
  g_autofree guint8 *clipped = g_new (guint8, w);
  g_autofree double *low = g_new (double, w);
  guint64 left_out = 0;
  for (guint y = 0; y < h; y++) {
    memset (clipped, 0, w);
    for (guint i = 0; i < n_lit; i++) {
      const void *r = ds_image_row (lit[i], y);
      for (guint x = 0; x < w; x++)
        clipped[x] |= ds_image_sample (lit[i], r, x) >= ceiling;
    }
    /* Dilation along the row by `half` on either side: a running count of clipped samples. */
    guint run = 0, row_out = 0;
    for (guint x = 0; x < MIN (half, w); x++)
      run += clipped[x];
    for (guint x = 0; x < w; x++) {
      if (x + half < w)
        run += clipped[x + half];
      if (x > half)
        run -= clipped[x - half - 1];
      out[x] = run > 0;
      row_out += out[x];
    }
    if (row_out && !masked[0])
      for (guint i = 0; i < n_lit; i++) {
        masked[i] = ds_image_new (DS_SAMPLE_F32, w, h, NULL);
        for (guint yy = 0; yy < y; yy++) {
          const void *r = ds_image_row (lit[i], yy);
          float *m = ds_image_row (masked[i], yy);
          for (guint x = 0; x < w; x++)
            m[x] = (float) ds_image_sample (lit[i], r, x);
        }
      }
    if (!masked[0])
      continue;
    for (guint i = 0; i < n_lit; i++) {
      const void *r = ds_image_row (lit[i], y);
      float *m = ds_image_row (masked[i], y);
      for (guint x = 0; x < w; x++)
        m[x] = out[x] ? NAN : (float) ds_image_sample (lit[i], r, x);
    }
    if (!row_out)
      continue;
    const void *r0 = ds_image_row (lit[0], y), *r1 = ds_image_row (lit[1], y);
    for (guint x = 0; x < w; x++)
      low[x] = MIN (ds_image_sample (lit[0], r0, x), ds_image_sample (lit[1], r1, x));
    for (guint x = 0; x < w; x++) {
      if (!out[x])
        continue;
      double trough = INFINITY;
      for (guint k = x > half_fine ? x - half_fine : 0; k <= MIN (w - 1, x + half_fine); k++)
        trough = MIN (trough, low[k]);
      if (!(trough < ceiling))
        trough = ceiling;
      places->mean_peak_over_trough += ceiling - trough;
      places->mean_sq_peak_over_trough += (ceiling - trough) * (ceiling - trough);
      places->mean_trough += trough;
      left_out++;
    }
  }
  places->fraction = (double) left_out / ((double) w * h);
  if (left_out) {
    places->mean_peak_over_trough /= (double) left_out;
    places->mean_sq_peak_over_trough /= (double) left_out;
    places->mean_trough /= (double) left_out;
  }
}

/* Counts the places ds_probe_mask_clipped_places () left out back into Ld, its spread and Lg: the
 * predictions are over the whole scene, at exposures where those places no longer clip, and
 * they are its brightest, which weigh most in a relative RMSE. A place's stripes' peak is at
 * least the clip level c and its trough t is measured: with the pattern's lit level 1, its
 * black level b and mean m, c <= D + Ld + m Lg and t = D + b Ld + m Lg, so Ld >= (c - t) / (1 - b)
 * and Lg = (t - D - b Ld) / m: a lower bound on Ld (a brighter place only makes the prediction
 * more cautious), whatever share of it the scattered light is (a narrow kernel's Lg follows the
 * direct light, a wide one's does not). Blur raises the troughs of fine stripes: Ld lower
 * still. */
void
ds_probe_count_clipped_places (DsSceneProbe *out, const DsProbeClippedPlaces *c, double black_level,
                               double pattern_mean, GString *leak_note)
{
  if (!(c->fraction > 0) || !(c->fraction < 1) || !(black_level < 1) || !(pattern_mean > 0))
    return;
  double ld_c = c->mean_peak_over_trough / (1 - black_level);
  double ld_c_sq = c->mean_sq_peak_over_trough / ((1 - black_level) * (1 - black_level));
  double lg_c = MAX (0.0, (c->mean_trough - out->noise.dark_dn - black_level * ld_c) / pattern_mean);
  double kept = 1 - c->fraction;
  double mean = kept * out->light.ld_mean + c->fraction * ld_c;
  double mean_sq = kept * out->light.ld_spread * out->light.ld_mean * out->light.ld_mean + c->fraction * ld_c_sq;
  double lg = kept * out->light.lg_mean + c->fraction * lg_c;
  /* The scattered stripes were measured on the kept places, as a share of their direct light:
   * the kernel's transfer times their scattered light over their direct light. Left are the dim
   * places, where the light scattered in from bright neighbours is a larger share (next to places
   * that clip it can be several times their direct light): the same transfer over the whole
   * scene's share. */
  double share_kept = out->light.ld_mean > 0 ? out->light.lg_mean / out->light.ld_mean : 0, share = mean > 0 ? lg / mean : 0;
  if (out->leak.measured && share_kept > 0 && out->leak.per_px > 0) {
    double p = out->geometry.period_px, leak = expm1 (out->leak.per_px * p) * share / share_kept;
    out->leak.per_px = log1p (leak) / p;
    g_string_append_printf (leak_note, " (%.1f %% over the scene, the places that clip counted in)", 100 * leak);
  }
  out->light.lg_mean = lg;
  out->light.ld_mean = mean;
  out->light.ld_spread = mean > 0 ? CLAMP (mean_sq / (mean * mean), 1.0, 25.0) : 1.0;
}

double
ds_probe_pair_spread_across_columns (const DsProbePairFit *f, const DsStripeModel *geometry, const DsSceneProbe *out)
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
    double v = 2 * out->noise.var0 + out->noise.gain * MAX (0.0, f->stats.mean_sum[x] - 2 * out->noise.dark_dn);
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
