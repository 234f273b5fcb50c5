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
 * pixels this reaches half a step or more. Rather than sum the series, the bend is measured on
 * the pattern itself, rendered noise-free as the camera records it, each pixel the mean of the
 * light over its width, with sharp edges, through the same measurement the check uses: the
 * projector's blur only lowers the harmonics above the first, so sharp edges bound what a frame
 * shows. (Point samples would bend far more, a step or several, as the edges jump from one
 * pixel centre to the next; no sensor records points. A fill factor well below one would bend
 * more than this bound.) */
#include "proc/phase_check.h"

#include <math.h>

#include "proc/stripe_phase.h"

/* Offsets tried within one step: where the edges fall against the pixel grid changes the bend. */
#define BEND_OFFSETS 8
/* One row of the pattern lit with phase phi (cycles), as the convention of proc/stripe_phase.h
 * puts it: stripes centred at x = (j + phi) P; each pixel the mean over its width (x the
 * centre) of the light: square stripes lit over duty P around each centre, exactly the pixel's
 * overlap with them; sine stripes (1 + cos (2 pi (x / P - phi))) / 2, whose mean over a pixel
 * is the cosine times sinc (1 / P). */
static void
render_row (float *row, guint width, gboolean square, double duty, double period, double phi)
{
  double sinc = sin (G_PI / period) / (G_PI / period);
  for (guint x = 0; x < width; x++) {
    if (!square) {
      row[x] = (float) (0.5 + 0.5 * sinc * cos (2.0 * G_PI * (x / period - phi)));
      continue;
    }
    double lo = x - 0.5, hi = x + 0.5, lit = 0;
    for (double j = floor (lo / period - phi) - 1; j <= ceil (hi / period - phi) + 1; j++) {
      double c = (j + phi) * period;
      lit += MAX (0.0, MIN (hi, c + duty * period / 2) - MAX (lo, c - duty * period / 2));
    }
    row[x] = (float) lit;
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
  for (guint o = 0; o < BEND_OFFSETS; o++) {
    double start = (double) o / (BEND_OFFSETS * n), prev = NAN;
    for (guint h = 0; h <= n; h++) {
      DsStripePhase sp;
      render_row (row, width, square, duty, period_px, start + (double) (h % n) / n);
      if (!ds_stripe_phase_measure (img, period_px, NULL, &sp, NULL))
        return 0.5 / n; /* nothing measurable: as large a bend as a step can hold */
      if (h > 0)
        worst = MAX (worst, fabs (ds_stripe_phase_diff (sp.phase - prev, 1.0 / n)));
      prev = sp.phase;
    }
  }
  return worst;
}
