#include "daemon/operating/scene_probe_loss.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "daemon/operating/film_bound.h"
#include "proc/harmonic_gain.h"
#include "proc/lit_level.h"

double
ds_probe_fresnel_transmittance (double n)
{
  double r = (n - 1) / (n + 1);
  r *= r;
  return (1 - r) / (1 + r);
}

static int
compare_double (const void *a, const void *b)
{
  double x = *(const double *) a, y = *(const double *) b;
  return (x > y) - (x < y);
}

/* Each unclipped pixel's lit level (proc/lit_level.h) over the sum the pattern model gives the two
 * opposite phases there. Returns how many; at most one sample in `step` rows is taken.
 * *model_sum is the model's mean sum over the columns used. */
static gsize
pixel_levels (const DsProbeFrames *fr, const DsSceneProbe *p, guint step, double *levels, double *model_sum)
{
  guint w = fr->lit[0]->width;
  g_autofree double *e = g_new (double, w);
  for (guint x = 0; x < w; x++)
    e[x] = ds_stripe_value (&p->geometry, x, p->phase_offset) + ds_stripe_value (&p->geometry, x, p->phase_offset + 0.5);
  return ds_lit_level_samples (fr->lit[0], fr->lit[1], fr->dark, e, p->clip.saturation_dn, step, levels, model_sum);
}

/* The upper end of the flagged film's bias (film_bound.h) at the loss's upper confidence. */
static void
film_bound (const DsProbeFrames *fr, DsProbeLoss *l)
{
  if (!(fr->acceptance_half_angle_deg > 0)) {
    g_strlcpy (l->bound_note, "not measured: the lens's acceptance angle is not known ([camera] "
                              "acceptance-half-angle-deg)", sizeof l->bound_note);
    return;
  }
  double t_low = l->transmittance * (1 - DS_PROBE_LOSS_Z * l->sigma);
  l->acceptance_deg = fr->acceptance_half_angle_deg;
  l->bias_upper = ds_film_bias_upper (t_low, l->acceptance_deg);
  l->bounded = isfinite (l->bias_upper);
  double f = ds_film_cone_fraction (DS_FILM_MAX_G, ds_film_inner_cone (l->acceptance_deg, DS_FILM_MIN_INDEX));
  if (l->bounded)
    g_snprintf (l->bound_note, sizeof l->bound_note,
                "single Henyey-Greenstein scattering with g <= %.2f puts %.0f %% of the scattered light into the "
                "lens's cone (%.3g deg in air); a transmittance of at least %.3f then bounds the light passing for "
                "direct at %.3g of the direct light",
                DS_FILM_MAX_G, 100 * f, l->acceptance_deg, t_low, l->bias_upper);
  else
    g_snprintf (l->bound_note, sizeof l->bound_note,
                "single Henyey-Greenstein scattering with g <= %.2f puts %.0f %% of the scattered light into the "
                "lens's cone (%.3g deg in air); a transmittance of %.3f allows no direct light at all, so no upper end",
                DS_FILM_MAX_G, 100 * f, l->acceptance_deg, t_low);
}

void
ds_probe_loss_measure (const DsProbeFrames *fr, DsSceneProbe *out)
{
  DsProbeLoss *l = &out->loss;
  memset (l, 0, sizeof *l);
  l->transmittance = NAN;
  if (!(fr->open_field_dn > 0) && fr->open_field_unused) {
    g_snprintf (l->note, sizeof l->note, "not measured: %s", fr->open_field_unused);
    return;
  }
  if (!(fr->open_field_dn > 0)) {
    g_strlcpy (l->note, "not measured: the open field's lit level is not known (descatterctl calibrate on a clear "
                        "reference prints it as [illuminator] open-field-dn-per-ms)", sizeof l->note);
    return;
  }
  const DsImage *lit = fr->lit[0];
  guint step = MAX (1u, (guint) ((gsize) lit->width * lit->height / DS_PROBE_LOSS_MAX_SAMPLES));
  g_autofree double *levels = g_new (double, (gsize) lit->width * ((lit->height + step - 1) / step));
  double model_sum = 0;
  gsize n = pixel_levels (fr, out, step, levels, &model_sum);
  if (n < DS_PROBE_LOSS_MIN_PIXELS) {
    g_snprintf (l->note, sizeof l->note, "not measured: %" G_GSIZE_FORMAT " unclipped lit pixels (need %u)", n,
                DS_PROBE_LOSS_MIN_PIXELS);
    return;
  }
  qsort (levels, n, sizeof *levels, compare_double);
  double quantile = levels[MIN (n - 1, (gsize) floor (DS_LIT_LEVEL_QUANTILE * n))];
  /* The quantile of a level spread by the noise sits DS_PROBE_LOSS_QUANTILE_Z of its standard
   * deviation above it: two lit frames' noise and twice the dark frame's, over the model's sum. */
  double sigma_px = sqrt (6 * out->noise.var0 + out->noise.gain * MAX (0.0, quantile * model_sum)) / model_sum;
  l->known = TRUE;
  l->open_dn = fr->open_field_dn;
  l->level_dn = quantile - DS_PROBE_LOSS_QUANTILE_Z * sigma_px;
  l->transmittance = l->level_dn / l->open_dn;
  double rel_noise = l->level_dn > 0 ? sigma_px / l->level_dn / sqrt ((double) n * (1 - DS_LIT_LEVEL_QUANTILE)) : 0;
  double sigma = hypot (DS_PROBE_LOSS_CALIBRATION, rel_noise);
  l->sigma = sigma;
  double fresnel = ds_probe_fresnel_transmittance (DS_PROBE_LOSS_MAX_INDEX);
  l->floor = fresnel * (1 - DS_PROBE_LOSS_Z * sigma);
  double seen = out->light.ld_mean > 0 ? out->light.lg_mean / out->light.ld_mean : 0;
  gboolean lost = l->transmittance < l->floor;
  l->unexplained = lost && seen < DS_PROBE_LOSS_SEEN_LG;
  g_debug ("scene probe: open field %.4g DN, scene %.4g DN over %" G_GSIZE_FORMAT " pixels (noise %.3g DN): T %.4f, "
           "floor %.4f, Lg/Ld %.4f", l->open_dn, l->level_dn, n, sigma_px, l->transmittance, l->floor, seen);
  if (l->unexplained)
    film_bound (fr, l);
  if (l->unexplained)
    g_snprintf (l->note, sizeof l->note,
                "the scene passes %.1f %% of the open field's light (two faces of index up to %.1f pass %.1f %%) and "
                "the pilot sees scattered light of %.1f %% of the direct light: the rest was absorbed or scattered, and "
                "a forward-peaked medium also scatters light into the lens within a pixel of its path, which no "
                "stripe period tells from direct light, so the prediction is a lower bound",
                100 * l->transmittance, DS_PROBE_LOSS_MAX_INDEX, 100 * fresnel, 100 * seen);
  else
    g_snprintf (l->note, sizeof l->note,
                "the scene passes %.1f %% of the open field's light (%s %.1f %%, what two faces of index up to %.1f, "
                "the noise and the calibration explain)%s",
                100 * l->transmittance, lost ? "below" : "at least", 100 * l->floor, DS_PROBE_LOSS_MAX_INDEX,
                lost ? "; the probe sees the scattered light itself" : "");
}
