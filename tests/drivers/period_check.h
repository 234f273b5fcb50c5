/* Does an illuminator project the stripe period it was asked for? Measured in the frames a
 * camera takes of it, with proc/stripe_phase.h only (the daemon's phase measurement), never from
 * what the devices report. Shared by the tests of labsim, the simulated devices and the
 * third-party controller (issue 12: a period register for projectors that can change it). */
#pragma once
#include "drivers/core/camera.h"
#include "drivers/core/illuminator.h"
#include "proc/stripe_phase.h"

/* The stripe period of a frame (rows of region, NULL: the whole frame), from the frame alone:
 * the period whose first harmonic is strongest among 2.5 px .. a third of the width (steps of
 * 0.2 %), refined by the drift of the phase measured at it between the region's halves (a
 * period p measured at p' drifts by x (1/p' - 1/p) cycles over x pixels). 0 when no period
 * stands out (snr below DS_STRIPE_PHASE_MIN_SNR). */
double period_check_measure (const DsImage *frame, const DsRegion *region);

/* set_pattern(pattern), then phases 0 .. N-1, one frame each (camera started, software
 * trigger): every frame's measured period is pattern->period_px within rel_tol, and phase k
 * lies k/N of a period from phase 0 (within half a phase step). Fails the test otherwise. */
void period_check_frames (DsIlluminator *ill, DsCamera *cam, const DsStripePattern *pattern, const DsRegion *region,
                          double rel_tol);
