/* What the pilot frames of an automatic capture say about the scene in front of the camera:
 * how much direct light there is and how it varies, how much scattered light, how noisy a frame
 * is, how blurred the stripes arrive, and how much of the scattered light keeps the stripes
 * (docs/accuracy.md, "Automatic operating point").
 *
 * Pilot frames: a dark frame, and at the configured period P the phases 0 and 1/2 (a two-phase
 * separation); where the illuminator can change its period, the same at 2P. The difference of
 * two opposite phases holds the odd harmonics of the pattern times the light that keeps it;
 * its column profile gives their amplitudes, its mean square how Ld varies across the scene.
 *
 * The model of a harmonic n at period Q (frame mean, first order in the leak):
 *     A_n(Q) = Ld G_n(Q, sigma) exp(alpha Q / n)
 * G_n is the sampled gain of the blurred, pixel-integrated pattern (stripe_model.h), exp(alpha Q/n)
 * the transfer of the pattern by the medium relative to the ballistic light alone: forward
 * scattering at small angles spreads light by a distance that grows with depth, and in the
 * small-angle limit of a Henyey-Greenstein medium the transfer of frequency f is
 * exp(sigma_s integral_0^d exp(-c f (d - z)) dz) ~ exp(sigma_s / (c f)) for c f d >> 1, so the
 * logarithm of the apparent Ld grows linearly in the period: two periods give Ld (the
 * extrapolation to period 0) and alpha.
 *
 * G_n is only as good as the blur it is computed with, and a harmonic the blur has nearly
 * erased moves by tens of % when the blur is off by a few hundredths of a pixel: all of them
 * the same way, which a line through log (A / G) would read as a transfer rising with Q / n,
 * i.e. as scattered stripes. So the blur's error is a third parameter of the fit (how far log
 * G_n moves for DS_PROBE_BLUR_UNCERTAINTY_PX, with a unit normal prior), and the first harmonic
 * at 2P, the least blur-sensitive point after the one at P, stays in the fit unless the
 * harmonics below P over-determine it (tests/daemon/test_error_model.c
 * /error-model/probe-blurred-harmonics; against the simulator's kernels:
 * tests/daemon/test_probe_sim.c).
 *
 * What no pair of periods can see: scattered light whose kernel is narrow against both periods
 * keeps the stripes at both, so it is counted as direct light (Ld too high, the scattered stripes
 * too low by as much); docs/accuracy.md, "Automatic operating point".
 *
 * Pure function of the frames; any thread; CPU only (a few passes over the frames). */
#pragma once
#include <glib.h>

#include "daemon/operating/stripe_model.h"
#include "proc/image.h"

G_BEGIN_DECLS

/* How well a calibrated or fitted stripe blur is known (Gaussian sigma, px): the harmonics whose
 * gain this moves by more than a few % weigh little in the scattered stripes' fit. */
#define DS_PROBE_BLUR_UNCERTAINTY_PX 0.05

typedef enum {
  DS_BLUR_CALIBRATED = 0,   /* from the calibrated harmonic gain */
  DS_BLUR_MEASURED,         /* fitted to the pilot's harmonics at two periods */
  DS_BLUR_ASSUMED_SHARP,    /* neither possible: sigma 0, the sampling part is a lower bound */
} DsBlurSource;

const char *ds_blur_source_name (DsBlurSource source);

typedef struct {
  const DsImage *dark;            /* illuminator off, the pilot's exposure */
  const DsImage *lit[2];          /* period P: phase 0 and phase 1/2 */
  const DsImage *coarse[2];       /* period 2P: phase 0 and 1/2; NULL when not available */
  const char *coarse_missing;     /* why not (shown with the lower bound) */
  double exposure_us;
  double saturation_dn;           /* the ADC's top or a known clip level; 0 = none */
  gboolean saturation_known;      /* saturation_dn is the sensor's real clip level (configured);
                                     FALSE: only the pixel format's top, a full well may be lower */
  DsStripeModel geometry;      /* as configured; blur_px is what the probe finds */
  double calibrated_gain;         /* h measured on a reference (descatterctl calibrate); 0 = none */
  gboolean blur_known;            /* calibrated_blur_px holds a calibrated edge blur */
  double calibrated_blur_px;      /* Gaussian sigma (descatterctl calibrate); wins over the gain's */
} DsProbeFrames;

/* The frames' shape, as both the probe and the pattern check need it: a dark frame and the pair
 * at P, the pair at 2P whole or absent, all of one size and sample type. Fails with
 * DS_PROTOCOL_ERROR_BAD_ARGUMENT naming the frame that is missing or differs. Any thread. */
gboolean ds_probe_frames_check (const DsProbeFrames *frames, GError **error);

typedef struct {
  DsStripeModel geometry;      /* with the blur found */
  DsBlurSource blur_source;
  double phase_offset;            /* cycles: phase 0's stripes are centred at x = P (j + offset) */
  double exposure_us;
  double ld_mean;                 /* direct light Ld (DN at exposure_us), mean over unclipped pixels */
  double ld_spread;               /* mean (Ld^2) / mean (Ld)^2, >= 1 */
  double lg_mean;                 /* scattered light Lg (full illumination), DN */
  double leak_per_px;             /* alpha (1/px); 0 when not measured */
  gboolean leak_measured;
  char leak_note[200];            /* how it was measured, or why not */
  double noise_var0;              /* DN^2 of one frame without signal (read, dark, quantisation) */
  double noise_gain;              /* DN^2 per DN of signal (shot noise) */
  double dark_dn;
  double saturation_dn;           /* the clip level applied: given, or a pile-up found lower */
  gboolean clip_known;            /* saturation_dn is known to be where the sensor clips (given as
                                     known, or a pile-up found): exposures may rise up to it.
                                     FALSE: a full well below the format's top would go unseen,
                                     so no exposure above the pilot's is safe */
  gboolean clip_flagged;          /* the separation flags samples at saturation_dn (it is the level
                                     given, not a full well the pilot found below it) */
  double bright_dn;               /* 99.9th percentile of the brighter pilot frame minus dark */
  double saturated_fraction;      /* pixels at the clip level in a pilot frame */
  guint width, height;
  guint equations;                /* harmonics the fit used */
  double fit_rms;                 /* rms of the fit's residuals in log amplitude */
} DsSceneProbe;

gboolean ds_scene_probe_measure (const DsProbeFrames *frames, DsSceneProbe *out, GError **error);

/* The transfer exp(alpha Q / n) - 1 of harmonic n at period Q: the part of the apparent Ld that
 * is scattered light keeping the stripes. */
double ds_scene_probe_leak (const DsSceneProbe *probe, double period_px, guint n);

G_END_DECLS
