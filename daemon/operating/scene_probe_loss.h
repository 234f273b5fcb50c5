/* The light the scene loses against the open field (docs/accuracy.md, "Automatic operating point":
 * light lost against the open field).
 *
 * A clear path delivers the open field's lit level L0 (descatterctl calibrate on a clear reference,
 * [illuminator] open-field-dn-per-ms, or what a simulated illuminator and camera give on one). The
 * scene's lit level L, the same quantity on the pilot frames, gives the transmittance into the
 * lens's acceptance cone T = L / L0. Two faces of a medium of index n reflect part of the light;
 * without absorption they pass (1 - R) / (1 + R), R = ((n - 1) / (n + 1))^2 at normal incidence,
 * 0.899 for n = DS_PROBE_LOSS_MAX_INDEX: a loss beyond that, the noise and the calibration's
 * uncertainty is light the medium absorbs or scatters out of the cone. Where the stripes keep
 * (nearly) all the light that reaches the camera (the probe's scattered light under
 * DS_PROBE_LOSS_SEEN_LG of the direct light), such a loss means a medium that scatters without
 * the pilot seeing it: a forward-peaked medium sends most of its scattered light out of the cone,
 * and the rest into the cone within a pixel of its path, which keeps the stripes at every period a
 * sensor resolves and passes for direct light in every harmonic. Nothing in the frames bounds that
 * light without the cone's angle and the medium's phase function, so the prediction is then a
 * lower bound; where the lens's acceptance angle is known, single scattering with a bounded
 * anisotropy gives it an upper end (film_bound.h), none otherwise. Absorption alone loses light the same way: the flag says the
 * prediction may be optimistic, not that it is.
 *
 * Objects (opaque or partial) and their shadows only darken pixels, so L is a bright quantile
 * (DS_LIT_LEVEL_QUANTILE) of the pixels' lit level, each pixel's two opposite phases over the sum
 * the pattern model gives there, less the lift the noise gives a quantile: as long as more than
 * 1 - DS_LIT_LEVEL_QUANTILE of the scene is free of objects, the quantile is a pixel the light
 * crossed alone (a mean would read a grid of opaque lines as loss). descatterctl calibrate takes
 * the open field with the same quantile of the reference's pixels, so that an uneven illumination
 * lifts both alike.
 *
 * Internal to the scene probe; pure function, any thread. */
#pragma once
#include <glib.h>

#include "daemon/operating/scene_probe.h"
#include "proc/lit_level.h"

/* The highest refractive index the Fresnel loss allows for (most films, plastics and glasses). */
#define DS_PROBE_LOSS_MAX_INDEX 1.6
/* How well the open field is known as a share of it: the calibration's noise and the illuminator's
 * drift between the calibration and the scene. */
#define DS_PROBE_LOSS_CALIBRATION 0.03
/* How many standard uncertainties the loss must stand beyond the Fresnel loss. */
#define DS_PROBE_LOSS_Z 2.0
/* Below this share of the direct light the probe's scattered light counts as none seen. */
#define DS_PROBE_LOSS_SEEN_LG 0.05
/* The standard normal quantile at DS_LIT_LEVEL_QUANTILE: how far the noise lifts it. */
#define DS_PROBE_LOSS_QUANTILE_Z 0.8416
/* The fewest lit, unclipped pixels measured, and the most (rows are skipped beyond). */
#define DS_PROBE_LOSS_MIN_PIXELS 256u
#define DS_PROBE_LOSS_MAX_SAMPLES 1000000u

/* The transmittance of two faces of index n without absorption, multiple reflections included. */
double ds_probe_fresnel_transmittance (double n);

/* From the pilot frames and the probe's noise, clip and light (measured before): fills out->loss. */
void ds_probe_loss_measure (const DsProbeFrames *frames, DsSceneProbe *out);
