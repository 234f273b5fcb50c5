/* The predicted error of a separation: relative RMSE of the transmissive image against the
 * direct light, split into its parts, for any estimator, N, M, exposure and stripe period, on
 * the scene a probe measured (scene_probe.h).
 *
 * The prediction separates synthetic phase sets with the real estimators (proc/separation.h):
 * pixels at every position of the stripe period the sensor has, lit by the blurred,
 * pixel-integrated pattern (stripe_model.h) plus the scattered light's share of the stripes,
 * with the noise of the probe's noise model, and Ld drawn from a two-valued distribution with
 * the probe's mean and spread (blank pixels where objects block the direct light). So the order
 * statistics of max/min, robust's windows, sine's aliasing of square stripes and the precondition
 * aN >= 1 are whatever the estimators actually do, at no modelling cost.
 *
 * Parts (each a relative RMSE):
 *   sampling   noise-free, without scattered stripes: pattern against estimator (blur, pixel
 *              aperture, aN and (1 - a)N, harmonic gain and sine's per-pixel ripple), and
 *              clipping at the exposure;
 *   systematic noise-free with scattered stripes;
 *   noise      sqrt(total^2 - systematic^2): shot and read noise, and max/min's bias from them.
 * total is the noisy set's error. Where the scattered stripes cancel part of the sampling error
 * (systematic < sampling) the leak is not known well enough to rely on that: total_upper is then
 * sqrt (noise^2 + worst^2), worst the larger noise-free error of no leak and twice the probe's
 * leak (`cancellation` says how much that adds to systematic).
 *
 * A term the pilot cannot measure makes the prediction an interval, [total, total_upper]: total
 * is what the measured terms give, total_upper the worst the unmeasured one allows. Two terms:
 * the leak's cancellation above (total_upper takes the worst of no leak and twice the probe's),
 * and the stripes' blur when the probe could not find it (DS_BLUR_ASSUMED_SHARP): total is the
 * sharp pattern's, total_upper the worse of it and one blurred by DS_ERROR_MODEL_UNKNOWN_BLUR_PX
 * (at most P/8). A configuration that only works on sharp stripes (maxmin at N = 2) is then not
 * accepted blind (targets are met on the upper end), and one that works whatever the blur is
 * not refused for a blur nobody measured (refusals are decided on the lower end,
 * operating_point.h).
 *
 * Threads: one model per thread (it caches its synthetic sets). */
#pragma once
#include <glib.h>

#include "daemon/operating/scene_probe.h"
#include "proc/separation.h"

G_BEGIN_DECLS

#define DS_ERROR_MODEL_UNKNOWN_BLUR_PX 0.75

typedef struct {
  double total;         /* relative RMSE of Ld, from the terms measured: the interval's lower end */
  double total_upper;   /* the interval's upper end over the terms not measured (the leak's
                           cancellation, an unknown blur); == total when every term is measured */
  double noise;
  double systematic;    /* sampling and scattered stripes together */
  double sampling;
  double scattered_stripes; /* sqrt(|systematic^2 - sampling^2|), signed: < 0 when it cancels sampling */
  double cancellation;  /* > 0 when the scattered stripes cancel part of the sampling error: how
                           much more systematic error total holds than `systematic`, the worst of
                           no leak and twice the probe's (a cancellation is not trusted as exact):
                           it is in total_upper, not in total */
  gboolean blur_assumed; /* the blur was not measured: total_upper holds the blurred pattern's */
} DsErrorParts;

typedef struct DsErrorModel DsErrorModel;

/* params: the separation parameters the rig will use (pattern, duty, black level, harmonic
 * gain, ...); estimator and N are set per prediction. */
DsErrorModel *ds_error_model_new (const DsSceneProbe *probe, const DsSeparationParams *params);
/* The same rig (separation parameters) on another scene: the operating point's worst case of a
 * probe's interval (ds_scene_probe_worst_case). */
DsErrorModel *ds_error_model_new_like (const DsErrorModel *like, const DsSceneProbe *probe);
void ds_error_model_free (DsErrorModel *model);
G_DEFINE_AUTOPTR_CLEANUP_FUNC (DsErrorModel, ds_error_model_free)

/* period_px 0: the probe's period. exposure_factor: of the probe's exposure. Fails (with the
 * estimator's own error) for configurations it refuses, e.g. sine with N < 3. */
gboolean ds_error_model_predict (DsErrorModel *model, DsEstimator estimator, guint phases,
                                 guint averages, double exposure_factor, double period_px,
                                 DsErrorParts *out, GError **error);

/* Whether a request for this estimator and N, at the rig's pattern (params of
 * ds_error_model_new: pattern, duty, black level), is accepted as a fixed capture: the check a
 * `capture` or `start` naming them gets before it runs (the parameters' own ranges and the
 * sampling precondition without the stripe geometry: maxmin and robust on square stripes need
 * aN >= 1 and (1 - a)N >= 1, sine N >= 3; proc/separation.h). The automatic choice compares only
 * such points, so that every point it runs or names in a refusal can be asked for by hand and
 * runs as predicted; the synthetic sets of ds_error_model_predict () know the period and would
 * accept more (a pixel position fully lit in one phase suffices there). FALSE with the check's
 * message. */
gboolean ds_error_model_request_accepts (const DsErrorModel *model, DsEstimator estimator, guint phases,
                                         GError **error);

G_END_DECLS
