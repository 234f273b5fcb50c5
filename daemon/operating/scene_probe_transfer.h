/* The scene probe's harmonic transfer fit across periods (scene_probe.h: the model
 * A_n(Q) = Ld G_n(Q, sigma) exp(alpha Q / n), the narrow kernel's term, the interval of Ld and
 * why): the equations the pilot pairs' harmonics give, the weighted line through log (A / G) with
 * the blur's error as a parameter, the narrow kernel's grid search, and the checks of the fit.
 * Internal to the scene probe: scene_probe.c is the only user. Pure functions, any thread;
 * CPU only. */
#pragma once
#include <glib.h>

#include "daemon/operating/cone_kernel.h"
#include "daemon/operating/scene_probe.h"
#include "daemon/operating/stripe_model.h"

/* At most this many equations (harmonics over all periods) enter one fit. */
#define DS_PROBE_MAX_EQUATIONS 16

/* One harmonic of the difference of two opposite phases at period Q. */
typedef struct {
  double period;
  guint n;
  double amplitude, sigma;
  double offset;             /* phase of the first harmonic at this period (cycles) */
} DsProbeEquation;

typedef struct {
  double log_ld, alpha, residual;
} DsProbeSolution;

typedef struct {
  DsProbeSolution s;
  double beta, width, shape;
} DsProbeNarrowFit;

/* What the interval of Ld needs from the harmonics, before the places that clip are counted
 * back (the ratio of the lower end to the fit's Ld carries over to the scene). */
typedef struct {
  gboolean computed, unbounded;
  double ratio;              /* interval.ld_lower / the fit's Ld */
  double kernel_px;
  char note[360];
} DsProbeDirectInterval;

double ds_probe_kernel_mtf (double b, double nu, double x);

double ds_probe_model_gain (const DsStripeModel *g, double period, double sigma, double offset, guint width,
                            guint n);

double ds_probe_gain_shift (const DsStripeModel *g, const DsProbeEquation *e, double sigma, double G, guint width);

/* Appends the usable odd harmonics of one pair's fit at period to eq[n_eq..]; the new count. */
guint ds_probe_collect_equations (const DsStripeHarmonics *fit, double period, const DsStripeModel *g, guint width,
                                  DsProbeEquation *eq, guint n_eq);

DsProbeSolution ds_probe_solve_at (const DsStripeModel *g, const DsProbeEquation *eq, guint n_eq, double sigma,
                                   guint width, gboolean two_periods, gboolean blur_uncertain);

gboolean ds_probe_fit_narrow (const DsStripeModel *g, const DsProbeEquation *eq, guint n_eq, double sigma, guint width,
                              double period, const DsProbeSolution *line, DsProbeNarrowFit *out);

/* The acceptance cone's kernel (cone_kernel.h) over all the equations, total the light the mean
 * shows, in place of the line (Ld ld_line) where the line cannot follow it: the harmonics see a
 * kernel radius between the fit's two limits (cone_kernel.h: DS_CONE_SEEN_CHI2), the kernel keeps
 * at least half its stripes at P (narrow against the period: a wider one is the small-angle line's
 * regime, where the line reads the leak right, e.g. tissue-veins), and it reads more of the light
 * as scattered than the line's extrapolation, which removes only the slope between the periods of
 * a transfer that has saturated. FALSE (the line stays) otherwise; *out holds the fit either way. */
gboolean ds_probe_fit_cone (const DsStripeModel *g, const DsProbeEquation *eq, guint n_eq, double sigma, guint width,
                            double total, double ld_line, DsConeFit *out);

double ds_probe_ld_uncertainty (const DsProbeEquation *eq, guint n_eq, const DsStripeModel *g, double sigma,
                                guint width);

void ds_probe_direct_interval (const DsProbeEquation *eq, guint n_eq, const DsStripeModel *g, double sigma,
                               guint width, double ld_fit, double total, DsProbeDirectInterval *out);

void ds_probe_fit_consistency (double chi2, guint n_eq, guint n_par, DsSceneProbe *out);
