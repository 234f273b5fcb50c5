#include "daemon/ctl/validate.h"

#include <math.h>
#include <string.h>

#include "daemon/operating/calibration_knowledge.h"
#include "proc/calibration.h"
#include "proc/image_stats.h"
#include "proc/metrics.h"

/* One phase set of the clear reference measured by the calibrator, as `descatterctl calibrate`
 * measures the set the daemon takes (daemon/service/calibrate_set.c): many phases (so that the
 * square wave's harmonics do not alias into the first), a dark frame, the exposure given. */
static gboolean
calibrate_set (const DsSimRig *ref, double exposure_us, const DsCalibrationHints *hints, guint64 seed,
               DsCalibration *cal, GError **error)
{
  const guint n = 32;
  const DsSceneSpec *s = ds_scene_spec (ds_sim_rig_scene (ref));
  g_autoptr (DsCalibrator) c = ds_calibrator_new (n, s->width, s->height, error);
  if (!c)
    return FALSE;
  for (guint k = 0; k < n; k++) {
    g_autoptr (DsImage) frame = ds_sim_rig_frame (ref, k, n, TRUE, exposure_us, seed + k, error);
    if (!frame || !ds_calibrator_add (c, k, frame, error))
      return FALSE;
  }
  g_autoptr (DsImage) dark = ds_sim_rig_frame (ref, 0, n, FALSE, exposure_us, seed + n, error);
  if (!dark || !ds_calibrator_set_dark (c, dark, error) || !ds_calibrator_finish (c, hints, cal, error))
    return FALSE;
  /* As the daemon's calibrate: the open field per ms above the dark frame, at the rig's 0 dB. */
  cal->open_field_dn_per_ms = cal->lit_level_dn / (exposure_us / 1000);
  return TRUE;
}

/* The rig's `descatterctl calibrate` on the clear reference (daemon/service/service.c): one set
 * at the illuminator's period, with what descatterd is configured with (the pattern, the black
 * level a sine's one period cannot tell from its blur, the clip level) and an exposure that keeps
 * the open field below the clip level; then, for sine stripes, a second set at twice the period
 * (the illuminator's PERIOD register) that tells the black level from the blur. An illuminator
 * that cannot change its period fails that set, and the one-period calibration stands, noted. */
static gboolean
calibrate_rig (const DsSimRig *rig, const DsValidateOptions *o, guint64 seed, DsValidateScene *out,
               GError **error)
{
  g_autoptr (DsSimRig) ref = ds_sim_rig_reference (rig, error);
  if (!ref)
    return FALSE;
  const DsScene *scene = ds_sim_rig_scene (ref);
  double e0 = ds_scene_default_exposure_us (scene);
  DsRenderRequest req = { .phase = 0, .n_phases = 2, .illuminator_on = TRUE, .exposure_us = e0 };
  g_autoptr (DsImage) probe = ds_renderer_render_expected (ds_sim_rig_renderer (ref), &req, error);
  if (!probe)
    return FALSE;
  double top = ds_image_percentile (probe, 100), clip = ds_sim_rig_clip_dn (ref);
  double exposure = top > 0 ? e0 * 0.6 * clip / top : e0;
  const DsSceneSpec *s = ds_scene_spec (scene);
  DsCalibrationHints hints;
  ds_calibration_hints_init (&hints);
  hints.pattern = s->sine ? DS_PATTERN_SINE : DS_PATTERN_SQUARE;
  hints.black_level = s->black_level;
  hints.period_px = s->period_px;
  hints.saturation_level = clip;
  DsCalibration *cal = &out->calibration;
  if (!calibrate_set (ref, exposure, &hints, seed, cal, error))
    return FALSE;
  if (!ds_calibration_wants_second_period (cal))
    return TRUE;
  if (o->fixed_period) {
    g_strlcpy (out->second_period_note, "the illuminator cannot change its period", sizeof out->second_period_note);
    return TRUE;
  }
  g_autoptr (DsSimRig) at_2p = ds_sim_rig_with_period (ref, 2 * s->period_px, error);
  if (!at_2p)
    return FALSE;
  ds_calibration_hints_second_period (&hints, 2 * s->period_px);
  DsCalibration second;
  g_autoptr (GError) local = NULL;
  if (!calibrate_set (at_2p, exposure, &hints, seed + 100, &second, &local) ||
      !ds_calibration_add_second_period (cal, &second, hints.pixel_aperture, &local))
    g_strlcpy (out->second_period_note, local->message, sizeof out->second_period_note);
  return TRUE;
}

