#include "daemon/service/sequencer.h"

#include <math.h>
#include <string.h>

#include "daemon/operating/operating_point.h"
#include "daemon/service/phase_check.h"
#include "proc/image_stats.h"
#include "proc/stripe_phase.h"
#include "daemon/protocol/protocol.h"

typedef enum {
  CMD_CAPTURE,
  CMD_DARK,
  CMD_START,
  CMD_STOP,
  CMD_DEFAULTS,
  CMD_QUIT,
} CommandKind;

typedef struct {
  CommandKind kind;
  DsCaptureSettings settings;
  guint64 tag;
} Command;

#define MAX_PENDING 8

struct DsSequencer {
  GThread *thread;
  GAsyncQueue *queue;
  GMainContext *context;
  DsSequencerEventFunc on_event;
  gpointer user_data;
  DsDevicesOpenFunc open_devices;
  gpointer open_data;
  gint quit;     /* atomic */
  gint pending;  /* atomic: captures and darks queued */
  /* Delivery of events after free must not happen: events hold a ref on this. */
  gint alive;    /* atomic: cleared by free before joining */

  GMutex lock;   /* protects status and defaults */
  DsSequencerStatus status;
  DsCaptureSettings defaults;

  /* Acquisition thread only. */
  DsDevices *dev;
  DsPhaseSet *set;
  DsSeparationParams set_params;
  guint set_width, set_height;
  DsImage *dark;
  double dark_exposure_us, dark_gain_db;
  gboolean camera_configured, camera_started;
  double camera_exposure_us, camera_gain_db;
  gboolean continuous;
  DsCaptureSettings continuous_settings;
  gboolean continuous_uses_defaults;
  guint64 next_set_id;
  DsPhaseCheck phase_check;
  double phase_check_period;
  gboolean need_reconnect;
  gint64 last_frame_us;     /* arrival of the last folded frame */
  const DsOperatingModel *model; /* set before the thread uses it; read-only */
  DsRigTiming timing;
};

const char *
ds_stage_name (DsStage stage)
{
  static const char *const names[DS_STAGE_N] = { "set_phase", "trigger", "grab", "verify",
                                                 "fold", "finalize", "set" };
  return (guint) stage < DS_STAGE_N ? names[stage] : "unknown";
}

/* ---- events to the main context ---- */

typedef struct {
  DsSequencer *seq;
  DsSequencerEventKind kind;
  guint64 tag;
  DsResult *result;
  GError *error;
  guint phase, n_phases;
  double dark_mean_dn;
  char *message;
} PendingEvent;

static void
pending_event_free (gpointer data)
{
  PendingEvent *p = data;
  if (p->result)
    ds_result_unref (p->result);
  g_clear_error (&p->error);
  g_free (p->message);
  g_free (p);
}

static gboolean
pending_event_dispatch (gpointer data)
{
  PendingEvent *p = data;
  if (!g_atomic_int_get (&p->seq->alive))
    return G_SOURCE_REMOVE;
  DsSequencerEvent ev = { .kind = p->kind, .tag = p->tag, .result = p->result, .error = p->error,
                          .phase = p->phase, .n_phases = p->n_phases,
                          .dark_mean_dn = p->dark_mean_dn, .message = p->message };
  p->seq->on_event (&ev, p->seq->user_data);
  return G_SOURCE_REMOVE;
}

/* Every event goes through one priority, so they are dispatched in the order they were
 * posted (a progress event never overtakes the result that follows it). */
static void
post (DsSequencer *seq, PendingEvent *p)
{
  GSource *src = g_idle_source_new ();
  g_source_set_priority (src, G_PRIORITY_DEFAULT);
  g_source_set_callback (src, pending_event_dispatch, p, pending_event_free);
  g_source_attach (src, seq->context);
  g_source_unref (src);
}

/* Takes ownership of result and error. */
static void
emit (DsSequencer *seq, DsSequencerEventKind kind, guint64 tag, DsResult *result, GError *error,
      const char *message)
{
  PendingEvent *p = g_new0 (PendingEvent, 1);
  p->seq = seq;
  p->kind = kind;
  p->tag = tag;
  p->result = result;
  p->error = error;
  p->message = g_strdup (message);
  post (seq, p);
}

static void
emit_progress (DsSequencer *seq, guint64 tag, guint phase, guint n)
{
  PendingEvent *p = g_new0 (PendingEvent, 1);
  p->seq = seq;
  p->kind = DS_SEQUENCER_EVENT_PROGRESS;
  p->tag = tag;
  p->phase = phase;
  p->n_phases = n;
  post (seq, p);
}

/* ---- status ---- */

static void
set_state (DsSequencer *seq, const char *state)
{
  g_mutex_lock (&seq->lock);
  g_strlcpy (seq->status.state, state, sizeof seq->status.state);
  seq->status.heartbeat_us = g_get_monotonic_time ();
  g_mutex_unlock (&seq->lock);
}

static void
heartbeat (DsSequencer *seq)
{
  g_mutex_lock (&seq->lock);
  seq->status.heartbeat_us = g_get_monotonic_time ();
  g_mutex_unlock (&seq->lock);
}

