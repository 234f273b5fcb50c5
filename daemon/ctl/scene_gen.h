/* Random scenes for validating the automatic operating point on cases nobody tuned for
 * (docs/accuracy.md, "Validation"): medium, thickness, stripe pattern, period, duty, black
 * level, edge blur, objects, ambient light and sensor are drawn from wide ranges; the exposure is
 * then set from a render so that the brightest pixels sit at a drawn fraction of the clip level
 * (a tenth of the scenes above it: they clip). Output: scene files in the format of
 * docs/scene-format.md.
 *
 * Versions: a seed means the scenes of one version of the draw. Version 1 (seeds 1 to 24 of the
 * records) is kept as it was; version 2 (the default) widens it: periods from 2.5 px, square
 * duty 0.2 to 0.8, black levels to 0.4, thin forward-peaked films, objects at the entry and exit
 * faces, 8- to 16-bit sensors, and regimes where the sine or the square estimators win. Every
 * version 2 scene's estimated render cost is within a quarter of its [scene] max-render-s.
 *
 * Deterministic: the same version, seed and index give the same text on any machine. Renders
 * (Monte Carlo kernels, cached on disk): seconds per scene. One thread at a time. */
#pragma once
#include <glib.h>

G_BEGIN_DECLS

#define DS_SCENE_GENERATOR_OLDEST 1
#define DS_SCENE_GENERATOR_LATEST 2

/* The drawn scene before its exposure is set (exposure-us 1000, irradiance 1): cheap, no
 * render. *clip_fraction (may be NULL) receives where the brightest pixels are to sit, as a
 * fraction of the clip level. An unknown version is an error naming the versions there are. */
char *ds_scene_draw (guint64 seed, guint index, guint version, double *clip_fraction, GError **error);

/* The scene text for (seed, index) of generator `version`, its exposure set from a render; name
 * goes into its [scene] group. */
char *ds_scene_generate (guint64 seed, guint index, guint version, GError **error);

G_END_DECLS
