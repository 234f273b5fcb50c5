/* Sine stripes' black level and harmonic gain, told apart (calibration.h). A sine illuminator
 * draws b + (1 - b) (1 + cos)/2; blur and the pixel's aperture multiply its first harmonic by
 * g(P) <= 1 and leave its mean alone, so a reference shows the contrast (harmonic over mean)
 *     c(P) = k g(P),   k = (1 - b) / (1 + b).
 * One period cannot tell b from g: the sinusoid's shape is the same. Two can: every blur that
 * is symmetric (the projector's defocus, the pixel's box of variance w^2/12) lowers the first
 * harmonic as exp (-2 pi^2 s^2 / P^2) to second order in 1/P (exactly so for a Gaussian), so
 *     ln c(P) = ln k - alpha / P^2,   alpha = 2 pi^2 s^2,
 * and two periods give k (the contrast at zero frequency: the illuminator's own) and s, in
 * closed form. The harmonic gain the sine estimator needs at P is then h = m c(P), m = (1 + b)/2,
 * and the gain at another period P' follows as g(P') = g(P)^((P/P')^2).
 * Pure functions, any thread. */
#pragma once
#include <glib.h>

G_BEGIN_DECLS

typedef struct {
  double black_level;   /* b, in [0, 1) (a k above 1, from noise, reads as 0) */
  double blur_px;       /* s: the whole symmetric blur as one Gaussian sigma, pixel included */
} DsSineLevels;

/* From the contrasts c1, c2 in (0, 1] at periods p1 != p2 (px). Fails (FALSE) when the periods
 * are too close to tell apart (a ratio under 1.25) or a contrast is not in (0, 1]. A longer
 * period showing less contrast (noise, or a reference that scatters) is read as no blur. */
gboolean ds_sine_levels_from_contrasts (double p1, double c1, double p2, double c2, DsSineLevels *out);

/* The first-harmonic factor g at period p_to, given g at p_from (closed form above). */
double ds_sine_gain_at_period (double g_from, double p_from, double p_to);

G_END_DECLS