static void
stage_add (DsSequencer *seq, DsStage stage, gint64 since_us)
{
  double ms = (double) (g_get_monotonic_time () - since_us) / 1000.0;
  g_mutex_lock (&seq->lock);
  seq->status.stages[stage].total_ms += ms;
  seq->status.stages[stage].count++;
  seq->status.heartbeat_us = g_get_monotonic_time ();
  g_mutex_unlock (&seq->lock);
}

static void
record_error (DsSequencer *seq, const GError *error)
{
  g_mutex_lock (&seq->lock);
  g_strlcpy (seq->status.last_error, error->message, sizeof seq->status.last_error);
  g_mutex_unlock (&seq->lock);
}

static void
refresh_device_status (DsSequencer *seq)
{
  if (!seq->dev)
    return;
  DsCameraStats cs = { 0 };
  DsCameraInfo ci = { 0 };
  DsIlluminatorStatus is = { .applied_phase = -1, .temperature_c = NAN };
  seq->dev->camera->ops->get_stats (seq->dev->camera->backend, &cs);
  seq->dev->camera->ops->get_info (seq->dev->camera->backend, &ci);
  g_autoptr (GError) error = NULL;
  gboolean have_ill = seq->dev->illuminator->ops->get_status (seq->dev->illuminator->backend, &is, &error);
  g_mutex_lock (&seq->lock);
  seq->status.camera_stats = cs;
  seq->status.camera_info = ci;
  if (have_ill)
    seq->status.illuminator = is;
  g_mutex_unlock (&seq->lock);
}

/* ---- device helpers ---- */

static gboolean
is_code (const GError *error, int code)
{
  return error && (error->domain == DS_CAMERA_ERROR || error->domain == DS_ILLUMINATOR_ERROR ||
                   error->domain == DS_TRIGGER_ERROR) && error->code == code;
}

static gboolean
ensure_camera (DsSequencer *seq, const DsCaptureSettings *s, GError **error)
{
  DsCamera *cam = seq->dev->camera;
  if (seq->camera_configured && seq->camera_exposure_us == s->exposure_us &&
      seq->camera_gain_db == s->gain_db) {
    if (!seq->camera_started) {
      if (!cam->ops->start (cam->backend, error))
        return FALSE;
      seq->camera_started = TRUE;
    }
    return TRUE;
  }
  if (seq->camera_started) {
    cam->ops->stop (cam->backend);
    seq->camera_started = FALSE;
  }
  DsCameraSettings cs = seq->dev->camera_settings;
  cs.exposure_us = s->exposure_us;
  cs.gain_db = s->gain_db;
  if (!cam->ops->configure (cam->backend, &cs, error)) {
    seq->camera_configured = FALSE;
    return FALSE;
  }
  seq->camera_configured = TRUE;
  seq->camera_exposure_us = s->exposure_us;
  seq->camera_gain_db = s->gain_db;
  if (!cam->ops->start (cam->backend, error))
    return FALSE;
  seq->camera_started = TRUE;
  return TRUE;
}

static gboolean
apply_pattern (DsSequencer *seq, const DsCaptureSettings *s, GError **error)
{
  DsStripePattern p = seq->dev->pattern;
  p.kind = s->pattern == DS_PATTERN_SINE ? DS_STRIPES_SINE : DS_STRIPES_SQUARE;
  p.period_px = s->period_px;
  p.duty = s->duty;
  p.black_level = s->black_level;
  p.n_phases = s->phases;
  return seq->dev->illuminator->ops->set_pattern (seq->dev->illuminator->backend, &p, error);
}

/* One frame: trigger and grab. Counts what happened. Returns NULL with error set. */
static DsFrame *
trigger_and_grab (DsSequencer *seq, DsFrameCounters *c, GError **error)
{
  gint64 t = g_get_monotonic_time ();
  if (!seq->dev->trigger->ops->fire (seq->dev->trigger->backend, error)) {
    c->device_errors++;
    return NULL;
  }
  stage_add (seq, DS_STAGE_TRIGGER, t);
  t = g_get_monotonic_time ();
  GError *local = NULL;
  DsFrame *frame = seq->dev->camera->ops->grab (seq->dev->camera->backend,
                                                seq->dev->grab_timeout_ms, &local);
  stage_add (seq, DS_STAGE_GRAB, t);
  if (frame) {
    c->acquired++;
    return frame;
  }
  if (is_code (local, DS_DEVICE_ERROR_TIMEOUT))
    c->timeouts++;
  else if (is_code (local, DS_DEVICE_ERROR_INCOMPLETE)) {
    c->acquired++;
    ds_frame_counters_drop (c, DS_DROP_INCOMPLETE, 1);
  } else
    c->device_errors++;
  g_propagate_error (error, local);
  return NULL;
}

static void
flush_stale (DsSequencer *seq, DsFrameCounters *c)
{
  guint n = seq->dev->camera->ops->flush (seq->dev->camera->backend);
  c->acquired += n;
  ds_frame_counters_drop (c, DS_DROP_STALE, n);
}

static gboolean
check_quit (DsSequencer *seq, GError **error)
{
  if (!g_atomic_int_get (&seq->quit))
    return TRUE;
  g_set_error (error, DS_PROTOCOL_ERROR, DS_PROTOCOL_ERROR_CANCELLED, "the daemon is stopping");
  return FALSE;
}

