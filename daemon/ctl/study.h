/* The accuracy-versus-time study (docs/accuracy.md): sweeps estimator, phases N, averages M,
 * exposure, stripe period and noise seed over simulated scenes, measuring the error of both
 * images against the simulator's truth, split into a systematic part (the same configuration on
 * noise-free frames) and a noise part, and the acquisition time from a timing model of the rig. */
#pragma once
#include <glib.h>

#include "daemon/operating/rig_timing.h"
#include "proc/separation.h"

G_BEGIN_DECLS

typedef struct {
  const char *scene;         /* file name */
  DsEstimator estimator;
  guint phases, averages;
  double period_px;
  double exposure_factor, exposure_us;
  guint64 seed;
  double rel_rmse_transmissive, rel_rmse_scattered;
  /* The same configuration on noise-free frames (clipped at the sensor's clip level): what no
   * number of frames removes. The noise part is sqrt(total^2 - systematic^2) (0 when noise's
   * bias cancels part of the systematic error). */
  double systematic_transmissive, systematic_scattered;
  double stripe_residue;     /* first-harmonic amplitude / mean left in transmissive */
  guint64 valid, masked, saturated;
  double signal_dn;          /* mean Ld + Lg of the truth at this exposure */
  double direct_fraction;    /* mean Ld / mean (Ld + Lg) */
  double acquisition_ms;     /* model */
  double compute_ms;         /* measured: accumulate + finalize */
  /* The set knew the scene's edge blur, as descatterd does with [illuminator] edge-blur-px
   * (robust's margin from the period and the blur). FALSE where the sampling precondition
   * refuses the configuration with the blur known: the point is then what descatterd does
   * without edge-blur-px (the period alone, the blur taken as sharp, robust's one-phase
   * margin). */
  gboolean edge_blur_known;
  /* How fast the scene's objects move (px/s; 0: a still scene). A moving scene's frames are
   * taken at their times in the rig's timing model and its error is against the truth at the
   * set's middle, so motion during the set counts against longer sets. */
  double speed_px_s;
  /* "ok"; "cannot-separate": the set left no pixel to score (every one clipped, not finite or
   * undersampled), its errors NAN; "refused": proc refuses the configuration on this scene (the
   * sampling precondition at this period, an estimator's N), nothing run. reason says why
   * ("" when ok); it lives until emit returns. */
  const char *status;
  const char *reason;
} DsStudyPoint;

typedef struct {
  guint *phases; guint n_phases;
  guint *averages; guint n_averages;
  double *exposure_factors; guint n_exposures;
  double *periods; guint n_periods;  /* stripe periods: > 0 px, 0 the scene's own, < 0 that many
                                        times the scene's own (-2: twice); one equal to the
                                        scene's own is run once */
  guint n_seeds;
  DsEstimator *estimators; guint n_estimators;
  DsRigTiming timing;
  gboolean dark_frame;
  const char *examples_dir;  /* NULL: none; else 8-bit previews of both components for the
                                smallest and largest N at M = 1, base exposure, first seed, the
                                scene's own period, first speed */
  double *speeds; guint n_speeds; /* px/s along +x (across the stripes) given to the scene's
                                     objects (ds_sim_rig_with_speed); none: as the scene declares */
  const char *moving_object;      /* NULL: every object but masks; else this [object.NAME] only */
} DsStudyPlan;

typedef void (*DsStudyPointFunc) (const DsStudyPoint *point, gpointer user_data);

/* Runs the plan on one scene file; every point goes to `emit` as it is measured, and each
 * configuration that cannot separate the scene as a point with its status and reason (the sweep
 * goes on). Frames are rendered once per (speed, period, N, M, exposure, seed) and folded into
 * one phase set per estimator; the noise-free frames once per (speed, period, N, exposure), and
 * per M as well when the scene moves (each frame then has its own time). */
gboolean ds_study_run_scene (const char *scene_path, const DsStudyPlan *plan,
                             DsStudyPointFunc emit, gpointer user_data, GError **error);

G_END_DECLS
