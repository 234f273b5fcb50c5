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
 * Pure function of the frames; any thread; CPU only (a few passes over the frames). */
#pragma once
#include <glib.h>

#include "daemon/operating/stripe_model.h"
#include "proc/image.h"

G_BEGIN_DECLS

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