static void
truth_stats (const DsImage *t, const DsImage *g, const DsImage *mask_from, double clip,
             DsValidateScene *out)
{
  double st = 0, st2 = 0, sg = 0;
  guint64 n = 0;
  for (guint y = 0; y < t->height; y++) {
    const float *a = ds_image_row (t, y), *b = ds_image_row (g, y);
    const guint16 *f = mask_from ? ds_image_row (mask_from, y) : NULL;
    for (guint x = 0; x < t->width; x++) {
      if (f && f[x] >= clip)
        continue;
      st += a[x];
      st2 += (double) a[x] * a[x];
      sg += b[x];
      n++;
    }
  }
  out->truth_ld_mean = n ? st / n : 0;
  out->truth_lg_mean = n ? sg / n : 0;
  out->truth_ld_spread = st > 0 ? st2 * n / (st * st) : 1;
}

gboolean
ds_validate_probe (const DsSimRig *rig, const DsValidateOptions *o, DsValidateScene *out, GError **error)
{
  memset (out, 0, sizeof *out);
  const DsScene *scene = ds_sim_rig_scene (rig);
  const DsSceneSpec *s = ds_scene_spec (scene);
  double e0 = ds_scene_default_exposure_us (scene);
  guint64 seed = o->seed * 1000;
  out->black_level = s->black_level;
  if (o->calibrated) {
    if (!calibrate_rig (rig, o, seed + 500, out, error)) {
      g_prefix_error (error, "calibration: ");
      return FALSE;
    }
    out->calibrated = TRUE;
  } else if (o->simulated) {
    /* descatterd --sim: the record a noise-free calibration of the scene's illuminator gives. */
    double w = ds_scene_pattern_aperture_px (scene);
    DsStripeModel g = { .kind = s->sine ? DS_PATTERN_SINE : DS_PATTERN_SQUARE, .period_px = s->period_px,
                        .duty = s->duty, .black_level = s->black_level, .blur_px = s->edge_blur_px,
                        .pixel_aperture = w > 0 ? w : DS_STRIPE_POINT_APERTURE };
    ds_calibration_from_geometry (&g, &out->calibration);
    out->calibration.open_field_dn_per_ms = ds_scene_open_field_dn_per_ms (scene);
    out->calibrated = TRUE;
  }
  if (out->calibrated) {
    /* What descatterd.conf then holds, the record's lines pasted (ds_calibration_config_lines):
     * the path every source of knowledge takes (daemon/operating/pattern_knowledge.h). */
    DsPatternKnowledge known;
    ds_pattern_knowledge_from_calibration (&out->calibration, &known);
    out->black_level = known.black_level;
    out->harmonic_gain = known.harmonic_gain;
    out->edge_blur_known = known.edge_blur_known;
    out->edge_blur_px = known.edge_blur_px;
    out->open_field_dn_per_ms = known.open_field_dn_per_ms;
  }
  /* Every rig knows its lens, as its user writes it ([camera] acceptance-half-angle-deg). */
  out->acceptance_half_angle_deg = s->acceptance_half_angle_deg;
  g_autoptr (DsImage) dark = ds_sim_rig_frame (rig, 0, 2, FALSE, e0, seed + 1, error);
  g_autoptr (DsImage) l0 = dark ? ds_sim_rig_frame (rig, 0, 2, TRUE, e0, seed + 2, error) : NULL;
  g_autoptr (DsImage) l1 = l0 ? ds_sim_rig_frame (rig, 1, 2, TRUE, e0, seed + 3, error) : NULL;
  if (!l1)
    return FALSE;
  g_autoptr (DsSimRig) coarse = NULL;
  g_autoptr (DsImage) c0 = NULL;
  g_autoptr (DsImage) c1 = NULL;
  if (!o->fixed_period) {
    coarse = ds_sim_rig_with_period (rig, 2 * s->period_px, error);
    if (!coarse)
      return FALSE;
    c0 = ds_sim_rig_frame (coarse, 0, 2, TRUE, e0, seed + 4, error);
    c1 = c0 ? ds_sim_rig_frame (coarse, 1, 2, TRUE, e0, seed + 5, error) : NULL;
    if (!c1)
      return FALSE;
  }
  /* The finer pilot periods, as descatterd takes them (auto_point.c): with the blur the rig
   * knows, the calibrated one (edge-blur-px), or only the 4 px floor without it. */
  double finer_period[DS_PROBE_FINER_MAX];
  guint n_finer = o->fixed_period ? 0
                                  : ds_scene_probe_finer_periods (s->period_px, out->edge_blur_known ? out->edge_blur_px : 0,
                                                                  finer_period);
  DsImage *finer_frames[DS_PROBE_FINER_MAX][2] = { { NULL, NULL }, { NULL, NULL } };
  gboolean finer_ok = TRUE;
  for (guint i = 0; i < n_finer && finer_ok; i++) {
    g_autoptr (DsSimRig) at = ds_sim_rig_with_period (rig, finer_period[i], error);
    for (guint k = 0; k < 2 && at && finer_ok; k++)
      finer_ok = (finer_frames[i][k] = ds_sim_rig_frame (at, k, 2, TRUE, e0, seed + 6 + 2 * i + k, error)) != NULL;
    finer_ok = finer_ok && at;
  }
  if (!finer_ok) {
    for (guint i = 0; i < DS_PROBE_FINER_MAX; i++)
      for (guint k = 0; k < 2; k++)
        ds_image_free (finer_frames[i][k]);
    return FALSE;
  }
  DsProbeFrames pf = {
    .dark = dark, .lit = { l0, l1 }, .coarse = { c0, c1 },
    .coarse_missing = o->fixed_period ? "the illuminator cannot change its period" : NULL,
    .exposure_us = e0,
    /* What descatterd knows: the pixel format's top, or the clip level configured ([camera]
     * saturation-dn). A full well below the format's top shows as a pile-up when reached. */
    .saturation_dn = o->saturation_known ? ds_sim_rig_clip_dn (rig) : (double) ((1u << s->bit_depth) - 1),
    .saturation_known = o->saturation_known,
    .geometry = { .kind = s->sine ? DS_PATTERN_SINE : DS_PATTERN_SQUARE, .period_px = s->period_px,
                  .duty = s->duty, .black_level = out->black_level },
    .calibrated_gain = out->harmonic_gain,
    .n_finer = n_finer,
    .finer_missing = o->fixed_period ? "the illuminator cannot change its period" : NULL,
    .blur_known = out->edge_blur_known,
    .calibrated_blur_px = out->edge_blur_px,
    .open_field_dn = out->open_field_dn_per_ms * e0 / 1000,
    .acceptance_half_angle_deg = out->acceptance_half_angle_deg,
  };
  for (guint i = 0; i < n_finer; i++)
    pf.finer[i] = (DsProbePair){ .frame = { finer_frames[i][0], finer_frames[i][1] }, .period_px = finer_period[i] };
  gboolean probed = ds_scene_probe_measure (&pf, &out->probe, error);
  for (guint i = 0; i < DS_PROBE_FINER_MAX; i++)
    for (guint k = 0; k < 2; k++)
      ds_image_free (finer_frames[i][k]);
  if (!probed)
    return FALSE;
  ds_separation_params_init (&out->params, 4);
  out->params.pattern = pf.geometry.kind;
  out->params.duty = pf.geometry.duty;
  out->params.black_level = pf.geometry.black_level;
  out->params.harmonic_gain = out->harmonic_gain;
  /* As ds_capture_settings_separation_params: the configured clip level flags clipped samples. */
  out->params.saturation_level = o->saturation_known ? ds_sim_rig_clip_dn (rig) : 0;
  /* As descatterd's sets (ds_capture_settings_separation_params): the period is known. */
  out->params.geometry.period_px = s->period_px;
  out->params.geometry.pixel_aperture = 1;
  /* As there, a calibrated blur sets robust's margin; unknown, robust keeps one phase. */
  out->params.geometry.edge_blur_known = out->edge_blur_known;
  out->params.geometry.edge_blur_px = out->edge_blur_known ? out->edge_blur_px : 0;
  DsImage *tt = NULL, *tg = NULL;
  if (!ds_renderer_truth (ds_sim_rig_renderer (rig), e0, 0.0, &tt, &tg, error))
    return FALSE;
  g_autoptr (DsImage) truth_t = tt;
  g_autoptr (DsImage) truth_g = tg;
  /* Over the whole scene, as the probe measures it (the places that clip in the pilot counted in)
   * and as the achieved error is taken at the chosen exposure. */
  truth_stats (truth_t, truth_g, NULL, INFINITY, out);
  return TRUE;
}