/* Consumes one retry of the current phase after `why`; fails with `why` when none are left. */
static gboolean
use_retry (guint *retries_left, DsFrameCounters *c, guint k, GError **why, GError **error)
{
  if (*retries_left == 0) {
    g_propagate_prefixed_error (error, g_steal_pointer (why), "phase %u: retries exhausted: ", k);
    return FALSE;
  }
  (*retries_left)--;
  c->retries++;
  g_clear_error (why);
  return TRUE;
}

static gboolean
fatal_device_error (DsSequencer *seq, const GError *e)
{
  if (is_code (e, DS_DEVICE_ERROR_DISCONNECTED)) {
    seq->need_reconnect = TRUE;
    return TRUE;
  }
  return is_code (e, DS_DEVICE_ERROR_INVALID) || is_code (e, DS_DEVICE_ERROR_UNSUPPORTED);
}

/* Acquires the M frames of phase k and folds them; every frame is verified first, so a frame
 * that fails is never folded, and frames already folded for k stay valid (they were verified
 * as phase k). */
static gboolean
acquire_phase (DsSequencer *seq, const DsCaptureSettings *s, guint k, DsFrameCounters *c,
               GError **error)
{
  guint retries_left = s->phase_retries;
  guint done = 0;
  gboolean need_phase = TRUE;
  gint64 applied_at = 0;
  while (done < s->averages) {
    GError *why = NULL;
    if (!check_quit (seq, error))
      return FALSE;
    if (need_phase) {
      gint64 t = g_get_monotonic_time ();
      if (!seq->dev->illuminator->ops->set_phase (seq->dev->illuminator->backend, k,
                                                  seq->dev->settle_timeout_ms, &why)) {
        c->device_errors++;
        g_prefix_error (&why, "illuminator: ");
        if (fatal_device_error (seq, why) || !use_retry (&retries_left, c, k, &why, &why)) {
          g_propagate_prefixed_error (error, why, "phase %u: ", k);
          return FALSE;
        }
        continue;
      }
      stage_add (seq, DS_STAGE_SET_PHASE, t);
      flush_stale (seq, c);
      applied_at = g_get_monotonic_time ();
      need_phase = FALSE;
    }
    g_autoptr (DsFrame) frame = trigger_and_grab (seq, c, &why);
    if (!frame) {
      g_prefix_error (&why, "camera: ");
      if (fatal_device_error (seq, why) || !use_retry (&retries_left, c, k, &why, &why)) {
        g_propagate_prefixed_error (error, why, "phase %u: ", k);
        return FALSE;
      }
      /* After a lost frame the illuminator's state is still right, but a late buffer of the
       * lost trigger may arrive: flush before the next trigger. */
      flush_stale (seq, c);
      continue;
    }
    gint64 t = g_get_monotonic_time ();
    DsDropReason reason = DS_DROP_N_REASONS;
    g_autofree char *detail = NULL;
    if (frame->host_time_us != 0 && (gint64) frame->host_time_us < applied_at) {
      reason = DS_DROP_STALE;
      detail = g_strdup ("frame arrived before the phase was applied");
    } else if (frame->ids_skipped > 0) {
      reason = DS_DROP_FRAME_GAP;
      detail = g_strdup_printf ("%u frame id(s) missing before id %" G_GUINT64_FORMAT,
                                frame->ids_skipped, frame->frame_id);
    } else if (s->verify_phase) {
      double measured = NAN;
      g_autofree char *msg = NULL;
      DsPhaseVerdict v = ds_phase_check_frame (&seq->phase_check, frame->image, k, s->phases,
                                               &measured, &msg);
      if (v == DS_PHASE_VERDICT_WRONG) {
        reason = DS_DROP_WRONG_PHASE;
        need_phase = TRUE; /* the illuminator may have applied another phase: apply again */
      } else if (v == DS_PHASE_VERDICT_UNVERIFIABLE)
        reason = DS_DROP_UNVERIFIABLE;
      detail = g_steal_pointer (&msg);
    }
    stage_add (seq, DS_STAGE_VERIFY, t);
    if (reason != DS_DROP_N_REASONS) {
      ds_frame_counters_drop (c, reason, 1);
      why = g_error_new (DS_PROTOCOL_ERROR, DS_PROTOCOL_ERROR_DEVICE, "frame dropped (%s): %s",
                         ds_drop_reason_name (reason), detail ? detail : "");
      if (!use_retry (&retries_left, c, k, &why, &why)) {
        g_propagate_prefixed_error (error, why, "phase %u: ", k);
        return FALSE;
      }
      continue;
    }
    t = g_get_monotonic_time ();
    if (!ds_phase_set_accumulate (seq->set, k, frame->image, error)) {
      ds_frame_counters_drop (c, DS_DROP_ABORTED, 1);
      return FALSE;
    }
    stage_add (seq, DS_STAGE_FOLD, t);
    seq->last_frame_us = frame->host_time_us ? (gint64) frame->host_time_us : t;
    done++;
  }
  return TRUE;
}

