/* Renderer stages (internal to drivers/sim): one file per stage, stage_<name>.c. A stage is
 * built only when the scene calls for it; it holds immutable data and works on a DsLight. */
#pragma once
#include <glib.h>

#include "drivers/sim/renderer.h"
#include "drivers/sim/scene.h"
#include "drivers/sim/sensor.h"
#include "proc/image.h"

G_BEGIN_DECLS

/* Photons per pixel in one exposure, split by how they reach the lens. The scene goes on beyond
 * the field of view: `incident` covers the frame plus `margin` pixels on every side (the
 * scattering kernel's radius), so light scattered in from outside the frame is there. */
typedef struct {
  guint margin;
  DsImage *incident;  /* arriving at the medium's entry face (pattern x irradiance), f32, with margin;
                       * varies along x only (the scattering stage relies on it) */
  DsImage *direct;    /* ballistic light reaching the lens, f32 */
  DsImage *scattered; /* scattered light reaching the lens inside its acceptance cone, f32 */
  double ambient;     /* pattern-independent photons per pixel, uniform */
  DsImage *frame;     /* the sensor's output (sensor stage) */
} DsLight;

typedef struct {
  guint phase, n_phases;
  gboolean illuminator_on;
  gboolean full;      /* truth: the pattern's "on" level everywhere */
  gboolean expected;  /* sensor: noise-free expectation (f32 DN) instead of a noisy u16 frame */
  double exposure_us, gain_db;
  guint64 seed;
} DsStageArgs;

typedef struct DsStage DsStage;
struct DsStage {
  DsRenderStage kind;
  char *reason;
  gboolean (*apply) (const DsStage *stage, DsLight *light, const DsStageArgs *args, GError **error);
  gpointer data;
  GDestroyNotify free_data;
};

void ds_stage_free (DsStage *stage);
G_DEFINE_AUTOPTR_CLEANUP_FUNC (DsStage, ds_stage_free)

DsStage *ds_stage_pattern_new (const DsSceneSpec *s, double object_pitch_mm);
/* The pattern at pixels x0 .. x0 + count - 1: blurred (edge-blur-px) on the medium, then integrated
 * over each pixel (square) or taken at its centre (sine); values in [b, 1]. */
double *ds_stage_pattern_profile (const DsSceneSpec *s, guint phase, guint n_phases, int x0, guint count);
DsStage *ds_stage_boundary_new (double n_outside, double n_medium);
double ds_stage_boundary_normal_reflectance (double n1, double n2);
DsStage *ds_stage_ballistic_new (double sigma_t, double thickness_mm);
/* margin: the map covers the frame plus margin pixels on every side (shapes go on; masks are
 * clear outside their image). */
DsStage *ds_stage_objects_new (const DsSceneSpec *s, guint margin, GError **error);
/* The transmittance map, with the margin given at construction. */
const DsImage *ds_stage_objects_map (const DsStage *objects);
/* objects: the objects stage or NULL. Kernels copied; see ds_renderer_new_with_kernels. */
DsStage *ds_stage_scattering_new (const DsSceneSpec *s, const DsStage *objects, const DsImage *psf_full,
                                  const DsImage *psf_before, const DsImage *psf_after, const char *how,
                                  GError **error);
/* The margin the kernels need around the frame (their largest radius). */
guint ds_stage_scattering_margin (const DsImage *psf_full, const DsImage *psf_before, const DsImage *psf_after);
DsStage *ds_stage_ambient_new (double photons_per_px_per_ms);
DsStage *ds_stage_sensor_new (const DsSensorModel *m);
/* Folds scattered light and ambient into l->direct: the photons the sensor sees. */
void ds_stage_sensor_photons (DsLight *l);

G_END_DECLS