gboolean
ds_validate_run (const DsSimRig *rig, const DsValidateScene *vs, DsEstimator estimator, guint phases,
                 guint averages, double exposure_us, guint64 seed, double *achieved,
                 double *achieved_systematic, GError **error)
{
  const DsScene *scene = ds_sim_rig_scene (rig);
  DsSeparationParams p = vs->params;
  p.n_phases = phases;
  p.estimator = estimator;
  DsImage *tt = NULL, *tg = NULL;
  if (!ds_renderer_truth (ds_sim_rig_renderer (rig), exposure_us, 0.0, &tt, &tg, error))
    return FALSE;
  g_autoptr (DsImage) truth_t = tt;
  g_autoptr (DsImage) truth_g = tg;
  const guint8 ignore = DS_MASK_SATURATED | DS_MASK_NONFINITE | DS_MASK_DARK_EXCEEDS;
  for (int pass = 0; pass < 2; pass++) {
    double *out = pass == 0 ? achieved : achieved_systematic;
    if (!out)
      continue;
    DsSeparation *sep = NULL;
    if (!ds_sim_rig_separate (rig, &p, 1, averages, exposure_us, seed, pass == 1, &sep, NULL, error))
      return FALSE;
    g_autoptr (DsSeparation) owned = sep;
    DsErrorStats st;
    if (!ds_metrics_error (sep->transmissive, truth_t, sep->mask, ignore, &st, error))
      return FALSE;
    *out = st.relative_rmse;
  }
  (void) scene;
  return TRUE;
}

