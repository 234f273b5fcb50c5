/* Validation of the automatic operating point on simulated scenes (docs/accuracy.md): the
 * pilot frames a rig would take, the probe and prediction made from them exactly as descatterd
 * makes them (daemon/operating), and the error the chosen configuration actually achieves
 * against the simulator's truth.
 *
 * Threads: one thread at a time per rig. */
#pragma once
#include <glib.h>

#include "daemon/ctl/sim_rig.h"
#include "daemon/operating/error_model.h"
#include "daemon/operating/operating_point.h"
#include "daemon/operating/scene_probe.h"
#include "proc/calibration.h"

G_BEGIN_DECLS

typedef struct {
  gboolean calibrated;     /* the rig was calibrated on the clear reference: h known */
  gboolean simulated;      /* (calibrated FALSE) the rig knows its pattern as descatterd --sim
                              does: the noise-free calibration of the scene's illuminator
                              (daemon/operating/pattern_knowledge.h) */
  gboolean fixed_period;   /* the illuminator cannot change its period: no second period */
  gboolean saturation_known; /* the rig is configured with the sensor's clip level ([camera]
                                saturation-dn); otherwise it knows the pixel format's top only */
  guint64 seed;            /* noise seeds of every frame derive from it */
} DsValidateOptions;

typedef struct {
  DsSceneProbe probe;
  gboolean calibrated;     /* calibration holds what `descatterctl calibrate` measured, or the
                              simulated illuminator's record (options' simulated) */
  DsCalibration calibration;
  char second_period_note[320]; /* a sine's black level assumed: why no second period told it */
  double black_level;      /* configured: the scene's, or the calibration's measured at two periods */
  double harmonic_gain;    /* calibrated h given to the sine estimator, or 0 (its theory) */
  double open_field_dn_per_ms; /* the open field's lit level known to the rig (pattern_knowledge.h), or 0 */
  double acceptance_half_angle_deg; /* the lens's acceptance cone ([camera] acceptance-half-angle-deg) */
  gboolean edge_blur_known; /* calibrated: the edge blur is known to the probe and the sets */
  double edge_blur_px;     /* the calibrated edge blur (Gaussian sigma, px) */
  DsSeparationParams params; /* the rig's separation parameters (estimator, N set per run) */
  /* The truth at the pilot's exposure, for the report. */
  double truth_ld_mean, truth_lg_mean, truth_ld_spread;
} DsValidateScene;

/* Renders the pilot frames (dark, phases 0 and 1/2 at P and, unless fixed_period, at 2P) at the
 * scene's exposure, calibrates on the reference if asked as the rig's `descatterctl calibrate`
 * does (a sine's second set at 2P unless fixed_period) and configures what its lines say
 * ([illuminator] black-level, harmonic-gain, a square's edge-blur-px: they reach the probe and
 * the sets), and probes. */
gboolean ds_validate_probe (const DsSimRig *rig, const DsValidateOptions *options,
                            DsValidateScene *out, GError **error);

/* The achieved error of one configuration: relative RMSE of the transmissive image over the
 * pixels the mask leaves (as the study and the daemon test define it); systematic: the same
 * from noise-free frames. Either pointer may be NULL. */
gboolean ds_validate_run (const DsSimRig *rig, const DsValidateScene *scene, DsEstimator estimator,
                          guint phases, guint averages, double exposure_us, guint64 seed,
                          double *achieved, double *achieved_systematic, GError **error);

typedef enum {
  DS_VERDICT_WITHIN = 0,      /* achieved within a factor 1.5 of predicted */
  DS_VERDICT_OFF,             /* chosen, but achieved outside that factor */
  DS_VERDICT_REFUSED_RIGHT,   /* refused, and the best reachable point indeed misses the target */
  DS_VERDICT_REFUSED_WRONG,   /* refused, but the best reachable point meets the target */
  DS_VERDICT_NONE,            /* refused and nothing fits the budget (nothing to run) */
} DsVerdict;

/* within, off, refused-right, refused-wrong, nothing-fits */
const char *ds_verdict_name (DsVerdict verdict);

typedef struct {
  double target_error, time_budget_ms;
  gboolean refused;
  char *refusal;              /* the message (owned), when refused */
  DsOperatingPoint point;     /* the choice, or the best reachable point when refused */
  double achieved, achieved_systematic;
  DsVerdict verdict;
} DsValidateOutcome;

void ds_validate_outcome_clear (DsValidateOutcome *outcome);

/* One automatic capture: chooses as descatterd would, runs the choice (or, when refused, the
 * best reachable point) and compares. */
gboolean ds_validate_request (const DsSimRig *rig, const DsValidateScene *scene, DsErrorModel *errors,
                              const DsOperatingModel *model, const DsRigTiming *timing,
                              double target_error, double time_budget_ms, guint64 seed,
                              DsValidateOutcome *out, GError **error);

/* A fixed configuration instead of a request: predicted against achieved. */
gboolean ds_validate_config (const DsSimRig *rig, const DsValidateScene *scene, DsErrorModel *errors,
                             const DsOperatingModel *model, const DsRigTiming *timing, DsEstimator estimator,
                             guint phases, guint averages, double exposure_factor, guint64 seed,
                             DsValidateOutcome *out, GError **error);

G_END_DECLS
