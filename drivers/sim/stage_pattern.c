/* Stripe pattern stage (always built): the illuminator's light on the medium's entry face.
 * Phase k of N: u = frac(x/P - k/N); square: lit where |u| (wrapped to [-1/2, 1/2)) < a/2;
 * sine: 0.5 (1 + cos 2 pi u); value b + (1 - b) pattern. The projector's defocus (a Gaussian of
 * sigma edge-blur-px) blurs the continuous pattern on the medium; a pixel then integrates the
 * blurred square stripes over its width (edges fall on pixels; a point sample there would shift
 * the duty), in closed form, and takes the sine at its centre. */
#include <math.h>
#include <string.h>

#include "drivers/sim/stage.h"

typedef struct {
  DsSceneSpec spec;   /* the scalar fields only (objects not used) */
  double photons_per_px_per_ms;
} PatternData;

/* Integral of the Gaussian-blurred unit step Phi(t / sigma) from -inf to u:
 * u Phi(u / sigma) + sigma phi(u / sigma). */
static double
blurred_step_integral (double u, double sigma)
{
  double z = u / sigma;
  return u * 0.5 * erfc (-z / G_SQRT2) + sigma * exp (-0.5 * z * z) / sqrt (2 * G_PI);
}

/* Lit fraction of the square stripes over [x0, x1] (pattern units: x in px). Lit intervals are
 * [P (j + shift) - aP/2, P (j + shift) + aP/2]. Without blur the overlap is exact; with blur each
 * interval's blurred indicator Phi((x - l)/sigma) - Phi((x - h)/sigma) integrates in closed form.
 * Only intervals within 8 sigma of the pixel can differ from 0 or their full length. */
static double
square_integral (const DsSceneSpec *s, double x0, double x1, double shift)
{
  double P = s->period_px, half = s->duty * P / 2, sigma = s->edge_blur_px, reach = 8 * sigma;
  double lit = 0;
  for (double j = floor ((x0 - reach) / P - shift) - 1; j <= floor ((x1 + reach) / P - shift) + 1; j++) {
    double c = P * (j + shift), l = c - half, h = c + half;
    if (!(sigma > 0)) {
      double lo = MAX (x0, l), hi = MIN (x1, h);
      if (hi > lo)
        lit += hi - lo;
      continue;
    }
    if (h < x0 - reach || l > x1 + reach)
      continue;
    if (l > x0 + reach && h < x1 - reach) {
      lit += h - l;
      continue;
    }
    lit += blurred_step_integral (x1 - l, sigma) - blurred_step_integral (x0 - l, sigma) -
           blurred_step_integral (x1 - h, sigma) + blurred_step_integral (x0 - h, sigma);
  }
  return lit;
}

/* Pattern in [0, 1] at pixel x (centre at x, covering [x - 1/2, x + 1/2]). */
static double
pattern_at (const DsSceneSpec *s, double x, double shift)
{
  double P = s->period_px;
  if (s->sine) {
    /* Sampled at the pixel centre: integrating over the pixel would scale the amplitude by
     * sin(pi/P)/(pi/P) (2.5 % at P = 8), which the estimators' theory gain leaves out; real
     * rigs calibrate it (proc/harmonic_gain.h), the simulator keeps the convention exact.
     * A Gaussian blur of a sine is the sine with its amplitude times exp(-2 pi^2 sigma^2 / P^2). */
    double blur = exp (-2 * G_PI * G_PI * s->edge_blur_px * s->edge_blur_px / (P * P));
    return 0.5 * (1.0 + blur * cos (2 * G_PI * (x / P - shift)));
  }
  return CLAMP (square_integral (s, x - 0.5, x + 0.5, shift), 0.0, 1.0);
}

double *
ds_stage_pattern_profile (const DsSceneSpec *s, guint k, guint n, int x0, guint count)
{
  double shift = n ? (double) k / n : 0.0, b = s->black_level;
  double *p = g_new (double, count);
  for (guint i = 0; i < count; i++)
    p[i] = b + (1.0 - b) * pattern_at (s, (double) x0 + i, shift);
  return p;
}

static gboolean
pattern_apply (const DsStage *st, DsLight *l, const DsStageArgs *a, GError **error)
{
  (void) error;
  const PatternData *d = st->data;
  if (!a->illuminator_on)
    return TRUE; /* buffers start dark */
  guint m = l->margin;
  DsSceneSpec spec = d->spec;
  if (a->period_px > 0)
    spec.period_px = a->period_px;
  g_autofree double *profile =
    a->full ? NULL : ds_stage_pattern_profile (&spec, a->phase, a->n_phases, -(int) m, l->incident->width);
  double flux = d->photons_per_px_per_ms * a->exposure_us / 1000.0;
  float *in = ds_image_row (l->incident, 0);
  for (guint x = 0; x < l->incident->width; x++)
    in[x] = (float) (flux * (profile ? profile[x] : 1.0));
  for (guint y = 0; y < l->direct->height; y++)
    memcpy (ds_image_row (l->direct, y), in + m, l->direct->width * sizeof (float));
  return TRUE;
}

DsStage *
ds_stage_pattern_new (const DsSceneSpec *s, double object_pitch_mm)
{
  PatternData *d = g_new0 (PatternData, 1);
  d->spec = *s;
  d->spec.objects = NULL;
  d->spec.name = d->spec.path = NULL;
  double pitch_um = object_pitch_mm * 1000.0;
  d->photons_per_px_per_ms = s->irradiance * pitch_um * pitch_um;
  DsStage *st = g_new0 (DsStage, 1);
  st->kind = DS_RENDER_STAGE_PATTERN;
  st->reason = g_strdup_printf ("always: %s stripes, period %g px, duty %g, black level %g%s; %.4g photons/px/ms",
                                s->sine ? "sine" : "square", s->period_px, s->duty, s->black_level,
                                s->edge_blur_px > 0 ? ", blurred edges" : "", d->photons_per_px_per_ms);
  st->apply = pattern_apply;
  st->data = d;
  st->free_data = g_free;
  return st;
}