const char *
ds_verdict_name (DsVerdict v)
{
  static const char *const names[] = { "within", "off", "refused-right", "refused-wrong", "nothing-fits" };
  return v <= DS_VERDICT_NONE ? names[v] : "?";
}

void
ds_validate_outcome_clear (DsValidateOutcome *o)
{
  g_clear_pointer (&o->refusal, g_free);
}

gboolean
ds_validate_request (const DsSimRig *rig, const DsValidateScene *vs, DsErrorModel *errors,
                     const DsOperatingModel *model, const DsRigTiming *timing, double target, double budget,
                     guint64 seed, DsValidateOutcome *out, GError **error)
{
  memset (out, 0, sizeof *out);
  out->target_error = target;
  out->time_budget_ms = budget;
  g_autoptr (GError) refused = NULL;
  out->refused = !ds_operating_point_choose (model, errors, &vs->probe, timing, vs->probe.width, vs->probe.height,
                                             target, budget, &out->point, &refused);
  if (out->refused) {
    out->refusal = g_strdup (refused->message);
    if (!isfinite (out->point.predicted_error)) {
      out->verdict = DS_VERDICT_NONE;
      return TRUE;
    }
  }
  const DsOperatingPoint *p = &out->point;
  if (!ds_validate_run (rig, vs, p->estimator, p->phases, p->averages, p->exposure_us, seed, &out->achieved,
                        &out->achieved_systematic, error))
    return FALSE;
  double ratio = out->achieved / p->predicted_error;
  if (out->refused)
    out->verdict = out->achieved > target ? DS_VERDICT_REFUSED_RIGHT : DS_VERDICT_REFUSED_WRONG;
  else
    out->verdict = ratio <= 1.5 && ratio >= 1 / 1.5 ? DS_VERDICT_WITHIN : DS_VERDICT_OFF;
  return TRUE;
}

gboolean
ds_validate_config (const DsSimRig *rig, const DsValidateScene *vs, DsErrorModel *errors, const DsOperatingModel *model,
                    const DsRigTiming *timing, DsEstimator estimator, guint phases, guint averages, double factor,
                    guint64 seed, DsValidateOutcome *out, GError **error)
{
  memset (out, 0, sizeof *out);
  DsOperatingPoint *p = &out->point;
  if (!ds_error_model_predict (errors, estimator, phases, averages, factor, 0, &p->parts, error))
    return FALSE;
  p->estimator = estimator;
  p->phases = phases;
  p->averages = averages;
  p->exposure_us = vs->probe.exposure_us * factor;
  p->period_px = vs->probe.geometry.period_px;
  p->predicted_error = model->scale * p->parts.total;
  /* a fixed configuration: the probe's own scene only, with the error model's own interval */
  p->predicted_error_upper = model->scale * p->parts.total_upper;
  p->predicted_time_ms = ds_rig_timing_set_ms (timing, vs->probe.width, vs->probe.height, phases, averages,
                                               p->exposure_us, TRUE);
  gboolean stripes_lower = !vs->probe.leak.measured || vs->probe.narrow.unresolved ||
                           vs->probe.transfer.inconsistent || vs->probe.blur.source == DS_BLUR_ASSUMED_SHARP;
  /* Light lost to a film the stripes do not show: a lower bound, with the film's bias added to
   * the upper end where the lens's cone bounds it (as ds_operating_point_choose () predicts). */
  const DsProbeLoss *loss = &vs->probe.loss;
  p->lower_bound = stripes_lower || loss->unexplained;
  p->upper_bounded = !stripes_lower && (!loss->unexplained || loss->bounded);
  if (p->upper_bounded && loss->unexplained)
    p->predicted_error_upper += loss->bias_upper;
  p->uncertainty = ds_operating_point_uncertainty (model, &vs->probe, &p->parts, p->period_px);
  if (!ds_validate_run (rig, vs, estimator, phases, averages, p->exposure_us, seed, &out->achieved,
                        &out->achieved_systematic, error))
    return FALSE;
  double ratio = out->achieved / p->predicted_error;
  out->verdict = ratio <= 1.5 && ratio >= 1 / 1.5 ? DS_VERDICT_WITHIN : DS_VERDICT_OFF;
  return TRUE;
}
