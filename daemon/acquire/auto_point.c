/* The automatic operating point of a capture with a target error or time budget. */
#include <math.h>

#include "daemon/operating/error_model.h"
#include "daemon/operating/motion_term.h"
#include "daemon/operating/pattern_check.h"
#include "daemon/operating/pilot_stripes.h"
#include "daemon/protocol/protocol.h"
#include "daemon/acquire/acquisition.h"
#include "proc/harmonic_gain.h"
#include "proc/stripe_phase.h"

/* A pair of pilot frames (phases 0 and 1/2 of one period) as it is acquired: the phase check
 * of its frames, the pilot's own (a pilot is not a phase set: the sequencer's templates and
 * offset stay as the sets left them). */
typedef struct {
  DsPhaseCheck check;
  gboolean *lost; /* the pilot lost or rejected a frame: a late frame of it may still come */
} PilotPair;

static void
pilot_pair_init (PilotPair *pair, double period_px, gboolean *lost)
{
  ds_phase_check_init (&pair->check, period_px, ds_phase_check_default_tolerance_deg (2));
  ds_phase_check_begin_set (&pair->check);
  pair->lost = lost;
}

/* A pilot frame is verified as a phase set's (docs/design.md, "Phase verification"), as far as
 * a pilot can be: it arrived after its phase was applied, no frame id is missing before it and,
 * once the pilot lost a frame (whose buffer may still arrive late, after the next phase was
 * applied and flushed), it does not repeat the frame of the pair's other phase. The stripes are
 * not required here: the pilot measures how much modulation is left (none at a period the
 * illuminator cannot draw, little at a fine one through a scattering scene), and a weak moving
 * part next to the scene's own texture at that period would pass for a repeat; the pilot's
 * stripes check decides about the configured period (daemon/operating/pilot_stripes.h). */
static void
pilot_verify (DsAcquisition *acq, const DsCaptureSettings *s, PilotPair *pair, guint k, const DsFrame *f,
              gint64 applied_at, DsFrameVerdict *v)
{
  DsCaptureSettings timing_only = *s;
  timing_only.verify_phase = FALSE;
  ds_seq_verify_frame (&acq->phase_check, &timing_only, k, f, applied_at, v);
  if (v->reason != DS_DROP_N_REASONS || !s->verify_phase)
    return;
  double measured;
  g_autofree char *why = NULL;
  if (ds_phase_check_frame (&pair->check, f->image, k, 2, &measured, &why) == DS_PHASE_VERDICT_WRONG && *pair->lost) {
    v->reason = DS_DROP_WRONG_PHASE;
    v->detail = g_steal_pointer (&why);
    v->reapply_phase = TRUE;
  }
}

/* One pilot frame of phase k of a two-phase pattern already applied, re-acquired like a phase
 * set's frame (ds_seq_retry_or_fail: lost, incomplete or rejected frames and an illuminator that
 * timed out, up to phase-retries times; counted in `retries`). */
static DsImage *
pilot_frame (DsAcquisition *acq, const DsCaptureSettings *s, PilotPair *pair, guint k, DsFrameCounters *c,
             GError **error)
{
  guint retries_left = s->phase_retries;
  gboolean lit = FALSE;
  gint64 applied_at = 0;
  for (;;) {
    GError *why = NULL;
    if (!ds_seq_check_quit (acq, error))
      return NULL;
    if (!lit) {
      if (!ds_seq_set_phase (acq, k, &why)) {
        c->device_errors++;
        g_prefix_error (&why, "illuminator: ");
        *pair->lost = TRUE;
        if (!ds_seq_retry_or_fail (acq, &retries_left, c, &why, error, "pilot: phase %u", k))
          return NULL;
        continue;
      }
      ds_seq_flush_stale (acq, c);
      applied_at = g_get_monotonic_time ();
      lit = TRUE;
    }
    g_autoptr (DsFrame) f = ds_seq_trigger_and_grab (acq, c, &why);
    if (!f) {
      g_prefix_error (&why, "camera: ");
      *pair->lost = TRUE;
      if (!ds_seq_retry_or_fail (acq, &retries_left, c, &why, error, "pilot: phase %u", k))
        return NULL;
      /* The illuminator still shows k, but the lost trigger's buffer may come late. */
      ds_seq_flush_stale (acq, c);
      continue;
    }
    DsFrameVerdict v;
    pilot_verify (acq, s, pair, k, f, applied_at, &v);
    if (v.reason != DS_DROP_N_REASONS) {
      ds_frame_counters_drop (c, v.reason, 1);
      why = g_error_new (DS_SEQUENCER_ERROR, DS_SEQUENCER_ERROR_FRAME_REJECTED, "frame dropped (%s): %s",
                         ds_drop_reason_name (v.reason), v.detail ? v.detail : "");
      lit = lit && !v.reapply_phase;
      ds_frame_verdict_clear (&v);
      *pair->lost = TRUE;
      if (!ds_seq_retry_or_fail (acq, &retries_left, c, &why, error, "pilot: phase %u", k))
        return NULL;
      continue;
    }
    return ds_image_copy (f->image, error);
  }
}