static gboolean
prepare_phase_set (DsSequencer *seq, const DsCaptureSettings *s, guint width, guint height,
                   GError **error)
{
  DsSeparationParams p;
  ds_separation_params_init (&p, s->phases);
  p.estimator = s->estimator;
  p.pattern = s->pattern;
  p.duty = s->duty;
  p.black_level = s->black_level;
  p.keep_extrema = s->keep_extrema;
  if (seq->set && width == seq->set_width && height == seq->set_height &&
      memcmp (&p, &seq->set_params, sizeof p) == 0) {
    ds_phase_set_reset (seq->set);
    return TRUE;
  }
  g_clear_pointer (&seq->set, ds_phase_set_free);
  seq->set = ds_phase_set_new (&p, width, height, error);
  if (!seq->set)
    return FALSE;
  seq->set_params = p;
  seq->set_width = width;
  seq->set_height = height;
  return TRUE;
}

/* Averages `n` frames with the illuminator off into an f32 image. */
static DsImage *
acquire_dark (DsSequencer *seq, const DsCaptureSettings *s, DsFrameCounters *c, GError **error)
{
  if (!seq->dev->illuminator->ops->off (seq->dev->illuminator->backend, seq->dev->settle_timeout_ms,
                                        error)) {
    c->device_errors++;
    g_prefix_error (error, "dark frame: illuminator off: ");
    return NULL;
  }
  flush_stale (seq, c);
  gint64 off_at = g_get_monotonic_time ();
  g_autofree double *sum = NULL;
  guint w = 0, h = 0, got = 0, retries_left = s->phase_retries, bit_depth = 16;
  DsSampleType type = DS_SAMPLE_U16;
  while (got < s->averages) {
    GError *why = NULL;
    if (!check_quit (seq, error))
      return NULL;
    g_autoptr (DsFrame) f = trigger_and_grab (seq, c, &why);
    if (f && f->host_time_us != 0 && (gint64) f->host_time_us < off_at) {
      ds_frame_counters_drop (c, DS_DROP_STALE, 1);
      why = g_error_new (DS_PROTOCOL_ERROR, DS_PROTOCOL_ERROR_DEVICE, "stale frame");
      g_clear_pointer (&f, ds_frame_free);
    }
    if (f && s->verify_phase && s->period_px > 2) {
      /* A dark frame must show no stripes: one exposed while the pattern was still on would
       * be subtracted from every phase. */
      DsStripePhase sp;
      if (ds_stripe_phase_measure (f->image, s->period_px, NULL, &sp, NULL) && sp.reliable) {
        ds_frame_counters_drop (c, DS_DROP_WRONG_PHASE, 1);
        why = g_error_new (DS_PROTOCOL_ERROR, DS_PROTOCOL_ERROR_DEVICE,
                           "dark frame shows stripes (snr %.1f): the illuminator was not off", sp.snr);
        g_clear_pointer (&f, ds_frame_free);
      }
    }
    if (!f) {
      if (fatal_device_error (seq, why) || retries_left == 0) {
        g_propagate_prefixed_error (error, why, "dark frame: ");
        return NULL;
      }
      retries_left--;
      c->retries++;
      g_clear_error (&why);
      continue;
    }
    const DsImage *img = f->image;
    if (!sum) {
      w = img->width;
      h = img->height;
      type = img->type;
      bit_depth = img->bit_depth;
      sum = g_new0 (double, (gsize) w * h);
    } else if (img->width != w || img->height != h) {
      ds_frame_counters_drop (c, DS_DROP_ABORTED, 1);
      g_set_error (error, DS_PROTOCOL_ERROR, DS_PROTOCOL_ERROR_DEVICE,
                   "dark frame: frame size changed from %ux%u to %ux%u", w, h, img->width,
                   img->height);
      return NULL;
    }
    for (guint y = 0; y < h; y++) {
      const guint8 *row = ds_image_row (img, y);
      double *out = sum + (gsize) y * w;
      for (guint x = 0; x < w; x++)
        out[x] += img->type == DS_SAMPLE_U8    ? ((const guint8 *) row)[x]
                  : img->type == DS_SAMPLE_U16 ? ((const guint16 *) row)[x]
                                               : ((const float *) row)[x];
    }
    got++;
  }
  /* The dark frame has the frames' own sample type, as the accumulator subtracts like from
   * like; averaging M integer frames rounds to the nearest DN (an unbiased error below the
   * read noise). */
  DsImage *dark = ds_image_new (type, w, h, error);
  if (!dark)
    return NULL;
  dark->bit_depth = bit_depth;
  for (guint y = 0; y < h; y++) {
    void *row = ds_image_row (dark, y);
    for (guint x = 0; x < w; x++) {
      double v = sum[(gsize) y * w + x] / got;
      if (type == DS_SAMPLE_F32)
        ((float *) row)[x] = (float) v;
      else if (type == DS_SAMPLE_U16)
        ((guint16 *) row)[x] = (guint16) CLAMP (v + 0.5, 0, 65535);
      else
        ((guint8 *) row)[x] = (guint8) CLAMP (v + 0.5, 0, 255);
    }
  }
  return dark;
}

static void
account (DsSequencer *seq, const DsFrameCounters *c, gboolean ok)
{
  g_mutex_lock (&seq->lock);
  ds_frame_counters_add (&seq->status.frames, c);
  if (ok)
    seq->status.sets_done++;
  else
    seq->status.sets_failed++;
  g_mutex_unlock (&seq->lock);
}

