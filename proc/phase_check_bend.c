/* The projected pattern's own bend of the measured phase step (proc/phase_check.h,
 * ds_phase_check_pattern_bend).
 *
 * The check measures a frame's first harmonic at the stripe period on pixels. A sine pattern
 * has no other harmonic, and its measured phase advances by exactly 1/N per phase. A square
 * pattern's harmonic j lies at j/P cycles per pixel; sampled on pixels it folds to
 * j/P - round (j/P), and where that lands on +-1/P (j = +-1 mod p for P = p/q: at 3 px the
 * second, fourth, fifth...) it joins the first harmonic while moving j times as fast, or
 * backwards. The measured phase then advances unevenly, by up to about asin (r) either way,
 * r the folded harmonics' amplitude against the first's; near whole-number periods of a few
 * pixels this reaches a step or more. Rather than sum the series, the bend is measured on the
 * pattern itself, rendered noise-free as the camera would see it with sharp edges, through the
 * same measurement the check uses: blur and a wider pixel aperture only lower the harmonics
 * above the first, so sharp edges bound what a real frame shows (point samples and pixel-wide
 * samples are both tried, the larger taken). */
#include "proc/phase_check.h"

#include <math.h>

#include "proc/stripe_phase.h"

/* Offsets tried within one step: where the edges fall against the pixel grid changes the bend. */
#define BEND_OFFSETS 8
/* Sub-samples per pixel for the pixel-wide aperture. */
#define BEND_SUBSAMPLES 8

/* One row of the pattern lit with phase phi (cycles), as the convention of proc/stripe_phase.h
 * puts it: stripes centred at x = j P + phi P, lit where |u| < duty / 2 (square) or
 * (1 + cos (2 pi u)) / 2 (sine). aperture: 0 point samples at the pixel centres, 1 the mean over
 * the pixel's width. */
static void
render_row (float *row, guint width, gboolean square, double duty, double period, double phi, gboolean aperture)
{
  guint subs = aperture ? BEND_SUBSAMPLES : 1;
  for (guint x = 0; x < width; x++) {
    double sum = 0;
    for (guint s = 0; s < subs; s++) {
      double pos = aperture ? x - 0.5 + (s + 0.5) / subs : x;
      double u = pos / period - phi;
      u -= floor (u + 0.5);
      sum += square ? (fabs (u) < duty / 2 ? 1.0 : 0.0) : 0.5 * (1.0 + cos (2.0 * G_PI * u));
    }
    row[x] = (float) (sum / subs);
  }
}

double
ds_phase_check_pattern_bend (gboolean square, double duty, double period_px, guint width, guint n)
{
  if (n < 2 || width < 2 || !(period_px >= 2.0) || (square && !(duty > 0 && duty < 1)))
    return 0.0;
  g_autoptr (DsImage) img = ds_image_new (DS_SAMPLE_F32, width, 1, NULL);
  if (!img)
    return 0.0;
  float *row = (float *) ds_image_row (img, 0);
  double worst = 0;
  for (int aperture = 0; aperture <= 1; aperture++)
    for (guint o = 0; o < BEND_OFFSETS; o++) {
      double start = (double) o / (BEND_OFFSETS * n), prev = NAN;
      for (guint h = 0; h <= n; h++) {
        DsStripePhase sp;
        render_row (row, width, square, duty, period_px, start + (double) (h % n) / n, aperture);
        if (!ds_stripe_phase_measure (img, period_px, NULL, &sp, NULL))
          return 0.5 / n; /* nothing measurable: as large a bend as a step can hold */
        if (h > 0)
          worst = MAX (worst, fabs (ds_stripe_phase_diff (sp.phase - prev, 1.0 / n)));
        prev = sp.phase;
      }
    }
  return worst;
}
