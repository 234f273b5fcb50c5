/* Automatic operating point: picks estimator, phases N, averages M and exposure for a target
 * error and/or a time budget, from the accuracy study's model and the statistics of the scene
 * in front of the camera (one preview frame).
 *
 * The model (written by `descatterctl study` as operating-model.csv) holds, per study scene and
 * per (estimator, N, M), a fit of the transmissive error over exposure e (in multiples of the
 * scene's base exposure):   err^2 = a / e + b
 * where a is the noise part (shot and read noise average down with exposure) and b the
 * systematic part (pattern harmonics, finite period, max/min order-statistic bias at the
 * noise floor). A new scene differs in signal S (DN per frame at base exposure, Ld + Lg) and
 * direct fraction f = Ld / S. The relative noise of Ld scales as sqrt(S) / (f S), so
 *   a_new = a * (f_s^2 S_s) / (f^2 S),   b_new = b of the study scene closest in f,
 * and the prediction is sqrt(a_new / e + b_new), multiplied by a safety factor (the fit's
 * worst ratio of measured to predicted error over the study, at least 1). */
#pragma once
#include <glib.h>

#include "daemon/operating/rig_timing.h"
#include "proc/separation.h"
#include "proc/image.h"

G_BEGIN_DECLS

typedef struct {
  char scene[64];
  DsEstimator estimator;
  guint phases, averages;
  double a, b;               /* err^2 = a / e + b */
  double signal_dn;          /* S of the study scene at its base exposure */
  double direct_fraction;    /* f of the study scene */
  double base_exposure_us;
} DsModelRow;

typedef struct DsOperatingModel DsOperatingModel;

DsOperatingModel *ds_operating_model_load (const char *path, GError **error);
DsOperatingModel *ds_operating_model_new (const DsModelRow *rows, guint n, double safety);
void ds_operating_model_free (DsOperatingModel *model);
G_DEFINE_AUTOPTR_CLEANUP_FUNC (DsOperatingModel, ds_operating_model_free)
double ds_operating_model_safety (const DsOperatingModel *model);
gboolean ds_operating_model_write (const DsModelRow *rows, guint n, double safety,
                                   const char *path, GError **error);

/* What one preview frame says about the scene: its signal and direct fraction, from the mean
 * and the first harmonic of the stripes (proc/stripe_phase): Ld = A / h, S = M / m. */
typedef struct {
  double signal_dn;          /* S at the preview's exposure */
  double direct_fraction;    /* f, clamped to [0.001, 1] */
  double exposure_us;
} DsSceneStats;

gboolean ds_scene_stats_from_frame (const DsImage *frame, double dark_dn, double period_px,
                                    double pattern_mean, double harmonic_gain,
                                    double exposure_us, DsSceneStats *out, GError **error);

typedef struct {
  DsEstimator estimator;
  guint phases, averages;
  double exposure_us;
  double predicted_error;    /* relative RMSE of transmissive, including the safety factor */
  double predicted_time_ms;
} DsOperatingPoint;

/* target_error <= 0: no target (fastest within the budget... or least error within budget);
 * time_budget_ms <= 0: no budget. With both, the fastest point meeting the target within the
 * budget. Exposure factors tried: 0.5, 1, 2, 4 of the preview's exposure, capped at
 * max_exposure_us (saturation is the caller's concern: it passes the largest exposure the
 * preview allows). Fails (with the best achievable error and time in the message) when no
 * point meets the request. */
gboolean ds_operating_point_choose (const DsOperatingModel *model, const DsSceneStats *stats,
                                    const DsRigTiming *timing, guint width, guint height,
                                    double max_exposure_us, double target_error,
                                    double time_budget_ms, DsOperatingPoint *out, GError **error);

/* The prediction for one configuration (exposure in µs, stats at stats->exposure_us). */
double ds_operating_model_predict (const DsOperatingModel *model, const DsSceneStats *stats,
                                   DsEstimator estimator, guint phases, guint averages,
                                   double exposure_us);

G_END_DECLS
