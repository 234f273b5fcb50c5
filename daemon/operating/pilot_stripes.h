/* Do the pilot frames of an automatic capture show stripes at the configured period at all?
 * (docs/accuracy.md, "Automatic operating point"). Without them there is no direct light to
 * separate and nothing for the pattern check, the probe or the error model to measure: a duty
 * read off a flat profile, or an error predicted from a ramp's rounding, would be refused as
 * the wrong request ("best reachable 42.5") when the scene (or the rig) is what is wrong.
 *
 * The stripes are the difference of phases 0 and 1/2, rows averaged into a column profile
 * (the scene cancels, the stripes double; clipped samples left out): its first harmonic at the
 * configured period must stand DS_PILOT_MIN_SNR standard errors of the profile's fit clear of
 * zero (what the probe needs to use a harmonic at all, scene_probe_transfer.c), and one frame's share of it be at least DS_PILOT_MIN_MODULATION of the lit
 * frames' mean level. The floor is where no operating point separates anything: shot noise of
 * a full well of 100 000 electrons is 3.2e-3 of the mean per frame; averaged over the largest
 * set (64 phases x 64 frames) it leaves a first harmonic's standard error of 7e-5 of the mean,
 * 0.7 of a modulation of 1e-4 in every pixel. A frame source whose picture changes by itself
 * (Aravis's fake camera: a ramp moving one pixel per frame) shows a first harmonic of a few
 * 1e-5 of the mean at any period, noise-free and so "significant" by the first test alone.
 * Pure function, any thread; CPU only (one pass over the two frames). */
#pragma once
#include <glib.h>

#include "daemon/operating/scene_probe.h"

G_BEGIN_DECLS

#define DS_PILOT_MIN_SNR 4.0
#define DS_PILOT_MIN_MODULATION 1e-4

typedef struct {
  double amplitude;   /* first harmonic of the phase difference's column profile, DN */
  double sigma;       /* its standard error from the profile's fit, DN */
  double mean_dn;     /* the lit frames' mean level, DN (dark not subtracted) */
  double light_dn;    /* the same less the dark frame's mean: the illuminator's light */
} DsPilotStripes;

/* TRUE when the stripes are there; FALSE with DS_OPERATING_ERROR_NO_STRIPES ("no stripes at the
 * configured period ...", naming what was measured) when not; with DS_OPERATING_ERROR_CLIPPED
 * (naming the clip level and the remedy) when the pair clips by the probe's rule
 * (ds_probe_pair_check_clipping ()) or its clipped samples leave the fit no columns; or with the
 * error of ds_probe_frames_check. */
gboolean ds_pilot_stripes_check (const DsProbeFrames *frames, DsPilotStripes *out, GError **error);

G_END_DECLS