/* Automatic operating point: one dark and one phase-0 preview frame at the requested base
 * exposure give the scene's signal and direct fraction; the model then picks estimator, N, M
 * and exposure (docs/accuracy.md). The two frames are counted as `preview` drops. */
static gboolean
choose_operating_point (DsSequencer *seq, DsCaptureSettings *s, DsFrameCounters *c, GError **error)
{
  if (!seq->model) {
    g_set_error (error, DS_PROTOCOL_ERROR, DS_PROTOCOL_ERROR_FAILED,
                 "automatic operating point: no operating model loaded");
    return FALSE;
  }
  DsCaptureSettings one = *s;
  one.averages = 1;
  guint64 before = c->acquired, dropped_before = c->dropped;
  g_autoptr (DsImage) dark = acquire_dark (seq, &one, c, error);
  if (!dark)
    return FALSE;
  if (!apply_pattern (seq, s, error) ||
      !seq->dev->illuminator->ops->set_phase (seq->dev->illuminator->backend, 0,
                                              seq->dev->settle_timeout_ms, error)) {
    c->device_errors++;
    g_prefix_error (error, "preview: illuminator: ");
    fatal_device_error (seq, *error);
    return FALSE;
  }
  flush_stale (seq, c);
  g_autoptr (DsFrame) preview = trigger_and_grab (seq, c, error);
  if (!preview) {
    g_prefix_error (error, "preview: ");
    fatal_device_error (seq, *error);
    return FALSE;
  }
  ds_frame_counters_drop (c, DS_DROP_PREVIEW, (c->acquired - before) - (c->dropped - dropped_before));
  double a = s->duty, b = s->black_level;
  gboolean sine = s->pattern == DS_PATTERN_SINE;
  double m = sine ? b + (1 - b) / 2 : a + b * (1 - a);
  double h = sine ? (1 - b) / 2 : (1 - b) * (2 / G_PI) * sin (G_PI * a);
  double dark_dn = ds_image_mean (dark);
  DsSceneStats st;
  if (!ds_scene_stats_from_frame (preview->image, dark_dn, s->period_px, m, h, s->exposure_us, &st, error)) {
    g_prefix_error (error, "preview: ");
    return FALSE;
  }
  /* The largest exposure that keeps the brightest pixels below 90 % of full scale. */
  double full = preview->image->type == DS_SAMPLE_F32 ? INFINITY : (double) ((1u << preview->image->bit_depth) - 1);
  double high = ds_image_percentile (preview->image, 99.9) - dark_dn;
  double max_exposure = high > 0 && isfinite (full) ? s->exposure_us * (0.9 * full - dark_dn) / high : 4 * s->exposure_us;
  max_exposure = CLAMP (max_exposure, s->exposure_us * 0.5, s->exposure_us * 4);
  DsCameraInfo info = { 0 };
  seq->dev->camera->ops->get_info (seq->dev->camera->backend, &info);
  guint w = seq->dev->camera_settings.roi_width ? seq->dev->camera_settings.roi_width : info.sensor_width;
  guint hh = seq->dev->camera_settings.roi_width ? seq->dev->camera_settings.roi_height : info.sensor_height;
  DsOperatingPoint op;
  if (!ds_operating_point_choose (seq->model, &st, &seq->timing, w, hh, max_exposure, s->target_error,
                                  s->time_budget_ms, &op, error))
    return FALSE;
  s->estimator = op.estimator;
  s->phases = op.phases;
  s->averages = op.averages;
  s->exposure_us = op.exposure_us;
  s->automatic = TRUE;
  s->predicted_error = op.predicted_error;
  s->predicted_time_ms = op.predicted_time_ms;
  s->preview_signal_dn = st.signal_dn;
  s->preview_direct_fraction = st.direct_fraction;
  s->phase_tolerance_deg = MIN (s->phase_tolerance_deg, 90.0 / op.phases);
  return TRUE;
}

/* The frames of one set, from configuring the camera to the finalized separation. Returns NULL
 * with error set; the caller accounts for the frames in `c` either way. Early returns only: no
 * jump may cross an auto-cleanup declaration (-Wjump-misses-init). */
