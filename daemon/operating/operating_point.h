/* Automatic operating point: picks estimator, phases N, averages M and exposure for a target
 * error and/or a time budget, from what the pilot frames say about the scene (scene_probe.h)
 * and the predicted error of every candidate (error_model.h): noise part plus systematic part,
 * on the scene in front of the camera, with no parameter fitted to any study scene
 * (docs/accuracy.md, "Automatic operating point").
 *
 * The operating model file (etc/operating-model.conf, written by `descatterctl validate --fit`)
 * holds the candidates searched and the scale predictions are multiplied by: 1 unless fitted
 * (leave-one-scene-out on the shipped scenes, docs/accuracy.md).
 * Pure functions, any thread (the error model is per thread). */
#pragma once
#include <glib.h>
#include <json-glib/json-glib.h>

#include "daemon/operating/error_model.h"
#include "daemon/operating/rig_timing.h"
#include "daemon/operating/scene_probe.h"
#include "proc/separation.h"

G_BEGIN_DECLS

#define DS_OPERATING_MAX_CANDIDATES 16

typedef struct DsOperatingModel {
  double scale;                /* predictions x this, [0.5, 2] */
  /* How far a prediction on a scene the scale was not fitted on is off by the model alone: the
   * RMS of log (achieved / predicted) over the fitted scenes, each predicted with the scale fitted
   * without it (leave one scene out). 0: not measured (a built-in or older model). [0, 1] */
  double scale_spread;
  guint phases[DS_OPERATING_MAX_CANDIDATES];
  guint n_phases;
  guint averages[DS_OPERATING_MAX_CANDIDATES];
  guint n_averages;
  double exposure_factors[DS_OPERATING_MAX_CANDIDATES];  /* of the pilot's exposure */
  guint n_exposure_factors;
  char fitted_on[256];         /* what the scale was fitted on (documentation) */
} DsOperatingModel;

/* The built-in candidates and a scale of 1. */
void ds_operating_model_init (DsOperatingModel *model);
/* A GKeyFile, group [operating-model]: scale, phases, averages, exposure-factors, fitted-on
 * (keys left out keep the built-in values). Errors name the file and the key. Free with
 * ds_operating_model_free. */
DsOperatingModel *ds_operating_model_load (const char *path, GError **error);
void ds_operating_model_free (DsOperatingModel *model);
G_DEFINE_AUTOPTR_CLEANUP_FUNC (DsOperatingModel, ds_operating_model_free)
gboolean ds_operating_model_write (const DsOperatingModel *model, const char *path, GError **error);

typedef struct {
  DsEstimator estimator;
  guint phases, averages;
  double exposure_us;
  double period_px;            /* the stripe period the prediction is for */
  double predicted_error;      /* relative RMSE of transmissive, x the model's scale: the lower end */
  double predicted_error_upper; /* the upper end, with Ld at the lower end of the probe's interval
                                   (ds_scene_probe_worst_case); INFINITY when the pilot cannot bound it;
                                   predicted_error when there is no interval. Targets are met on it */
  DsErrorParts parts;          /* its parts, without the scale */
  double predicted_time_ms;
  gboolean lower_bound;        /* the scattered stripes could not be measured, or no period finer than P
                                  was on a scene that scatters: the error may be larger */
  gboolean upper_bounded;      /* the pilot bounds the error from above: predicted_error_upper is that
                                  bound. FALSE for a lower bound without an interval (the target is then
                                  decided on predicted_error) and where the interval has no lower end of Ld */
  /* The prediction's relative standard uncertainty (of its logarithm): the model's scale_spread and
   * what the probe knows about its own measurements (ds_operating_point_uncertainty) */
  double uncertainty;
  /* Chosen on the margin: no candidate is predicted to meet the target, but it lies within the
   * uncertainty of the most accurate one's prediction, which is run; target_note says so */
  gboolean target_may_be_missed;
  /* No point's upper end meets the target and this one's lower end does (within its uncertainty):
   * whether the target is met is undetermined (docs/accuracy.md, "What is measured, what is
   * assumed"); the point is run with target_may_be_missed and the interval in target_note */
  gboolean undetermined;
  char target_note[2048];
  /* A declared speed's motion term (daemon/operating/motion_term.h), in quadrature in
   * predicted_error and predicted_error_upper: NAN when no speed was declared or the estimator's
   * motion error has no model. predicted_error_still is the prediction without it, motion_span_ms
   * the time from the first frame's exposure to the last's, over which the object moves. */
  double motion_term;
  double predicted_error_still;
  double motion_span_ms;
  /* Why motion made the point a lower bound (a static string), NULL when it did not */
  const char *motion_why;
} DsOperatingPoint;

