/* The closed-form scene of the tests and benchmarks that need exact frames rather than physics:
 * the sequencer's scripted lab (tests/daemon/scripted_lab.h) and the rate benchmark's fake GigE
 * Vision camera (tests/bench/fake_rig.h). Square stripes of duty 1/2 and period period_px,
 * centred at x = (j + phase/N) P and sampled at pixel centres (the project's convention,
 * docs/estimators.md), so that half of each period's pixels are lit when P/N is a whole
 * number of pixels; Ld = 1000 DN of direct light over Lg = 600 DN of global light (Lg/2 in
 * every frame, in the half-lit convention) and a dark offset of 2 DN. Without noise,
 * max - min = Ld and 2 min = Lg + 2 offset at every pixel, which is what the tests assert. */
#pragma once

#include <glib.h>
#include <math.h>

#define STRIPE_SCENE_DIRECT_DN 1000.0
#define STRIPE_SCENE_GLOBAL_DN 600.0
#define STRIPE_SCENE_DARK_DN 2.0
/* What a dark-unsubtracted separation gives as scattered light: 2 min = Lg + 2 offset. */
#define STRIPE_SCENE_SCATTERED_DN (STRIPE_SCENE_GLOBAL_DN + 2 * STRIPE_SCENE_DARK_DN)

/* 1 where column x is lit by phase `phase` of n_phases, else 0. */
static inline double
stripe_scene_lit (guint x, int phase, guint n_phases, double period_px)
{
  double u = (x + 0.5) / period_px - (double) phase / n_phases;
  u -= floor (u + 0.5);
  return fabs (u) < 0.25 ? 1.0 : 0.0;
}

/* The sample at column x under phase `phase` of n_phases (DN, rounded as a camera would). */
static inline guint16
stripe_scene_value (guint x, int phase, guint n_phases, double period_px)
{
  return (guint16) lround (STRIPE_SCENE_DIRECT_DN * stripe_scene_lit (x, phase, n_phases, period_px)
                           + STRIPE_SCENE_GLOBAL_DN * 0.5 + STRIPE_SCENE_DARK_DN);
}
