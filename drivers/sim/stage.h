/* Renderer stages (internal to drivers/sim): one file per stage, stage_<name>.c. A stage is
 * built only when the scene calls for it; it holds immutable data and works on a DsLight. */
#pragma once
#include <glib.h>

#include "drivers/sim/renderer.h"
#include "drivers/sim/scene.h"
#include "drivers/sim/sensor.h"
#include "drivers/sim/transport.h"
#include "proc/image.h"

G_BEGIN_DECLS

/* The object planes at one frame's time, made by the motion stage (stage_motion.c) for the
 * objects and scattering stages: only planes holding a moving object are new. */
typedef struct {
  double time_s;
  DsSceneSpec spec;             /* the scene's, with `objects` displaced to time_s (for the shapes
                                 * beyond the maps' margin) */
  DsSceneObject *objects;       /* owned array; names and paths borrowed from the scene */
  DsImage *map[DS_SCENE_MAX_DEPTHS + 2]; /* per objects-stage plane, frame + margin; NULL: that
                                          * plane is still, the objects stage's own map holds */
  DsImage *direct;              /* frame: the product of every plane's map at time_s */
} DsMovedObjects;

void ds_moved_objects_free (DsMovedObjects *moved);

/* Photons per pixel in one exposure, split by how they reach the lens. The scene goes on beyond
 * the field of view: `incident` covers the frame plus `margin` pixels on either side (what the
 * scattering kernels reach), so light scattered in from outside the frame is there. */
typedef struct {
  guint margin;
  DsImage *incident;  /* arriving at the medium's entry face (pattern x irradiance), f32, one row of
                       * width + 2 margin: it varies along x only */
  DsImage *direct;    /* ballistic light reaching the lens, f32 */
  DsImage *scattered; /* scattered light reaching the lens inside its acceptance cone, f32 */
  double ambient;     /* pattern-independent photons per pixel, uniform */
  DsImage *frame;     /* the sensor's output (sensor stage) */
  DsMovedObjects *moved; /* the motion stage's planes at args->time_s, or NULL (no motion) */
} DsLight;

typedef struct {
  guint phase, n_phases;
  gboolean illuminator_on;
  gboolean full;      /* truth: the pattern's "on" level everywhere */
  gboolean expected;  /* sensor: noise-free expectation (f32 DN) instead of a noisy u16 frame */
  double exposure_us, gain_db;
  guint64 seed;
  double period_px;   /* 0: the scene's */
  double time_s;      /* the frame's time (its exposure's midpoint): where moving objects are */
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
typedef enum { DS_OBJECTS_ALL, DS_OBJECTS_STILL, DS_OBJECTS_MOVING } DsObjectSelect;
/* The transmittance map of the selected objects at one depth (frame + margin on every side),
 * each shape displaced by its (dx, dy), area-sampled 4 x 4 per pixel; masks are clear beyond
 * their image. */
DsImage *ds_stage_objects_map_at_depth (const DsSceneSpec *s, double depth, guint margin, DsObjectSelect select,
                                        GError **error);
/* One plane per distinct object depth, shallowest first. margin: each plane's map covers the
 * frame plus margin pixels on every side (shapes go on; masks are clear outside their image). */
DsStage *ds_stage_objects_new (const DsSceneSpec *s, guint margin, GError **error);
guint ds_stage_objects_n_planes (const DsStage *objects);
/* The distinct object depths strictly inside the medium, shallowest first. */
void ds_stage_objects_interior_depths (const DsSceneSpec *s, DsSlabPlanes *planes);
double ds_stage_objects_plane_depth (const DsStage *objects, guint plane);
/* The transmittance map of one plane, with the margin given at construction. */
const DsImage *ds_stage_objects_plane_map (const DsStage *objects, guint plane);
/* Block means of a plane's map over f x f blocks aligned on the frame, with block_margin blocks
 * around it: from the map where it reaches, from the shapes at pixel centres beyond. */
DsImage *ds_stage_objects_coarse_map (const DsSceneSpec *s, const DsStage *objects, guint plane, guint f,
                                      guint block_margin, GError **error);
/* As ds_stage_objects_coarse_map from a given fine map (frame + margin) of the objects at depth. */
DsImage *ds_stage_objects_coarse_map_of (const DsSceneSpec *s, const DsImage *fine, double depth, guint f,
                                         guint block_margin, GError **error);
/* Built when an object declares a velocity: renders the planes holding moving objects at each
 * frame's time into DsLight.moved, reusing the still objects' maps made here once. Runs before
 * the objects stage; objects: that stage (borrowed, outlives this one). */
DsStage *ds_stage_motion_new (const DsSceneSpec *s, const DsStage *objects, GError **error);
/* objects: the objects stage or NULL; kernels: copied from, their planes the interior planes
 * of the objects stage (docs/scene-format.md, "Objects inside the medium"). */
DsStage *ds_stage_scattering_new (const DsSceneSpec *s, const DsStage *objects, const DsSlabKernels *kernels,
                                  const char *how, GError **error);
/* How far beyond the frame the scene must be rendered for these kernels: the incident row, and
 * the object planes' maps (the scattering stage makes coarser maps farther out itself). */
void ds_stage_scattering_margins (const DsSceneSpec *s, const DsSlabKernels *kernels, guint *incident_margin,
                                  guint *map_margin);
/* What the stage was built with, for describe. */
void ds_stage_scattering_info (const DsStage *scattering, guint *radius_px, guint *margin_px, double *held,
                               double *scattered_in_cone, double *se, double *mtf, double *mtf_noise);
DsStage *ds_stage_ambient_new (double photons_per_px_per_ms);
DsStage *ds_stage_sensor_new (const DsSensorModel *m);
/* Folds scattered light and ambient into l->direct: the photons the sensor sees. */
void ds_stage_sensor_photons (DsLight *l);

G_END_DECLS