static DsSeparation *
acquire_set (DsSequencer *seq, const DsCaptureSettings *s, guint64 tag, DsFrameCounters *c,
             gint64 *last_frame_us, GError **error)
{
  if (seq->phase_check_period != s->period_px || !seq->phase_check.offset_known) {
    if (seq->phase_check_period != s->period_px)
      ds_phase_check_init (&seq->phase_check, s->period_px, s->phase_tolerance_deg);
    seq->phase_check_period = s->period_px;
  }
  seq->phase_check.tolerance_cycles = s->phase_tolerance_deg / 360.0;

  if (!ensure_camera (seq, s, error)) {
    g_prefix_error (error, "camera: ");
    fatal_device_error (seq, *error);
    return NULL;
  }
  if (!apply_pattern (seq, s, error)) {
    g_prefix_error (error, "illuminator: ");
    fatal_device_error (seq, *error);
    return NULL;
  }
  g_autoptr (DsImage) dark = NULL;
  if (s->dark_frame) {
    dark = acquire_dark (seq, s, c, error);
    if (!dark)
      return NULL;
  }
  const DsImage *use_dark = dark;
  if (!use_dark && seq->dark && seq->dark_exposure_us == s->exposure_us && seq->dark_gain_db == s->gain_db)
    use_dark = seq->dark;

  /* The frame size the camera delivers: its ROI, or the whole sensor. */
  DsCameraSettings *cs = &seq->dev->camera_settings;
  DsCameraInfo info = { 0 };
  seq->dev->camera->ops->get_info (seq->dev->camera->backend, &info);
  guint w = cs->roi_width ? cs->roi_width : info.sensor_width;
  guint h = cs->roi_width ? cs->roi_height : info.sensor_height;
  if (!prepare_phase_set (seq, s, w, h, error))
    return NULL;
  /* The phase set is reused between sets: forget an earlier dark frame when this set has
   * none (or one for other settings). */
  if (!ds_phase_set_set_dark (seq->set, use_dark, error))
    return NULL;
  for (guint k = 0; k < s->phases; k++) {
    if (!acquire_phase (seq, s, k, c, error)) {
      if (seq->phase_check.provisional)
        ds_phase_check_abandon (&seq->phase_check);
      return NULL;
    }
    emit_progress (seq, tag, k, s->phases);
  }
  *last_frame_us = seq->last_frame_us;
  return ds_phase_set_finalize (seq->set, error);
}

static void
run_set (DsSequencer *seq, const DsCaptureSettings *requested, guint64 tag)
{
  /* The stripe geometry is the illuminator's (configured for real devices, the scene's for
   * the simulated lab), never a per-capture choice: the set records what was projected. */
  DsCaptureSettings settings = *requested;
  const DsCaptureSettings *s = &settings;
  settings.pattern = seq->dev->pattern.kind == DS_STRIPES_SINE ? DS_PATTERN_SINE : DS_PATTERN_SQUARE;
  settings.period_px = seq->dev->pattern.period_px;
  settings.duty = seq->dev->pattern.duty;
  settings.black_level = seq->dev->pattern.black_level;
  DsFrameCounters c = { 0 };
  g_autoptr (GError) error = NULL;
  if (settings.target_error > 0 || settings.time_budget_ms > 0) {
    if (!ensure_camera (seq, s, &error) || !choose_operating_point (seq, &settings, &c, &error)) {
      account (seq, &c, FALSE);
      record_error (seq, error);
      emit (seq, DS_SEQUENCER_EVENT_FAILED, tag, NULL, g_steal_pointer (&error), NULL);
      return;
    }
  }
  gint64 started = g_get_monotonic_time ();
  gint64 acquired = 0;
  g_autoptr (DsSeparation) sep = acquire_set (seq, s, tag, &c, &acquired, &error);
  if (!sep) {
    /* Whatever was not dropped already (folded frames, dark frames) goes down with the set. */
    ds_frame_counters_drop (&c, DS_DROP_ABORTED, c.acquired - c.dropped);
    account (seq, &c, FALSE);
    record_error (seq, error);
    refresh_device_status (seq);
    emit (seq, DS_SEQUENCER_EVENT_FAILED, tag, NULL, g_steal_pointer (&error), NULL);
    return;
  }
  stage_add (seq, DS_STAGE_FINALIZE, acquired);
  if (seq->phase_check.provisional) {
    ds_phase_check_confirm (&seq->phase_check);
    g_mutex_lock (&seq->lock);
    seq->status.phase_offset_cycles = seq->phase_check.offset_cycles;
    g_mutex_unlock (&seq->lock);
  }
  gint64 finished = g_get_monotonic_time ();
  stage_add (seq, DS_STAGE_SET, started);
  /* Every frame not dropped went into the result: folded into a phase, or averaged into its
   * dark frame. */
  c.folded = c.acquired - c.dropped;
  account (seq, &c, TRUE);
  DsResult *result = ds_result_new (++seq->next_set_id, g_steal_pointer (&sep), s, &c, started,
                                    acquired, finished);
  refresh_device_status (seq);
  emit (seq, DS_SEQUENCER_EVENT_RESULT, tag, result, NULL, NULL);
}

static void
run_dark (DsSequencer *seq, const DsCaptureSettings *s, guint64 tag)
{
  DsFrameCounters c = { 0 };
  g_autoptr (GError) error = NULL;
  DsImage *dark = NULL;
  if (!ensure_camera (seq, s, &error)) {
    g_prefix_error (&error, "camera: ");
    fatal_device_error (seq, error);
  } else
    dark = acquire_dark (seq, s, &c, &error);
  if (!dark) {
    ds_frame_counters_drop (&c, DS_DROP_ABORTED, c.acquired - c.dropped);
    account (seq, &c, FALSE);
    record_error (seq, error);
    emit (seq, DS_SEQUENCER_EVENT_DARK, tag, NULL, g_steal_pointer (&error), NULL);
    return;
  }
  c.folded = c.acquired - c.dropped;
  g_mutex_lock (&seq->lock);
  ds_frame_counters_add (&seq->status.frames, &c);
  seq->status.has_dark = TRUE;
  g_mutex_unlock (&seq->lock);
  double mean = ds_image_mean (dark);
  g_clear_pointer (&seq->dark, ds_image_free);
  seq->dark = dark;
  seq->dark_exposure_us = s->exposure_us;
  seq->dark_gain_db = s->gain_db;
  PendingEvent *p = g_new0 (PendingEvent, 1);
  p->seq = seq;
  p->kind = DS_SEQUENCER_EVENT_DARK;
  p->tag = tag;
  p->dark_mean_dn = mean;
  post (seq, p);
}