/* The relative standard uncertainty of a prediction with these parts at this period (px; 0: the
 * probe's) on this probe's scene: the model's scale_spread, Ld's uncertainty
 * (probe->light.ld_uncertainty) on the parts relative to Ld (the noise, and the scattered stripes,
 * whose leak L at the period the pilot measures as part of the modulated light Ld (1 + L), so that
 * they move by (1 + L)/L times Ld's relative error, and at most vanish where L is smaller than its
 * own uncertainty), and the sampling error of the frame noise's estimate, added in quadrature
 * (docs/accuracy.md, "Decisions on the margin"). Any thread; never fails. */
double ds_operating_point_uncertainty (const DsOperatingModel *model, const DsSceneProbe *probe,
                                       const DsErrorParts *parts, double period_px);

/* The longest exposure (µs) that keeps the probe's brightest pixels (99.9th percentile) below
 * 90 % of its clip level; when that level is only the pixel format's top (not configured, no
 * pile-up in the pilot frames), at most the pilot's exposure: a full well below the format's top
 * clips unflagged and unseen at longer ones. */
double ds_scene_probe_max_exposure (const DsSceneProbe *probe);

/* target_error <= 0: no target; time_budget_ms <= 0: no budget. With a target: the fastest
 * candidate meeting it within the budget; with only a budget: the most accurate within it. Where
 * the prediction is an interval (the probe's direct light, scene_probe.h; a term the error model
 * cannot measure, error_model.h), a candidate meets a target only with the upper end of its
 * prediction, and "most accurate" is by the upper end first.
 * No candidate within the budget meets the target, but the most accurate one's lower end divided
 * by exp (its uncertainty) does: whether the target is met is undetermined; the fastest candidate
 * whose lower end meets the target (else that most accurate one) is chosen, target_may_be_missed
 * and undetermined set and target_note says why, with the intervals.
 * Neither possible (even the lower end is above the target): UNREACHABLE with the best reachable error and what would reach the
 * target (a larger budget, a finer stripe period, a longer exposure), each with its prediction;
 * *out is then the best reachable point (predicted_error INFINITY when none fits the budget). */
gboolean ds_operating_point_choose (const DsOperatingModel *model, DsErrorModel *errors,
                                    const DsSceneProbe *probe, const DsRigTiming *timing,
                                    guint width, guint height, double target_error,
                                    double time_budget_ms, DsOperatingPoint *out, GError **error);

/* A speed declared for the choice (docs/accuracy.md, "Moving objects"): every candidate's
 * prediction gets its motion term (ds_motion_apply). */
typedef struct DsMotionTable DsMotionTable;
typedef struct {
  double speed_px_s;        /* px/s along x (the stripes' normal); NAN: none declared, a still scene */
  DsMotionTable *table;     /* the scene's direct image as the pilot saw it (ds_motion_table_new) */
} DsOperatingMotion;

/* ds_operating_point_choose with a declared speed (motion NULL, or its speed NAN: the same). With
 * a speed, the candidates are the estimators whose motion error has a model (maxmin, sine). */
gboolean ds_operating_point_choose_moving (const DsOperatingModel *model, DsErrorModel *errors,
                                           const DsSceneProbe *probe, const DsRigTiming *timing,
                                           guint width, guint height, double target_error,
                                           double time_budget_ms, const DsOperatingMotion *motion,
                                           DsOperatingPoint *out, GError **error);

/* What an automatic capture records about its choice (result metadata,
 * `settings.operating_point`, docs/protocol.md). */
typedef struct {
  double target_error, time_budget_ms;
  gboolean speed_declared;     /* FALSE: a still scene was assumed */
  double speed_px_s;           /* the declared speed, px/s along x */
  /* What the set's motion bit said (ds_capture_settings_note_motion): whether it was judged and
   * on how many pixels */
  gboolean motion_checked;
  guint64 motion_pixels;
  DsOperatingPoint point;
  double scale;
  DsSceneProbe probe;
  guint pilot_frames;
  double pilot_ms;
  /* The pattern check's assumption (daemon/operating/pattern_check.h: off-stripe light the
   * scene cannot tell from a black level, taken as scattered light): its message, "" when the
   * frames needed none. Listed in `assumptions`. */
  char pattern_assumption[640];
} DsOperatingReport;

/* Adds the report's members to the object being built: the request, the choice, the predicted
 * error with the parts it contains and why it is a lower bound when it is one, and what the
 * pilot frames measured. */
void ds_operating_report_to_json (const DsOperatingReport *report, JsonBuilder *builder);

G_END_DECLS
