/* Does a calibration reference scatter? (issue 12, "Calibration"). The calibration reads the
 * black level b as the off-stripe light over the lit light of each pixel; light scattered by the
 * reference lands off the stripes too and is read as black level (and lowers the harmonic gain).
 * The two differ in how they vary across the reference: a black level is the same fraction of
 * every pixel's lit level; scattered light comes from around the pixel, so it is a larger
 * fraction where the reference is dark (behind an absorbing line, a grid, an edge) than where it
 * is bright. The check compares that fraction on the dimmest and brightest third of the pixels,
 * brightness taken relative to the surroundings (a box of about two periods) so that vignetting
 * and illumination fall-off, which scattered light follows as well, do not count.
 * Second, the shape of the period profile: scattered light that keeps the stripes reaches into
 * the dark stripes with long tails that no blurred square edge has, so a blurred square with a
 * black level does not fit it (square stripes only: a blurred sine is a sine).
 * A featureless slab whose scattered light keeps no stripes shows neither: it is not caught
 * (the result says whether the reference had the detail to tell).
 * Pure function, any thread; CPU only (two passes over the plane). */
#pragma once
#include <glib.h>

G_BEGIN_DECLS

typedef struct {
  gboolean scattering;        /* spatial or shape_misfit */
  gboolean measured;          /* the reference had the detail to tell (brightness_contrast >= 1.5,
                                 or a difference seen at >= 1.1) */
  gboolean spatial;           /* the off-stripe fraction grows where the reference is dark */
  double off_dim, off_bright; /* median off-stripe fraction of the dimmest and brightest third */
  double brightness_contrast; /* their relative brightness's ratio, >= 1 (0: too few pixels) */
  gboolean shape_misfit;      /* shape_residual well above what a clear reference leaves */
  double shape_residual;      /* rms residual of the profile fit over the profile's range */
  double shape_noise;         /* the profile's standard error over its range */
} DsScatterCheck;

/* brightness: the pixel's mean over the phases (NaN or <= 0 where not usable); off: its
 * off-stripe over lit level (NaN where not usable); width x height planes. */
void ds_calibration_scatter_check (const double *brightness, const double *off, guint width, guint height,
                                   double period_px, DsScatterCheck *out);
/* Whether a model fits a period profile as closely as a clear reference's must: rms residual
 * (over the profile's range) <= max(0.5 %, 5 x the profile's noise). */
gboolean ds_calibration_shape_fits (double residual, double noise);
/* Sets shape_misfit (and scattering) from shape_residual and shape_noise. */
void ds_calibration_scatter_shape (DsScatterCheck *check);

G_END_DECLS
