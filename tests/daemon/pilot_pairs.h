/* Closed-form pilot frames probed as descatterd probes them (the scene probe's tests): a dark
 * frame, then phases 0 and 1/2 at P (shifts 0.1 and 0.6 of a period), at 2P (0.2, 0.7) and at the
 * finer periods the blur resolves (0.3, 0.8), drawn in that order by the test's own frame function
 * from one random generator. */
#pragma once
#include "daemon/operating/scene_probe.h"

G_BEGIN_DECLS

typedef DsImage *(*PilotFrameFunc) (gconstpointer scene, double period, double shift, gboolean on, GRand *r);

/* base: the geometry (its period is P), blur, open field and the rest the test wants; its frames
 * are filled here. Probes into *p, aborting the test on any error; returns the number of finer
 * periods (ds_scene_probe_finer_periods at blur_px). */
guint pilot_pairs_probe (PilotFrameFunc frame, gconstpointer scene, const DsProbeFrames *base, double blur_px,
                         guint32 seed, DsSceneProbe *p);

G_END_DECLS