/* The two phases at another period (twice the period, or a finer one), where the illuminator
 * can change it; NULL frames and a reason otherwise (the prediction is then a lower bound). */
static gboolean
period_frames (DsAcquisition *acq, const DsCaptureSettings *s, double period, gboolean *lost, DsFrameCounters *c,
               DsImage **out, char **reason, GError **error)
{
  DsStripePattern p = acq->dev->pattern;
  p.kind = s->pattern == DS_PATTERN_SINE ? DS_STRIPES_SINE : DS_STRIPES_SQUARE;
  p.period_px = period;
  p.duty = s->duty;
  p.black_level = s->black_level;
  p.n_phases = 2;
  g_autoptr (GError) refused = NULL;
  ds_seq_blocking (acq->shared, DS_SEQ_CONTROL_BOUND_MS);
  if (!acq->dev->illuminator->ops->set_pattern (acq->dev->illuminator->backend, &p, &refused)) {
    if (refused->code != DS_DEVICE_ERROR_INVALID && refused->code != DS_DEVICE_ERROR_UNSUPPORTED) {
      g_propagate_prefixed_error (error, g_steal_pointer (&refused), "pilot: illuminator: ");
      c->device_errors++;
      ds_seq_fatal_device_error (acq, *error);
      return FALSE;
    }
    *reason = g_strdup_printf ("the illuminator cannot change its period: %s", refused->message);
    return TRUE;
  }
  PilotPair pair;
  pilot_pair_init (&pair, period, lost);
  for (guint k = 0; k < 2; k++)
    if (!(out[k] = pilot_frame (acq, s, &pair, k, c, error)))
      return FALSE;
  /* A device that takes the register but keeps its period shows no stripes at the new one. */
  DsStripePhase sp;
  if (!ds_stripe_phase_measure (out[0], period, NULL, &sp, NULL) || !sp.reliable) {
    *reason = g_strdup_printf ("the illuminator accepted a period of %g px but the frames show no "
                               "stripes at it", period);
    g_clear_pointer (&out[0], ds_image_free);
    g_clear_pointer (&out[1], ds_image_free);
  }
  return TRUE;
}

/* A duty or black level the pilot frames contradict is refused as what it is, not predicted as
 * scattering (daemon/operating/pattern_check.h); an off-stripe level the scene cannot attribute
 * is taken as scattered light, and the log and the result's assumptions say so. */
static gboolean
pattern_matches (const DsProbeFrames *pf, DsOperatingReport *report, GError **error)
{
  DsPatternCheck check;
  if (!ds_pattern_check (pf, &check, error))
    return FALSE;
  switch (check.verdict) {
  case DS_PATTERN_MATCHES:
    return TRUE;
  case DS_PATTERN_OFF_LEVEL_ASSUMED:
    g_message ("automatic operating point: %s", check.message);
    g_strlcpy (report->pattern_assumption, check.message, sizeof report->pattern_assumption);
    return TRUE;
  case DS_PATTERN_WRONG_DUTY:
  case DS_PATTERN_WRONG_BLACK_LEVEL:
    break;
  }
  g_set_error (error, DS_PROTOCOL_ERROR, DS_PROTOCOL_ERROR_FAILED, "automatic operating point: %s", check.message);
  return FALSE;
}

/* The scene's direct light as the pilot frames show it, for a declared speed's motion term
 * (daemon/operating/motion_term.h): two opposite phases sum to the pattern's mean twice, so
 * (lit0 + lit1 - 2 dark) / (2 m) is Ld + Lg at full illumination, and the probe's mean scattered
 * light Lg is taken out (scattered light is smooth: what moves sharply is the direct light). Its
 * noise variance per pixel, from the probe's noise model (var0 + gain x signal per frame), is
 * *var, so that the term does not count the pilot's noise as motion. */
