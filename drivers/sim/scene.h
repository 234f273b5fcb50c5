/* Scene files (docs/scene-format.md): what the simulated lab looks like. A GKeyFile checked
 * against one table of keys; errors name the file, line, group, key and allowed range.
 * A loaded scene is immutable: any thread may read it. */
#pragma once
#include <glib.h>

#include "drivers/sim/sim_error.h"

G_BEGIN_DECLS

/* Distinct object depths strictly inside the medium (the faces do not count): the slab is split
 * at each. Depths closer than the tolerance are one plane. */
#define DS_SCENE_MAX_DEPTHS 8
#define DS_SCENE_DEPTH_TOLERANCE_MM 1e-9

typedef enum { DS_SHAPE_RECT, DS_SHAPE_DISC, DS_SHAPE_GRID, DS_SHAPE_LINES, DS_SHAPE_MASK } DsShape;

typedef struct {
  char *name;
  DsShape shape;
  double x, y;                /* rect: top-left corner; disc: centre (px) */
  double width, height;       /* rect size (px) */
  double radius;              /* disc (px) */
  double pitch, line_width;   /* grid / lines (px); lines run along y, wavy if amplitude > 0 */
  double amplitude;           /* lines: lateral waviness (px), vein-like */
  char *mask_path;            /* mask: absolute path (resolved against the scene file) */
  double depth_mm;            /* inside the medium, 0..thickness */
  double transmittance;       /* 0 opaque .. 1 clear */
  double vx, vy;              /* velocity on the sensor (px/s); 0, 0: the object stands still */
  double dx, dy;              /* displacement rendered (px): 0 as loaded; v t in the copy the motion
                               * stage makes for a frame at time t */
} DsSceneObject;

typedef struct {
  /* [sensor] (EMVA 1288 terms) */
  guint width, height, bit_depth;
  double pixel_pitch_um;
  double quantum_efficiency, system_gain, read_noise_e, dark_current_e_s, full_well_e;
  double exposure_us;             /* the scene's base exposure */
  /* [illuminator] */
  gboolean sine;
  double period_px, duty, black_level, edge_blur_px;
  double irradiance;              /* photons / um^2 / ms on the medium's entry face, "on" level */
  double wavelength_nm;
  /* [medium] (optional) */
  gboolean has_medium;
  double thickness_mm, mua, mus, g, n_medium;
  gboolean diffusion;             /* model = diffusion (else monte-carlo) */
  guint64 photons, mc_seed;
  /* [camera] */
  double magnification, acceptance_half_angle_deg;
  /* [ambient] (optional) */
  gboolean has_ambient;
  double ambient_level;           /* photons / um^2 / ms (object side), pattern-independent */
  /* [object.*] */
  DsSceneObject *objects;
  guint n_objects;
  /* [scene] max-render-s: the render cost (render_cost.h) beyond which the scene is refused */
  double max_render_s;
  char *name;
  char *path;
} DsSceneSpec;

typedef struct DsScene DsScene;

DsScene *ds_scene_load (const char *path, GError **error);
/* name is used in messages and to resolve relative mask paths (its folder). */
DsScene *ds_scene_load_data (const char *data, gsize length, const char *name, GError **error);
/* The files a scene names, as the renderer will open them: every mask must read as an image
 * of the sensor's size. Fails DS_SIM_ERROR_IO or _INVALID naming the object and file. Reads
 * (and decodes) each mask once; main thread of whoever validates the scene. */
gboolean ds_scene_check_files (const DsScene *scene, GError **error);
DsScene *ds_scene_copy (const DsScene *scene);
/* A copy at another sensor size, object geometry scaled with it, stripe period kept (benchmarks). */
DsScene *ds_scene_copy_resized (const DsScene *scene, guint width, guint height);
void ds_scene_free (DsScene *scene);
G_DEFINE_AUTOPTR_CLEANUP_FUNC (DsScene, ds_scene_free)

const DsSceneSpec *ds_scene_spec (const DsScene *scene);
guint ds_scene_width (const DsScene *scene);
guint ds_scene_height (const DsScene *scene);
guint ds_scene_bit_depth (const DsScene *scene);
double ds_scene_period_px (const DsScene *scene);
double ds_scene_duty (const DsScene *scene);
double ds_scene_black_level (const DsScene *scene);
gboolean ds_scene_pattern_is_sine (const DsScene *scene);
double ds_scene_edge_blur_px (const DsScene *scene);   /* the projector's Gaussian sigma on the sensor */
/* The width of a pixel that sees the pattern, px, as the renderer draws it (stage_pattern.c): sine
 * stripes are taken at the pixel's centre (0), square stripes integrated over the whole pixel (1). */
double ds_scene_pattern_aperture_px (const DsScene *scene);
double ds_scene_system_gain (const DsScene *scene);   /* DN per electron */
double ds_scene_read_noise_dn (const DsScene *scene);
double ds_scene_default_exposure_us (const DsScene *scene);
/* Whether an object declares a velocity other than 0, 0: only then is anything rendered per
 * frame time (docs/scene-format.md, "Motion"). */
gboolean ds_scene_object_moves (const DsSceneObject *object);
gboolean ds_scene_has_motion (const DsScene *scene);
/* Side of one pixel projected into the object (mm): sensor pitch / magnification. */
double ds_scene_object_pitch_mm (const DsScene *scene);
/* The open field a calibration on the scene's clear reference measures (no medium, objects or
 * ambient light: the illuminator, lens and sensor alone): a fully lit pixel's level above dark, DN
 * per ms of exposure at 0 dB gain (docs/scene-format.md: photons per pixel per ms, times the
 * quantum efficiency and the system gain). */
double ds_scene_open_field_dn_per_ms (const DsScene *scene);

G_END_DECLS
