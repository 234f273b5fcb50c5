/* Scattered light the mean shows and the stripes keep at the coarsest pilot period, which the
 * transfer fit left in the direct light (docs/accuracy.md, "Automatic operating point": scattered
 * light that keeps the stripes in thin forward-scattering media).
 *
 * The first harmonic at a period Q, after the calibrated blur, is A(Q) = Ld + S T(Q), S the
 * scattered light and T its kernel's MTF at 1/Q, 0 <= T <= 1 and rising with Q; the mean holds
 * M = Ld + S. With the fit's Ld, the mean's scattered light is Lg = M - Ld and the coarsest period
 * Q_c keeps K = A(Q_c) - Ld of it. Where K is most of Lg the kernel is narrow against Q_c, and
 * since T rises with the period the leak at P is at most K / Ld: the fit's leak at P can be
 * anything from 0 to that, and where the fit read much less (no kernel seen at the finer periods,
 * the first harmonic at P pulled down by objects' column profile, a fit can read no leak where K
 * holds most of Lg) the prediction is a lower bound whose
 * upper end takes the leak at K / Ld at every harmonic and period. Only where Lg is significant:
 * at least DS_PROBE_HIDDEN_Z standard uncertainties (Ld's at P, and what objects put between the
 * harmonics and the mean, DS_PROBE_PAIR_SCATTER) above zero; a clear scene reads Lg within them.
 *
 * What this cannot see: a kernel narrow against every period the pilot draws keeps the stripes at
 * all of them, so Ld absorbs it, Lg holds only S (1 - T) and K nothing (a kernel of about 1 px
 * loses only a few % of S even at P/2, a few tenths of a % of Ld, below the first harmonics'
 * noise and what the blur's uncertainty moves them by).
 *
 * Internal to the scene probe; pure function, any thread. */
#pragma once
#include <glib.h>

#include "daemon/operating/scene_probe_transfer.h"

/* How many standard uncertainties the mean's scattered light must stand above zero. */
#define DS_PROBE_HIDDEN_Z 2.0
/* The share of the mean's scattered light the coarsest period must keep (the kernel narrow
 * against it), and how far the light it keeps must exceed the fit's leak at P (the factor the
 * validation asks of a prediction). */
#define DS_PROBE_HIDDEN_KEPT 0.5
#define DS_PROBE_HIDDEN_FACTOR 1.5

typedef struct {
  gboolean suspect;          /* the fit left light the coarse period keeps in Ld: a lower bound */
  double lg, lg_sigma;       /* the mean's scattered light and its standard uncertainty, shares of Ld */
  double kept;               /* K / Ld */
  double coarse_px;          /* Q_c */
  double leak_fit;           /* the fit's leak at P */
  char note[300];
} DsProbeHiddenLight;

/* From the first harmonic at the coarsest period among eq, the fit's ld, the mean's total light
 * (DN), the share of Ld that Ld is known to at P (ds_probe_ld_uncertainty) and the fit's leak at P. */
void ds_probe_hidden_light (const DsProbeEquation *eq, guint n_eq, const DsStripeModel *g, double sigma, guint width,
                            double ld, double total, double ld_uncertainty, double leak_fit, DsProbeHiddenLight *out);