static gboolean
pilot_direct (const DsProbeFrames *pf, const DsSceneProbe *probe, DsImage **direct, DsImage **var, GError **error)
{
  const DsImage *l0 = pf->lit[0], *l1 = pf->lit[1], *dk = pf->dark;
  double m = ds_pattern_mean (pf->geometry.kind, pf->geometry.duty, pf->geometry.black_level);
  if (!(m > 0)) {
    g_set_error (error, DS_PROTOCOL_ERROR, DS_PROTOCOL_ERROR_FAILED, "motion term: the pattern has no mean light");
    return FALSE;
  }
  g_autoptr (DsImage) t = ds_image_new (DS_SAMPLE_F32, l0->width, l0->height, error);
  g_autoptr (DsImage) v = t ? ds_image_new (DS_SAMPLE_F32, l0->width, l0->height, error) : NULL;
  if (!v)
    return FALSE;
  double scale = 1 / (2 * m), var0 = probe->noise.var0, gain = probe->noise.gain, dark_dn = probe->noise.dark_dn;
  for (guint y = 0; y < l0->height; y++) {
    float *to = ds_image_row (t, y), *vo = ds_image_row (v, y);
    const void *r0 = ds_image_row (l0, y), *r1 = ds_image_row (l1, y), *rd = ds_image_row (dk, y);
    for (guint x = 0; x < l0->width; x++) {
      double a = ds_image_sample (l0, r0, x), b = ds_image_sample (l1, r1, x), d = ds_image_sample (dk, rd, x);
      to[x] = (float) ((a + b - 2 * d) * scale - probe->light.lg_mean);
      double va = var0 + gain * MAX (0.0, a - dark_dn), vb = var0 + gain * MAX (0.0, b - dark_dn);
      vo[x] = (float) ((va + vb + 4 * var0) * scale * scale);
    }
  }
  *direct = g_steal_pointer (&t);
  *var = g_steal_pointer (&v);
  return TRUE;
}

/* Pilot frames (docs/accuracy.md, "Automatic operating point"): a dark frame, the phases 0 and
 * 1/2 at the configured period and, where the illuminator can change it, at twice the period and
 * at P/2 and P/4 while resolvable, all at the requested exposure. The probe measures the scene from them and the error model
 * predicts every candidate; the choice and its prediction are recorded in the settings. The
 * pilot frames are counted as `preview` drops. */
