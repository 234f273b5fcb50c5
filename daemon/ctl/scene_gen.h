/* Random scenes for validating the automatic operating point on cases nobody tuned for
 * (docs/accuracy.md, "Validation"): medium (none, thin to dense, isotropic to strongly
 * forward-peaked), thickness, stripe pattern, period, duty, black level, edge blur, objects,
 * ambient light and sensor are drawn from wide ranges; the exposure is then set from a render
 * so that the brightest pixels sit at a drawn fraction of the clip level (a tenth of the scenes
 * above it: they clip). Output: scene files in the format of docs/scene-format.md.
 *
 * Deterministic: the same seed and index give the same text on any machine. Renders (Monte
 * Carlo kernels, cached on disk): seconds per scene. One thread at a time. */
#pragma once
#include <glib.h>

G_BEGIN_DECLS

/* The scene text for (seed, index); name goes into its [scene] group. */
char *ds_scene_generate (guint64 seed, guint index, GError **error);

G_END_DECLS
