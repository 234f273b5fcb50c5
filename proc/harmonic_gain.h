/* The stripe pattern's mean m and first-harmonic amplitude h, both including the black level,
 * in theory and measured on a non-scattering reference (docs/estimators.md).
 *
 * Pattern convention (the whole project's): stripes vary along x; phase k of N has
 * u = frac(x/P - k/N) wrapped to [-1/2, 1/2); square: lit where |u| < a/2; sine:
 * 0.5 (1 + cos 2 pi u); the value is b + (1 - b) * pattern.
 *
 * Pure functions, any thread, CPU only. */
#pragma once
#include <glib.h>

#include "proc/image.h"
#include "proc/separation.h"

G_BEGIN_DECLS

/* m: a + b (1 - a) for square stripes, b + (1 - b) / 2 for a 0..1 sinusoid (duty ignored). */
double ds_pattern_mean (DsPatternKind pattern, double duty, double black_level);

/* h: (1 - b) (2 / pi) sin (pi a) for sharp square stripes, (1 - b) / 2 for a 0..1 sinusoid.
 * Blurred edges lower it; an N-step DFT of a square pattern also aliases harmonics
 * n = jN +- 1 into it (a per-pixel ripple that averages out over a period). */
double ds_harmonic_gain_theory (DsPatternKind pattern, double duty, double black_level);

/* h as the N-step DFT sees sharp square stripes: when aN is an integer L, every pixel is lit
 * in exactly L phases (barring a pixel exactly on an edge) and the sampled gain is
 * (1 - b) 2 sin (pi L / N) / (N sin (pi / N)), exact at every pixel (N = 4, a = 1/2: 11 % above
 * the continuous value). Otherwise, and for sine stripes, ds_harmonic_gain_theory. */
double ds_harmonic_gain_sampled (DsPatternKind pattern, double duty, double black_level,
                                 guint n_phases);

/* h measured from a separation of a non-scattering reference (Lg = 0) made with the sine
 * estimator and keep_extrema: per pixel A = Ld * h_used and M = mean, so h = m * A / M;
 * returned as m * sum(A) / sum(M) over pixels with M > 0 and no mask bit but NEGATIVE (a
 * reference's Lg is about 0, so half of its pixels may come out slightly negative).
 * Fails (INVALID_ARGUMENT) when the separation is not sine with extrema, or (EMPTY) when no
 * pixel qualifies. */
gboolean ds_harmonic_gain_from_separation (const DsSeparation *reference, double *h_out,
                                           GError **error);

/* Convenience: separates the N frames (frame k lit with phase k, one frame per phase, optional
 * dark) of a non-scattering reference with the sine estimator and returns h as above.
 * pattern, duty, black_level describe the illuminator (they give m). */
gboolean ds_harmonic_gain_calibrate (const DsImage *const *frames, guint n_phases,
                                     const DsImage *dark, DsPatternKind pattern, double duty,
                                     double black_level, double *h_out, GError **error);

G_END_DECLS