gboolean
ds_seq_choose_operating_point (DsAcquisition *acq, DsCaptureSettings *s, DsFrameCounters *c, GError **error)
{
  if (!acq->model) {
    g_set_error (error, DS_PROTOCOL_ERROR, DS_PROTOCOL_ERROR_FAILED,
                 "automatic operating point: no operating model loaded");
    return FALSE;
  }
  gint64 started = g_get_monotonic_time ();
  DsCaptureSettings pilot = *s;
  pilot.averages = 1;
  pilot.phases = 2;
  guint64 before = c->acquired, dropped_before = c->dropped, retries_before = c->retries;
  g_autoptr (DsImage) dark = ds_seq_acquire_dark (acq, &pilot, c, NULL, error);
  if (!dark)
    return FALSE;
  gboolean lost = c->retries > retries_before;
  if (!ds_seq_apply_pattern (acq, &pilot, error)) {
    c->device_errors++;
    g_prefix_error (error, "pilot: illuminator: ");
    ds_seq_fatal_device_error (acq, *error);
    return FALSE;
  }
  PilotPair pair;
  pilot_pair_init (&pair, s->period_px, &lost);
  g_autoptr (DsImage) lit0 = pilot_frame (acq, s, &pair, 0, c, error);
  g_autoptr (DsImage) lit1 = lit0 ? pilot_frame (acq, s, &pair, 1, c, error) : NULL;
  if (!lit1)
    return FALSE;
  DsImage *coarse[2] = { NULL, NULL };
  g_autofree char *coarse_missing = NULL;
  gboolean ok = period_frames (acq, s, 2 * s->period_px, &lost, c, coarse, &coarse_missing, error);
  g_autoptr (DsImage) coarse0 = coarse[0];
  g_autoptr (DsImage) coarse1 = coarse[1];
  /* Finer periods, while the sensor resolves them (scene_probe.h), and not after the illuminator
   * has refused a period: a narrow kernel passes for direct light at P and 2P alike. */
  double finer_period[DS_PROBE_FINER_MAX];
  guint n_finer = ds_scene_probe_finer_periods (s->period_px, s->edge_blur_known ? s->edge_blur_px : 0, finer_period);
  DsImage *finer[DS_PROBE_FINER_MAX][2] = { { NULL, NULL }, { NULL, NULL } };
  g_autofree char *finer_missing = NULL;
  guint got = 0;
  for (guint i = 0; ok && i < n_finer && !finer_missing && !coarse_missing; i++) {
    ok = period_frames (acq, s, finer_period[i], &lost, c, finer[got], &finer_missing, error);
    got += ok && finer[got][0];
  }
  if (coarse_missing && n_finer)
    finer_missing = g_strdup (coarse_missing);
  G_STATIC_ASSERT (DS_PROBE_FINER_MAX == 2);
  g_autoptr (DsImage) finer00 = finer[0][0];
  g_autoptr (DsImage) finer01 = finer[0][1];
  g_autoptr (DsImage) finer10 = finer[1][0];
  g_autoptr (DsImage) finer11 = finer[1][1];
  /* The frames the pilot used; those it dropped and re-acquired keep their reasons. */
  guint pilot_frames = (guint) ((c->acquired - before) - (c->dropped - dropped_before));
  ds_frame_counters_drop (c, DS_DROP_PREVIEW, pilot_frames);
  if (!ok)
    return FALSE;

  DsProbeFrames pf = {
    .dark = dark, .lit = { lit0, lit1 }, .coarse = { coarse0, coarse1 }, .coarse_missing = coarse_missing,
    .exposure_us = s->exposure_us,
    .saturation_dn = lit0->type == DS_SAMPLE_F32 ? 0 : (double) ((1u << lit0->bit_depth) - 1),
    .geometry = { .kind = s->pattern, .period_px = s->period_px, .duty = s->duty, .black_level = s->black_level },
    /* What calibration measured and the sensor's clip level, when configured. */
    .calibrated_gain = s->harmonic_gain,
    .blur_known = s->edge_blur_known,
    .calibrated_blur_px = s->edge_blur_px,
    /* The open field at the pilot's exposure and gain (the key is per ms at 0 dB). */
    .open_field_dn = s->open_field_dn_per_ms * s->exposure_us / 1000 * pow (10, s->gain_db / 20),
    .open_field_unused = s->open_field_unused[0] ? s->open_field_unused : NULL,
    .acceptance_half_angle_deg = s->acceptance_half_angle_deg,
    .n_finer = got,
    .finer_missing = finer_missing,
  };
  for (guint i = 0; i < got; i++)
    pf.finer[i] = (DsProbePair){ .frame = { finer[i][0], finer[i][1] }, .period_px = finer_period[i] };
  if (s->saturation_dn > 0 && lit0->type != DS_SAMPLE_F32) {
    pf.saturation_dn = MIN (pf.saturation_dn, s->saturation_dn);
    pf.saturation_known = TRUE;
  }
  DsOperatingReport *r = &s->operating;
  memset (r, 0, sizeof *r);
  DsPilotStripes stripes;
  if (!ds_pilot_stripes_check (&pf, &stripes, error)) {
    g_prefix_error (error, "automatic operating point: ");
    return FALSE;
  }
  if (!pattern_matches (&pf, r, error))
    return FALSE;
  if (!ds_scene_probe_measure (&pf, &r->probe, error))
    return FALSE;
  DsSeparationParams params;
  ds_capture_settings_separation_params (s, &params);
  g_autoptr (DsErrorModel) errors = ds_error_model_new (&r->probe, &params);
  DsOperatingMotion motion = { .speed_px_s = s->speed_declared ? s->speed_px_s : NAN };
  g_autoptr (DsMotionTable) table = NULL;
  if (s->speed_declared) {
    DsImage *direct = NULL, *var = NULL;
    if (!pilot_direct (&pf, &r->probe, &direct, &var, error))
      return FALSE;
    g_autoptr (DsImage) direct_owned = direct;
    g_autoptr (DsImage) var_owned = var;
    if (!(table = ds_motion_table_new (direct, var, error))) {
      g_prefix_error (error, "automatic operating point: ");
      return FALSE;
    }
    motion.table = table;
  }
  DsOperatingPoint op;
  if (!ds_operating_point_choose_moving (acq->model, errors, &r->probe, &acq->timing, lit0->width, lit0->height,
                                         s->target_error, s->time_budget_ms, &motion, &op, error))
    return FALSE;
  r->speed_declared = s->speed_declared;
  r->speed_px_s = s->speed_px_s;
  r->target_error = s->target_error;
  r->time_budget_ms = s->time_budget_ms;
  r->point = op;
  r->scale = acq->model->scale;
  r->pilot_frames = pilot_frames;
  r->pilot_ms = (g_get_monotonic_time () - started) / 1000.0;
  s->estimator = op.estimator;
  s->phases = op.phases;
  s->averages = op.averages;
  s->exposure_us = op.exposure_us;
  s->automatic = TRUE;
  s->phase_tolerance_deg = MIN (s->phase_tolerance_deg, ds_phase_check_default_tolerance_deg (op.phases));
  return TRUE;
}
