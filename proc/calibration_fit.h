/* The calibrator's models of the period profile (calibration.h): the phase profile of the lit
 * pixels binned by where a pixel sits in the period, bin j holding the mean over its pixels of
 * V_k / mean_k V (the pixel's own brightness divides out), fitted by a blurred square with a
 * black level (Nelder-Mead over duty, black level and edge blur) and by a pure sinusoid (closed
 * form). Private to proc/calibration*.c. Pure functions, any thread; CPU only. */
#pragma once
#include <glib.h>

#include "proc/separation.h"

G_BEGIN_DECLS

#define DS_CALIBRATION_BINS 48u

typedef struct {
  DsSeparationParams p;       /* pattern, period, aperture; duty, b, blur are the unknowns */
  guint n;
  const double *profile;      /* DS_CALIBRATION_BINS x n */
  const double *profile_sq;   /* the same of the squares, for the profile's noise */
  const guint *filled;        /* pixels per bin */
  const double *position;     /* mean position of the bin's pixels in the period, [0, 1) */
  double offset;              /* cycles */
} DsCalibrationFit;

/* The blurred square with a black level fitted from the starting duty a0 and level b0:
 * x = (a, b, sigma). */
void ds_calibration_fit_square (DsCalibrationFit *f, double a0, double b0, double x[3]);

/* How well the square model at x explains the profile: its rms residual and the profile's
 * standard error, both over the profile's range (0 when the profile is flat). */
void ds_calibration_fit_residual (const DsCalibrationFit *f, const double x[3], double *residual, double *noise);

/* A pure sinusoid's rms misfit over the profile's range: the profile (mean 1 per bin) against
 * 1 + c cos(2 pi (position - phase)), c by least squares, whatever the black level, blur or
 * pixel aperture that set c. */
double ds_calibration_fit_sine_residual (const DsCalibrationFit *f);

G_END_DECLS
