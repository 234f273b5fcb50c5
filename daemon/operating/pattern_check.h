/* Does the configured stripe pattern match what the camera sees? A check of the automatic
 * operating point's pilot frames (docs/accuracy.md, "Automatic operating point"), so that a
 * duty or black level left at its default is reported as such and not blamed on scattering.
 *
 * Per pixel, r = (L0 - D) / (L0 + L1 - 2 D) of the two opposite phases L0, L1 and the dark
 * frame D: the pixel's own brightness divides out, and so does any light that does not keep
 * the stripes, except that it raises the off-stripe level. Binned by the position in the
 * period, r is fitted by the pattern (stripe_model.h) with a duty a, an apparent off-stripe
 * level b' and an edge blur sigma:
 *     r = (b' + (1 - b') s(x)) / (2 b' + (1 - b') (s(x) + s(x - P/2))),  b' = (b + g) / (1 + g)
 * g the light that does not keep the stripes relative to the direct light. So:
 * - the duty is read from where the stripes overlap or leave gaps, which scattered light does
 *   not move: a fitted duty far from the configured one is a wrong configuration;
 * - b' is at least the black level: b' well below the configured b is a wrong configuration
 *   when the pixels nearest the stripe centres show it too (each pixel's off fraction is at
 *   least b whatever blurs or scatters its light; the fit's shape is not where an opaque object
 *   leaves some pixels only light scattered in from their sides);
 *   b' well above it is either a black level left unconfigured or scattered light. A black
 *   level is a fixed fraction of each pixel's lit level; scattered light comes from around the
 *   pixel, so it is a larger fraction where an object in front of the medium darkens the scene
 *   (one behind it darkens the scattered light with the direct). With a calibrated black level
 *   (the harmonic gain calibrate measured with it) the excess is scattered light; without one,
 *   dim and bright pixels showing the same off-stripe fraction are refused as a black level
 *   left unconfigured, and when the scene has too little contrast to tell, the light is taken
 *   as scattered; descatterd's log and the result's operating_point.assumptions name that
 *   assumption.
 * The duty is compared with what the configured pattern, rendered through the same blur, pixel,
 * phases and noise, reads by the same fit, within that reading's spread: a few pixels wide, the
 * fit's duty trades against its blur and level.
 * Where the illuminator can change its period, the pair at 2P is checked as well (stripes twice
 * as wide are less blurred, so the duty is read better there).
 * The level is read from the troughs, which the blur and the pixel keep by g1, the first
 * harmonic's factor: its tolerance is LEVEL_TOLERANCE / g1 at each pair's period. A pair with
 * more than a few % of its pixels clipped (the format's top, or a pile-up below it where a full
 * well is reached first: proc/clip_level.h) has lost its bright stripe centres and is not judged.
 *
 * Pure function, any thread; CPU only (one pass over each pair of frames). */
#pragma once
#include <glib.h>

#include "daemon/operating/scene_probe.h"
#include "daemon/operating/stripe_model.h"
#include "proc/image.h"

G_BEGIN_DECLS

typedef enum {
  DS_PATTERN_MATCHES = 0,        /* the frames agree with the configuration */
  DS_PATTERN_OFF_LEVEL_ASSUMED,  /* more off-stripe light than the black level, taken as scattered
                                    light: the scene cannot tell it from a black level */
  DS_PATTERN_WRONG_DUTY,         /* the frames show another duty */
  DS_PATTERN_WRONG_BLACK_LEVEL,  /* the frames show another black level */
} DsPatternVerdict;

/* What one pair of opposite phases shows. */
typedef struct {
  gboolean measured;             /* FALSE: too few lit pixels, no stripes at this period, or more
                                    than a few % of the pixels clipped */
  double period_px;
  double duty, off_level, blur_px; /* the fit: a, b', sigma */
  double fit_rms;                /* rms of r about the fit */
  double configured_rms;         /* rms of r about the best fit with the configured a and b' >= b */
  double expected_duty;          /* the duty the fit reads on the configured pattern seen through the
                                    same blur, pixels, phases and noise (square; else configured) */
  double duty_tolerance;         /* how far duty may be from expected_duty: the readings' spread
                                    plus what the model leaves out (pattern_check.c); the frames'
                                    own spread is read only where duty is further than the model's
                                    part, else the replicas' stands for it */
  double level_tolerance;        /* how far b' may fall below b: LEVEL_TOLERANCE / g1 (pattern_check.c) */
  double mean_position;          /* the kernel-free reading (square): where the profile's mean lies
                                    between its trough and its peak; NaN where not read */
  double mean_position_lo, mean_position_hi; /* what any kernel wider than the edge blur leaves it
                                    at on the configured pattern, widened by its spread */
  double centre_off;             /* median off-stripe fraction of the pixels nearest the stripe centres
                                    (no model: each is at least the black level); NaN: too few */
  double clipped_share;          /* pixels with a sample at the clip level (or a pile-up below it) */
  guint64 pixels;
} DsPatternPair;

typedef struct {
  DsPatternVerdict verdict;
  DsPatternPair pair[2];         /* [0] at P, [1] at 2P */
  double duty;                   /* what the frames show (2P when measured there) */
  double off_level;              /* b', the lower of P and 2P (blur only raises it) */
  double off_dim, off_bright;    /* b' of the dimmest and brightest third of the stripe centres */
  double brightness_ratio;       /* their lit levels' ratio (>= 1); 0 when not measured */
  char message[640];             /* for a verdict other than MATCHES: what was configured, what the
                                    frames show and what to do */
} DsPatternCheck;

/* The probe's pilot frames: dark, lit and coarse, saturation_dn (samples at or above are left
 * out; 0 = none) and geometry (kind, period, duty and black level as configured); the rest is
 * not read. Fails only where ds_probe_frames_check does (BAD_ARGUMENT); a scene that shows too
 * little to check gives MATCHES with pair[0].measured FALSE. */
gboolean ds_pattern_check (const DsProbeFrames *frames, DsPatternCheck *out, GError **error);

const char *ds_pattern_verdict_name (DsPatternVerdict verdict);

G_END_DECLS