/* Reopens a lost camera (or illuminator) with capped exponential backoff, until it works or
 * the daemon stops. Commands wait in the queue meanwhile. */
static void
reconnect (DsSequencer *seq)
{
  set_state (seq, "reconnecting");
  emit (seq, DS_SEQUENCER_EVENT_DEVICE, 0, NULL, NULL, "device disconnected: reconnecting");
  guint delay_ms = 100;
  while (!g_atomic_int_get (&seq->quit)) {
    g_autoptr (GError) e1 = NULL;
    g_autoptr (GError) e2 = NULL;
    gboolean cam_ok = seq->dev->camera->ops->reconnect (seq->dev->camera->backend, &e1);
    gboolean ill_ok = cam_ok && seq->dev->illuminator->ops->reconnect (seq->dev->illuminator->backend, &e2);
    heartbeat (seq);
    if (cam_ok && ill_ok) {
      seq->camera_started = FALSE;
      seq->camera_configured = FALSE;
      seq->need_reconnect = FALSE;
      g_mutex_lock (&seq->lock);
      seq->status.camera_stats.reconnects++;
      g_mutex_unlock (&seq->lock);
      emit (seq, DS_SEQUENCER_EVENT_DEVICE, 0, NULL, NULL, "devices reconnected");
      return;
    }
    record_error (seq, e1 ? e1 : e2);
    /* Sleep in slices so that quitting stays prompt. */
    for (guint slept = 0; slept < delay_ms && !g_atomic_int_get (&seq->quit); slept += 50)
      g_usleep (50 * 1000);
    delay_ms = MIN (delay_ms * 2, 2000);
  }
}

static gpointer
thread_main (gpointer data)
{
  DsSequencer *seq = data;
  g_autoptr (GError) error = NULL;
  set_state (seq, "opening");
  seq->dev = seq->open_devices (seq->open_data, &error);
  if (!seq->dev) {
    set_state (seq, "failed");
    record_error (seq, error);
    emit (seq, DS_SEQUENCER_EVENT_READY, 0, NULL, g_steal_pointer (&error), NULL);
    /* Nothing to drive: wait for the quit command so that status stays answerable. */
    for (;;) {
      Command *cmd = g_async_queue_timeout_pop (seq->queue, G_USEC_PER_SEC);
      heartbeat (seq);
      gboolean quit = cmd && cmd->kind == CMD_QUIT;
      if (cmd && (cmd->kind == CMD_CAPTURE || cmd->kind == CMD_DARK)) {
        g_atomic_int_dec_and_test (&seq->pending);
        emit (seq, cmd->kind == CMD_DARK ? DS_SEQUENCER_EVENT_DARK : DS_SEQUENCER_EVENT_FAILED,
              cmd->tag, NULL,
              g_error_new (DS_PROTOCOL_ERROR, DS_PROTOCOL_ERROR_DEVICE, "devices are not open: %s",
                           seq->status.last_error),
              NULL);
      }
      g_free (cmd);
      if (quit)
        return NULL;
    }
  }
  g_mutex_lock (&seq->lock);
  g_strlcpy (seq->status.devices, seq->dev->description, sizeof seq->status.devices);
  g_mutex_unlock (&seq->lock);
  refresh_device_status (seq);
  set_state (seq, "idle");
  emit (seq, DS_SEQUENCER_EVENT_READY, 0, NULL, NULL, seq->dev->description);

  for (;;) {
    if (seq->need_reconnect)
      reconnect (seq);
    Command *cmd = seq->continuous ? g_async_queue_try_pop (seq->queue)
                                   : g_async_queue_timeout_pop (seq->queue, G_USEC_PER_SEC / 2);
    heartbeat (seq);
    if (!cmd) {
      if (g_atomic_int_get (&seq->quit))
        break;
      if (seq->continuous) {
        if (seq->continuous_uses_defaults) {
          g_mutex_lock (&seq->lock);
          seq->continuous_settings = seq->defaults;
          g_mutex_unlock (&seq->lock);
        }
        set_state (seq, "continuous");
        run_set (seq, &seq->continuous_settings, 0);
      }
      continue;
    }
    CommandKind kind = cmd->kind;
    switch (kind) {
    case CMD_CAPTURE:
      set_state (seq, "acquiring");
      run_set (seq, &cmd->settings, cmd->tag);
      g_atomic_int_add (&seq->pending, -1);
      break;
    case CMD_DARK:
      set_state (seq, "acquiring");
      run_dark (seq, &cmd->settings, cmd->tag);
      g_atomic_int_add (&seq->pending, -1);
      break;
    case CMD_START:
      seq->continuous = TRUE;
      seq->continuous_settings = cmd->settings;
      seq->continuous_uses_defaults = cmd->tag == 1;
      break;
    case CMD_STOP:
      seq->continuous = FALSE;
      break;
    case CMD_DEFAULTS:
      g_mutex_lock (&seq->lock);
      seq->defaults = cmd->settings;
      g_mutex_unlock (&seq->lock);
      break;
    case CMD_QUIT:
      break;
    }
    g_free (cmd);
    if (kind == CMD_QUIT)
      break;
    g_mutex_lock (&seq->lock);
    seq->status.continuous = seq->continuous;
    g_mutex_unlock (&seq->lock);
    set_state (seq, seq->continuous ? "continuous" : "idle");
  }
  if (seq->camera_started)
    seq->dev->camera->ops->stop (seq->dev->camera->backend);
  g_autoptr (GError) off_error = NULL;
  seq->dev->illuminator->ops->off (seq->dev->illuminator->backend, seq->dev->settle_timeout_ms,
                                   &off_error);
  return NULL;
}

