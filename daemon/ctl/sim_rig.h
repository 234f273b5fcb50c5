/* A rig emulated over the scene simulator, for the offline study and the validation of the
 * automatic operating point: frames as the camera would take them, the same scene at another
 * stripe period (an illuminator that can change it), the clear reference a user calibrates on,
 * the truth, and the separation of one configuration as descatterd would compute it.
 *
 * A rig of its own beside drivers/simdev: the study asks for a frame at a given phase, exposure
 * and noise seed, with the truth and the clear reference beside it and no trigger or device
 * timing between; simdev is the pair of devices that descatterd --sim drives through its
 * sequencer, one triggered frame at a time.
 *
 * Threads: a rig is used by one thread at a time. */
#pragma once
#include <glib.h>

#include "drivers/sim/renderer.h"
#include "drivers/sim/scene.h"
#include "proc/separation.h"

G_BEGIN_DECLS

typedef struct DsSimRig DsSimRig;

/* The scene file's text is kept, so that variants can be made from it. */
DsSimRig *ds_sim_rig_new (const char *scene_path, GError **error);
DsSimRig *ds_sim_rig_new_from_data (const char *text, const char *name, GError **error);
void ds_sim_rig_free (DsSimRig *rig);
G_DEFINE_AUTOPTR_CLEANUP_FUNC (DsSimRig, ds_sim_rig_free)

/* The same scene with the stripe period changed (the illuminator's PERIOD register). */
DsSimRig *ds_sim_rig_with_period (const DsSimRig *rig, double period_px, GError **error);
/* The same scene with its objects moving at speed_px_s along +x, across the stripes (velocity =
 * speed, 0 on every object but masks, which cannot move; or on the object named `object` only,
 * failing when there is none). speed 0 makes every object still. */
DsSimRig *ds_sim_rig_with_speed (const DsSimRig *rig, double speed_px_s, const char *object, GError **error);
/* The clear reference of a calibration: the same illuminator, camera and sensor, no medium,
 * no objects, no ambient light. */
DsSimRig *ds_sim_rig_reference (const DsSimRig *rig, GError **error);

const DsScene *ds_sim_rig_scene (const DsSimRig *rig);
const DsRenderer *ds_sim_rig_renderer (const DsSimRig *rig);
const char *ds_sim_rig_name (const DsSimRig *rig);   /* file name, or the name given */
const char *ds_sim_rig_text (const DsSimRig *rig);
/* The level at and above which a sample is clipped (DN): the sensor's full well or the ADC's
 * top, whichever is lower. */
double ds_sim_rig_clip_dn (const DsSimRig *rig);

/* One frame (u16, the sensor's bit depth): phase k of n, or the illuminator off. */
DsImage *ds_sim_rig_frame (const DsSimRig *rig, guint phase, guint n_phases, gboolean on,
                           double exposure_us, guint64 seed, GError **error);
/* The same at time_s (s, its exposure's midpoint): where moving objects are. */
DsImage *ds_sim_rig_frame_at (const DsSimRig *rig, guint phase, guint n_phases, gboolean on,
                              double exposure_us, guint64 seed, double time_s, GError **error);

/* Renders one set (M dark frames averaged, then M frames per phase) and folds it into one phase
 * set per parameter block (one render for all of them); seps[i] receives each result.
 * noise_free: the frames' expectation instead (f32, clipped at the clip level), for the
 * systematic part of the error. compute_us (may be NULL) receives each set's fold+finalize time. */
gboolean ds_sim_rig_separate (const DsSimRig *rig, const DsSeparationParams *params, guint n_params,
                              guint averages, double exposure_us, guint64 seed, gboolean noise_free,
                              DsSeparation **seps, double *compute_us, GError **error);
/* As ds_sim_rig_separate with frame j of phase k taken at frame_time_s[k * averages + j] (s):
 * a scene with moving objects meets them where they are at each frame. The noise-free set then
 * averages the M expected frames of each phase as the noisy set does. NULL: every frame at 0. */
gboolean ds_sim_rig_separate_at (const DsSimRig *rig, const DsSeparationParams *params, guint n_params,
                                 guint averages, double exposure_us, guint64 seed, gboolean noise_free,
                                 const double *frame_time_s, DsSeparation **seps, double *compute_us,
                                 GError **error);

G_END_DECLS
