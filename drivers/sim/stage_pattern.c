/* Stripe pattern stage (always built): the illuminator's light on the medium's entry face.
 * Phase k of N: u = frac(x/P - k/N); square: lit where |u| (wrapped to [-1/2, 1/2)) < a/2;
 * sine: 0.5 (1 + cos 2 pi u); value b + (1 - b) pattern. A pixel integrates square stripes
 * over its width (edges fall on pixels; a point sample there would shift the duty) and takes
 * the sine at its centre; then a Gaussian of sigma edge-blur-px blurs the edges. */
#include <math.h>
#include <string.h>

#include "drivers/sim/stage.h"

typedef struct {
  DsSceneSpec spec;   /* the scalar fields only (objects not used) */
  double photons_per_px_per_ms;
} PatternData;

/* Pattern in [0, 1] at pixel x (centre at x, covering [x - 1/2, x + 1/2]). */
static double
pattern_at (const DsSceneSpec *s, double x, double shift)
{
  double P = s->period_px;
  if (s->sine) {
    /* Sampled at the pixel centre: integrating over the pixel would scale the amplitude by
     * sin(pi/P)/(pi/P) (2.5 % at P = 8), which the estimators' theory gain leaves out; real
     * rigs calibrate it (proc/harmonic_gain.h), the simulator keeps the convention exact. */
    return 0.5 * (1.0 + cos (2 * G_PI * (x / P - shift)));
  }
  double u0 = (x - 0.5) / P - shift, u1 = (x + 0.5) / P - shift, lit = 0;
  for (double j = floor (u0) - 1; j <= floor (u1) + 1; j++) {
    double lo = MAX (u0, j - s->duty / 2), hi = MIN (u1, j + s->duty / 2);
    if (hi > lo)
      lit += hi - lo;
  }
  return lit / (u1 - u0);
}

double *
ds_stage_pattern_profile (const DsSceneSpec *s, guint k, guint n, int x0, guint count)
{
  double shift = n ? (double) k / n : 0.0, b = s->black_level;
  double *p = g_new (double, count);
  if (!(s->edge_blur_px > 0)) {
    for (guint i = 0; i < count; i++)
      p[i] = b + (1.0 - b) * pattern_at (s, (double) x0 + i, shift);
    return p;
  }
  /* The illuminator's pattern goes on beyond the frame: blur the analytic pattern evaluated on
   * a margin, not a frame padded by reflection. */
  int rad = (int) ceil (4 * s->edge_blur_px);
  guint n_ext = count + 2u * (guint) rad;
  g_autofree double *ext = g_new (double, n_ext);
  g_autofree double *w = g_new (double, 2 * rad + 1);
  double norm = 0;
  for (int d = -rad; d <= rad; d++)
    norm += w[d + rad] = exp (-0.5 * d * d / (s->edge_blur_px * s->edge_blur_px));
  for (guint i = 0; i < n_ext; i++)
    ext[i] = pattern_at (s, (double) x0 + (double) i - rad, shift);
  for (guint x = 0; x < count; x++) {
    double acc = 0;
    for (int d = -rad; d <= rad; d++)
      acc += w[d + rad] * ext[(int) x + rad + d];
    p[x] = b + (1.0 - b) * acc / norm;
  }
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
  g_autofree double *profile =
    a->full ? NULL : ds_stage_pattern_profile (&d->spec, a->phase, a->n_phases, -(int) m, l->incident->width);
  double flux = d->photons_per_px_per_ms * a->exposure_us / 1000.0;
  for (guint y = 0; y < l->incident->height; y++) {
    float *in = ds_image_row (l->incident, y);
    for (guint x = 0; x < l->incident->width; x++)
      in[x] = (float) (flux * (profile ? profile[x] : 1.0));
  }
  for (guint y = 0; y < l->direct->height; y++)
    memcpy (ds_image_row (l->direct, y), (float *) ds_image_row (l->incident, y + m) + m,
            l->direct->width * sizeof (float));
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