DsSequencer *
ds_sequencer_new (DsDevicesOpenFunc open_devices, gpointer open_data,
                  const DsCaptureSettings *defaults, GMainContext *context,
                  DsSequencerEventFunc on_event, gpointer user_data)
{
  DsSequencer *seq = g_new0 (DsSequencer, 1);
  seq->queue = g_async_queue_new_full (g_free);
  seq->context = g_main_context_ref (context);
  seq->on_event = on_event;
  seq->user_data = user_data;
  seq->open_devices = open_devices;
  seq->open_data = open_data;
  seq->alive = 1;
  seq->defaults = *defaults;
  seq->phase_check_period = NAN;
  g_mutex_init (&seq->lock);
  g_strlcpy (seq->status.state, "opening", sizeof seq->status.state);
  seq->status.phase_offset_cycles = NAN;
  seq->status.illuminator.applied_phase = -1;
  seq->status.illuminator.temperature_c = NAN;
  seq->status.heartbeat_us = g_get_monotonic_time ();
  seq->thread = g_thread_new ("acquisition", thread_main, seq);
  return seq;
}

static void
push (DsSequencer *seq, CommandKind kind, const DsCaptureSettings *s, guint64 tag)
{
  Command *cmd = g_new0 (Command, 1);
  cmd->kind = kind;
  if (s)
    cmd->settings = *s;
  cmd->tag = tag;
  g_async_queue_push (seq->queue, cmd);
}

void
ds_sequencer_free (DsSequencer *seq)
{
  if (!seq)
    return;
  g_atomic_int_set (&seq->quit, 1);
  push (seq, CMD_QUIT, NULL, 0);
  g_thread_join (seq->thread);
  g_atomic_int_set (&seq->alive, 0);
  /* Events still queued in the context are dropped by their dispatch (alive == 0), but they
   * point at seq: flush them now, before seq is freed. */
  while (g_main_context_iteration (seq->context, FALSE))
    ;
  if (seq->dev)
    ds_devices_close (seq->dev);
  g_clear_pointer (&seq->set, ds_phase_set_free);
  g_clear_pointer (&seq->dark, ds_image_free);
  g_async_queue_unref (seq->queue);
  g_main_context_unref (seq->context);
  g_mutex_clear (&seq->lock);
  g_free (seq);
}

gboolean
ds_sequencer_capture (DsSequencer *seq, const DsCaptureSettings *settings, guint64 tag)
{
  if (g_atomic_int_add (&seq->pending, 1) >= MAX_PENDING) {
    g_atomic_int_add (&seq->pending, -1);
    return FALSE;
  }
  push (seq, CMD_CAPTURE, settings, tag);
  return TRUE;
}

gboolean
ds_sequencer_dark (DsSequencer *seq, const DsCaptureSettings *settings, guint64 tag)
{
  if (g_atomic_int_add (&seq->pending, 1) >= MAX_PENDING) {
    g_atomic_int_add (&seq->pending, -1);
    return FALSE;
  }
  push (seq, CMD_DARK, settings, tag);
  return TRUE;
}

void
ds_sequencer_start (DsSequencer *seq, const DsCaptureSettings *settings)
{
  /* tag 1 marks "follow the defaults" (no explicit settings given): the thread reads them. */
  push (seq, CMD_START, settings, settings ? 0 : 1);
}

void
ds_sequencer_stop (DsSequencer *seq)
{
  push (seq, CMD_STOP, NULL, 0);
}

void
ds_sequencer_set_defaults (DsSequencer *seq, const DsCaptureSettings *defaults)
{
  push (seq, CMD_DEFAULTS, defaults, 0);
}

void
ds_sequencer_get_status (DsSequencer *seq, DsSequencerStatus *status)
{
  g_mutex_lock (&seq->lock);
  *status = seq->status;
  status->pending = (guint) g_atomic_int_get (&seq->pending);
  g_mutex_unlock (&seq->lock);
}

void
ds_sequencer_set_operating_model (DsSequencer *seq, const DsOperatingModel *model, double settle_ms,
                                  double link_mbit)
{
  seq->model = model;
  ds_rig_timing_init (&seq->timing);
  seq->timing.settle_ms = settle_ms;
  seq->timing.link_mbit_s = link_mbit;
}
