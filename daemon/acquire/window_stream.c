/* Continuous mode with per-frame results (docs/protocol.md, "Per-frame results"): the phases are
 * lit in turn, 0, 1, ..., N-1, 0, ..., one frame each, and every good frame replaces its phase's
 * frame in the sliding window (proc/phase_window.h); once the window holds a confirmed frame of
 * every phase, each good frame publishes a result, which is what a fresh set over the window's
 * N frames gives.
 *
 * Why such a result is as trustworthy as a set's:
 *   - every frame is verified before it enters the window, by the checks a set's frame passes
 *     (verify.c: stale, frame gap, stripe phase), on the fold thread while the next frame
 *     exposes; the illuminator moves to the next phase during a frame's transfer under the
 *     same rule as the set pipeline's (pipeline.c: only once the camera began sending it);
 *   - the phase check judges a frame alone only against the templates of a scene that held
 *     still; a frame it can judge only with its whole cycle (the first one, or a scene that
 *     changed) enters the window unconfirmed, and no result is made while the window holds an
 *     unconfirmed frame: the cycle is checked as a whole at its phase N-1, when the window is
 *     exactly that cycle's N frames. A scene whose stripe phases stop matching the templates
 *     therefore gives a result per cycle;
 *   - a lost frame, a refused frame, a cycle refused as a whole, or settings other than the last
 *     run's break the window: no result mixes frames from both sides of a gap, and the next one
 *     needs a good frame of every phase again. Each break is told (WINDOW_BROKEN) and counted.
 * Retries: as in a set, a phase may fail phase-retries times in a row (no good frame of it in
 * between) and the run fails at the next. A set retakes the failed phase at once, so a set fails
 * exactly when one phase does; a window goes on in turn after a refused frame, so its failures
 * are charged to the phase that failed, and the count of a phase restarts with its next good
 * frame. A budget shared by all phases until the next result would instead end a run whose
 * losses are spread over the phases (a camera losing a frame in five) that sets get through.
 * Accounting: acquired = folded + dropped holds as for sets. A frame is folded once a
 * published result holds it; the frames of a window broken before they made a result are
 * aborted. The counters of each result are those since the result before it. */
#include <math.h>
#include <string.h>

#include "daemon/acquire/acquisition.h"

typedef struct {
  DsAcquisition *acq;
  DsCaptureSettings settings;  /* the run's: stripe geometry from the illuminator, region filled in */
  guint n;
  guint width, height;
  DsFrameCounters c;           /* since the last result */
  guint64 unpublished;         /* good frames since the last result or break */
  guint *retries_left;         /* per phase: failures allowed before its next good frame */
  gint64 *arrival;             /* per phase: when the window's frame of it arrived */
  /* Lent to the fold worker with the window during a job (window_step). */
  gboolean *confirmed;         /* per phase: the phase check confirmed the window's frame of it */
  gboolean cycle_whole;        /* the phase check's cycle began at phase 0, no break since */
  char *confirm_error;         /* the cycle failed the check as a whole */
  /* The job in the worker (at most one). */
  gboolean in_flight;
  DsFrame *in_flight_frame;
  guint in_flight_phase;
  DsSeparation *in_flight_planes;
  gboolean reapply;            /* a refused frame: the illuminator may show another phase */
  guint64 result_span;         /* the window's span and frames since the break at its last
                                  push (set by window_step, for the result) */
  guint64 result_since_break;
  gboolean published_in_job;   /* window_done published the job's result */
  /* save_phases: a copy of the window's frames, so that each result carries the N frames it
   * was made from (and the dark frame), as a set's result carries its set's. */
  DsImage **kept;
  guint64 *kept_id, *kept_ts, *kept_push;
  guint64 pushes;
  DsImage *black;
  GArray *black_ids;
  gint64 last_refresh_us;      /* device status read for status, at most twice a second */
} WindowStream;

/* Fold thread, between submit and collect: the verified frame into the window, the cycle
 * confirmed at its last phase, and the result finalized when every frame is confirmed. A
 * result that will be wanted is made with the push (ds_phase_window_push_finalize_into, one
 * pass over the rows): whether it is wanted is known before the push, as the confirmations
 * depend on the phase check alone; a confirmation that then fails discards it. */
static gboolean
window_step (DsFoldJob *job, gpointer data)
{
  WindowStream *ws = data;
  DsPhaseWindow *window = ws->acq->window;
  guint k = job->phase;
  gboolean complete = FALSE;
  gboolean checked = job->settings->verify_phase;
  gboolean confirmed_k = !checked || job->phase_check->set_by_template;
  gboolean cycle_end = checked && ws->cycle_whole && k + 1 == ws->n;
  /* at the cycle's end a successful confirmation confirms every phase */
  gboolean wanted = confirmed_k || cycle_end;
  for (guint h = 0; h < ws->n && wanted && !cycle_end; h++)
    if (h != k && !ws->confirmed[h])
      wanted = FALSE;
  gboolean finalized = FALSE;
  if (wanted) {
    gboolean pushed = FALSE;
    finalized = ds_phase_window_push_finalize_into (window, k, job->frame->image, job->finalize_into,
                                                    &complete, &pushed, &job->fold_error);
    if (!pushed)
      return FALSE;
    /* a push without a result (planes that did not fit) keeps fold_error, as the finalize
     * would: the frame is in the window either way */
    finalized = finalized && complete;
  } else if (!ds_phase_window_push (window, k, job->frame->image, &complete, &job->fold_error)) {
    return FALSE;
  }
  ws->pushes++;
  ws->result_span = ds_phase_window_span (window);
  ws->result_since_break = ds_phase_window_frames_since_break (window);
  if (ws->kept) {
    /* A copy failed: the results go without their raw frames (kept_push 0 never matches). */
    g_clear_pointer (&ws->kept[k], ds_image_free);
    ws->kept[k] = ds_image_copy (job->frame->image, NULL);
    ws->kept_id[k] = job->frame->frame_id;
    ws->kept_ts[k] = job->frame->timestamp_ns;
    ws->kept_push[k] = ws->kept[k] ? ws->pushes : 0;
  }
  ws->confirmed[k] = confirmed_k;
  if (cycle_end) {
    g_autofree char *why = NULL;
    if (!ds_phase_check_confirm (job->phase_check, &why)) {
      ws->confirm_error = g_steal_pointer (&why);
      g_clear_error (&job->fold_error);
      return TRUE;
    }
    /* No break since phase 0 and one frame per phase in turn: the window is this cycle. */
    for (guint h = 0; h < ws->n; h++)
      ws->confirmed[h] = TRUE;
  }
  if (!complete)
    return TRUE;
  for (guint h = 0; h < ws->n; h++)
    if (!ws->confirmed[h])
      return TRUE;
  job->finalized = finalized;
  return TRUE;
}

/* After a failure of phase k (its frame lost or refused, or the illuminator could not light it). */
static gboolean
retry_or_fail (WindowStream *ws, guint k, GError **why, GError **error)
{
  return ds_seq_retry_or_fail (ws->acq, &ws->retries_left[k], &ws->c, why, error, "per-frame results");
}

/* No result until a good frame of every phase follows; told to subscribers and counted. */
static void
window_break (WindowStream *ws, const char *reason, const char *detail)
{
  DsAcquisition *acq = ws->acq;
  ds_phase_window_break (acq->window);
  if (ws->unpublished)
    ds_frame_counters_drop (&ws->c, DS_DROP_ABORTED, ws->unpublished);
  ws->unpublished = 0;
  memset (ws->confirmed, 0, ws->n * sizeof *ws->confirmed);
  /* The frames after the break are checked as a cycle of their own (templates kept). */
  ds_phase_check_begin_set (&acq->phase_check);
  ws->cycle_whole = FALSE;
  g_mutex_lock (&acq->shared->lock);
  acq->shared->status.window_breaks++;
  g_strlcpy (acq->shared->status.last_window_break, reason, sizeof acq->shared->status.last_window_break);
  g_mutex_unlock (&acq->shared->lock);
  g_autofree char *message = g_strdup_printf ("%s: %s", reason, detail);
  ds_seq_emit (acq->shared, DS_SEQUENCER_EVENT_WINDOW_BROKEN, 0, NULL, NULL, message);
}

/* The window's frames in the order they arrived, with the dark frame: NULL when a copy
 * failed. Acquisition thread, after the job that completed the window. */
static DsRawFrames *
window_raw_frames (WindowStream *ws)
{
  g_autoptr (DsRawFrames) raw = ds_raw_frames_new (ws->n);
  guint64 since = ws->pushes - ws->result_span;
  for (guint64 push = since + 1; push <= ws->pushes; push++)
    for (guint k = 0; k < ws->n; k++)
      if (ws->kept_push[k] == push && !ds_raw_frames_add (raw, k, ws->kept_id[k], ws->kept_ts[k], ws->kept[k], NULL))
        return NULL;
  if (raw->frames->len != ws->n)
    return NULL;
  if (ws->black && !ds_raw_frames_set_black (raw, ws->black, (const guint64 *) ws->black_ids->data,
                                             ws->black_ids->len, NULL))
    return NULL;
  return g_steal_pointer (&raw);
}

static void
publish (WindowStream *ws, DsSeparation *planes, guint k, guint64 frame_id, const DsLastFrameTimes *times)
{
  DsAcquisition *acq = ws->acq;
  gint64 oldest = ws->arrival[k];
  for (guint h = 0; h < ws->n; h++)
    oldest = MIN (oldest, ws->arrival[h]);
  /* Every frame acquired and not dropped since the last result is in this one: this frame, the
   * window's frames since the break, the dark frame of the run's first result. */
  ds_frame_counters_fold_rest (&ws->c);
  ds_seq_account_frames (acq->shared, &ws->c);
  DsResultWindow w = { .frames = ws->n, .span = ws->result_span, .newest_frame_id = frame_id,
                       .since_break = ws->result_since_break };
  g_mutex_lock (&acq->shared->lock);
  acq->shared->status.frame_results++;
  w.breaks = acq->shared->status.window_breaks;
  g_strlcpy (w.last_break, acq->shared->status.last_window_break, sizeof w.last_break);
  g_mutex_unlock (&acq->shared->lock);
  gint64 now = g_get_monotonic_time ();
  DsResult *result = ds_result_new (++acq->next_set_id, planes, acq->planes, &ws->settings, &ws->c, oldest,
                                    ws->arrival[k], now);
  ds_result_set_last_frame_times (result, times);
  ds_result_set_window (result, &w);
  if (ws->kept)
    ds_result_set_raw_frames (result, window_raw_frames (ws));
  memset (&ws->c, 0, sizeof ws->c);
  ws->unpublished = 0;
  ds_seq_emit (acq->shared, DS_SEQUENCER_EVENT_RESULT, 0, result, NULL, NULL);
}

/* Fold thread, at the end of a job whose frame went in (DsFoldJob.window_done): the result the
 * job made is published now, not when the acquisition thread collects the job after the next
 * frame arrived. What publish touches is lent with ws during the job: the counters since the
 * last result (the acquisition thread counts the next frame apart until it collects), the
 * window's frames and the planes; the shared status and the events take their own lock. A
 * result collect would refuse (a failed finalize, a cycle refused as a whole) is left to it. */
static void
window_done (DsFoldJob *job, gpointer data)
{
  WindowStream *ws = data;
  if (!job->finalized || job->fold_error || ws->confirm_error)
    return;
  guint k = job->phase;
  ws->unpublished++;
  ws->arrival[k] = job->frame->host_time_us ? (gint64) job->frame->host_time_us : g_get_monotonic_time ();
  publish (ws, g_steal_pointer (&ws->in_flight_planes), k, job->frame->frame_id, &job->times);
  ws->published_in_job = TRUE;
}

/* Waits for the frame in the worker and accounts for it: a refused frame breaks the window, a
 * good one may publish a result. FALSE with error when the run must fail. */
static gboolean
collect (WindowStream *ws, GError **error)
{
  if (!ws->in_flight)
    return TRUE;
  DsAcquisition *acq = ws->acq;
  DsFoldJob job;
  ds_fold_worker_collect (acq->worker, &job);
  ws->in_flight = FALSE;
  g_autoptr (DsFrame) frame = g_steal_pointer (&ws->in_flight_frame);
  DsSeparation *planes = g_steal_pointer (&ws->in_flight_planes);
  guint k = ws->in_flight_phase;
  if (ws->published_in_job) {
    /* the worker published it (window_done); the device status is read here, by the thread
     * that owns the devices, at most twice a second */
    ws->published_in_job = FALSE;
    ws->retries_left[k] = ws->settings.phase_retries;
    gint64 now = g_get_monotonic_time ();
    if (now - ws->last_refresh_us > G_USEC_PER_SEC / 2) {
      ds_seq_refresh_device_status (acq);
      ws->last_refresh_us = now;
    }
    return TRUE;
  }
  if (job.verdict.reason != DS_DROP_N_REASONS) {
    ds_plane_pool_give (acq->planes, planes);
    ds_frame_counters_drop (&ws->c, job.verdict.reason, 1);
    const char *reason = ds_drop_reason_name (job.verdict.reason);
    GError *why = g_error_new (DS_SEQUENCER_ERROR, DS_SEQUENCER_ERROR_FRAME_REJECTED,
                               "phase %u: frame %" G_GUINT64_FORMAT " dropped (%s): %s", k, frame->frame_id, reason,
                               job.verdict.detail ? job.verdict.detail : "");
    window_break (ws, reason, why->message);
    ws->reapply = ws->reapply || job.verdict.reapply_phase;
    ds_frame_verdict_clear (&job.verdict);
    return retry_or_fail (ws, k, &why, error);
  }
  if (!job.folded) {
    ds_plane_pool_give (acq->planes, planes);
    ds_frame_counters_drop (&ws->c, DS_DROP_ABORTED, 1);
    g_propagate_error (error, job.fold_error);
    return FALSE;
  }
  ws->unpublished++;
  ws->arrival[k] = frame->host_time_us ? (gint64) frame->host_time_us : g_get_monotonic_time ();
  if (job.fold_error) {
    ds_plane_pool_give (acq->planes, planes);
    g_propagate_prefixed_error (error, job.fold_error, "finalize: ");
    return FALSE;
  }
  if (ws->confirm_error) {
    ds_plane_pool_give (acq->planes, planes);
    GError *why = g_error_new (DS_SEQUENCER_ERROR, DS_SEQUENCER_ERROR_FRAME_REJECTED, "%s", ws->confirm_error);
    g_clear_pointer (&ws->confirm_error, g_free);
    window_break (ws, "phase_check", why->message);
    return retry_or_fail (ws, k, &why, error);
  }
  /* a result is published by the worker (window_done) */
  ds_plane_pool_give (acq->planes, planes);
  ws->retries_left[k] = ws->settings.phase_retries;
  return TRUE;
}

/* Hands the frame of phase k to the worker with the planes a result would take. */
static gboolean
submit (WindowStream *ws, guint k, DsFrame *frame, gint64 applied_at, GError **error)
{
  DsAcquisition *acq = ws->acq;
  DsSeparation *planes = ds_plane_pool_take (acq->planes, ws->width, ws->height, error);
  if (!planes) {
    ds_frame_free (frame);
    ds_frame_counters_drop (&ws->c, DS_DROP_ABORTED, 1);
    return FALSE;
  }
  if (ws->settings.verify_phase && k == 0) {
    /* A cycle for the phase check: checked as a whole at phase N-1 unless its frames match
     * the templates one by one. */
    ds_phase_check_begin_set (&acq->phase_check);
    ws->cycle_whole = TRUE;
  }
  ws->in_flight = TRUE;
  ws->in_flight_frame = frame;
  ws->in_flight_phase = k;
  ws->in_flight_planes = planes;
  DsFoldJob job = { .settings = &ws->settings, .phase = k, .frame = frame, .applied_at_us = applied_at,
                    .phase_check = &acq->phase_check, .finalize_into = planes, .window_step = window_step,
                    .window_data = ws, .window_done = window_done };
  ds_fold_worker_submit (acq->worker, &job, FALSE);
  return TRUE;
}

/* Triggers and grabs the frame of phase k. When the camera tells that its exposure is over (it
 * began sending it), the next phase is lit during its transfer, as in the set pipeline:
 * *applied and *applied_at then follow it (a failure to light it is counted, and the loop
 * lights it again before the next trigger). */
static DsFrame *
trigger_and_grab (WindowStream *ws, guint k, DsFrameCounters *c, int *applied, gint64 *applied_at, GError **error)
{
  DsAcquisition *acq = ws->acq;
  guint next = (k + 1) % ws->n;
  guint64 before = ds_seq_frames_begun (acq);
  if (!ds_seq_trigger (acq, c, error))
    return NULL;
  gint64 t = g_get_monotonic_time ();
  if (!ds_seq_wait_exposure_over (acq, before)) {
    guint waited_ms = (guint) ((g_get_monotonic_time () - t) / 1000);
    guint left = acq->dev->grab_timeout_ms > waited_ms ? acq->dev->grab_timeout_ms - waited_ms : 1;
    return ds_seq_grab_within (acq, c, left, error);
  }
  t = g_get_monotonic_time ();
  g_autoptr (GError) early = NULL;
  if (ds_seq_set_phase (acq, next, &early)) {
    ds_seq_stage_add (acq->shared, DS_STAGE_SET_PHASE, t);
    *applied = (int) next;
  } else {
    c->device_errors++;
    *applied = -1;
  }
  DsFrame *frame = ds_seq_grab (acq, c, error);
  /* What was delivered besides this frame is stale; frames of `next` arrive after this. */
  ds_seq_flush_stale (acq, c);
  *applied_at = g_get_monotonic_time ();
  return frame;
}

/* The frames, until a command is queued (TRUE) or the run fails or is cancelled (FALSE with
 * error). */
static gboolean
run_frames (WindowStream *ws, GError **error)
{
  DsAcquisition *acq = ws->acq;
  int applied = -1;
  gint64 applied_at = 0;
  guint k = 0;
  for (;;) {
    if (!ds_seq_check_quit (acq, error))
      return FALSE;
    /* Any command comes first (it may change settings, capture once, stop or release). */
    if (g_async_queue_length (acq->shared->queue) > 0)
      return collect (ws, error);
    if (ws->reapply) {
      applied = -1;
      ws->reapply = FALSE;
    }
    GError *why = NULL;
    /* Counted apart until the frame before is collected: the worker may publish that frame's
     * result meanwhile (window_done), which holds the frames before it, not what happens now. */
    DsFrameCounters fc = { 0 };
    if (applied != (int) k) {
      /* Overlaps with the worker verifying the previous frame. */
      gint64 t = g_get_monotonic_time ();
      if (!ds_seq_set_phase (acq, k, &why)) {
        fc.device_errors++;
        g_prefix_error (&why, "phase %u: illuminator: ", k);
        gboolean collected = collect (ws, error);
        ds_frame_counters_add (&ws->c, &fc);
        if (!collected) {
          g_clear_error (&why);
          return FALSE;
        }
        window_break (ws, "device_error", why->message);
        if (!retry_or_fail (ws, k, &why, error))
          return FALSE;
        continue;
      }
      ds_seq_stage_add (acq->shared, DS_STAGE_SET_PHASE, t);
      ds_seq_flush_stale (acq, &fc);
      applied = (int) k;
      applied_at = g_get_monotonic_time ();
    }
    gint64 frame_applied_at = applied_at;
    DsFrame *frame = trigger_and_grab (ws, k, &fc, &applied, &applied_at, &why);
    gboolean collected = collect (ws, error);
    ds_frame_counters_add (&ws->c, &fc);
    if (!frame) {
      g_prefix_error (&why, "phase %u: camera: ", k);
      /* The frame before got its verdict (and may have published) before the break. */
      if (!collected) {
        g_clear_error (&why);
        return FALSE;
      }
      window_break (ws, "lost", why->message);
      if (!retry_or_fail (ws, k, &why, error))
        return FALSE;
      /* A late buffer of the lost trigger may still arrive: flushed before the next trigger,
       * which takes phase k again. */
      ds_seq_flush_stale (acq, &ws->c);
      continue;
    }
    if (!collected) {
      ds_frame_free (frame); /* acquired, not dropped: aborted with the run */
      return FALSE;
    }
    if (!submit (ws, k, frame, frame_applied_at, error))
      return FALSE;
    k = (k + 1) % ws->n;
  }
}

/* Camera, pattern, dark frame and window for the run, as a set's (set_runner.c). */
static gboolean
setup (WindowStream *ws, GError **error)
{
  DsAcquisition *acq = ws->acq;
  DsCaptureSettings *s = &ws->settings;
  if (acq->phase_check_period != s->period_px)
    ds_phase_check_init (&acq->phase_check, s->period_px, s->phase_tolerance_deg);
  acq->phase_check_period = s->period_px;
  acq->phase_check.tolerance_cycles = s->phase_tolerance_deg / 360.0;
  ds_phase_check_set_pattern (&acq->phase_check, s->pattern == DS_PATTERN_SQUARE, s->duty);
  ds_phase_check_begin_set (&acq->phase_check);
  if (!ds_seq_ensure_camera (acq, s, error)) {
    g_prefix_error (error, "camera: ");
    ds_seq_fatal_device_error (acq, *error);
    return FALSE;
  }
  if (!ds_seq_apply_pattern (acq, s, error)) {
    g_prefix_error (error, "illuminator: ");
    ds_seq_fatal_device_error (acq, *error);
    return FALSE;
  }
  g_autoptr (DsImage) dark = NULL;
  const DsImage *use_dark = NULL;
  if (!ds_seq_dark_for (acq, s, &ws->c, &dark, &use_dark, error))
    return FALSE;
  DsCameraInfo info;
  ds_seq_frame_size (acq, &info, &ws->width, &ws->height);
  DsSeparationParams p;
  ds_capture_settings_separation_params (s, &p);
  if (!acq->window || ws->width != acq->window_width || ws->height != acq->window_height ||
      memcmp (&p, &acq->window_params, sizeof p) != 0) {
    g_clear_pointer (&acq->window, ds_phase_window_free);
    acq->window = ds_phase_window_new (&p, ws->width, ws->height, error);
    if (!acq->window)
      return FALSE;
    acq->window_params = p;
    acq->window_width = ws->width;
    acq->window_height = ws->height;
  }
  if (!ds_phase_window_set_dark (acq->window, use_dark, error))
    return FALSE;
  if (s->save_phases && use_dark) {
    ws->black = ds_image_copy (use_dark, error);
    if (!ws->black)
      return FALSE;
    GArray *ids = dark ? acq->dark_ids : acq->stored_dark_ids;
    ws->black_ids = g_array_copy (ids);
  }
  ds_phase_window_break (acq->window);
  guint region[4];
  ds_seq_camera_region (acq, &info, region);
  s->roi_x = region[0];
  s->roi_y = region[1];
  s->roi_width = region[2];
  s->roi_height = region[3];
  return TRUE;
}

/* The window a run before this one filled is gone (a command ran in between); a break is told
 * when the settings or the sensor region changed, which is what the frames after it differ
 * by. */
static void
note_settings (DsAcquisition *acq, const DsCaptureSettings *s)
{
  const DsCaptureSettings *was = &acq->window_settings;
  gboolean region_same = was->roi_x == s->roi_x && was->roi_y == s->roi_y && was->roi_width == s->roi_width &&
                         was->roi_height == s->roi_height;
  if (acq->window_ran && (!ds_capture_settings_equal (was, s) || !region_same)) {
    g_mutex_lock (&acq->shared->lock);
    acq->shared->status.window_breaks++;
    g_strlcpy (acq->shared->status.last_window_break, "settings", sizeof acq->shared->status.last_window_break);
    g_mutex_unlock (&acq->shared->lock);
    ds_seq_emit (acq->shared, DS_SEQUENCER_EVENT_WINDOW_BROKEN, 0, NULL, NULL,
                 region_same ? "settings: the stream's settings changed (a reload, `set`, or a new start)"
                             : "settings: the camera's region changed (`set`)");
  }
  acq->window_ran = TRUE;
  acq->window_settings = *s;
}

void
ds_seq_run_window_stream (DsAcquisition *acq, const DsCaptureSettings *requested)
{
  WindowStream ws = { .acq = acq, .settings = *requested, .n = requested->phases };
  DsCaptureSettings *s = &ws.settings;
  /* The stripe geometry is the illuminator's, as for a set (set_runner.c). */
  s->pattern = acq->dev->pattern.kind == DS_STRIPES_SINE ? DS_PATTERN_SINE : DS_PATTERN_SQUARE;
  s->period_px = requested->period_override_px > 0 ? requested->period_override_px : acq->dev->pattern.period_px;
  s->duty = acq->dev->pattern.duty;
  s->black_level = acq->dev->pattern.black_level;
  /* Per-frame mode triggers nothing ahead; a frame a set triggered ahead goes down. */
  ds_seq_carry_discard (acq);
  ws.arrival = g_new0 (gint64, ws.n);
  ws.retries_left = g_new (guint, ws.n);
  for (guint k = 0; k < ws.n; k++)
    ws.retries_left[k] = requested->phase_retries;
  ws.confirmed = g_new0 (gboolean, ws.n);
  ws.last_refresh_us = g_get_monotonic_time ();
  if (requested->save_phases) {
    ws.kept = g_new0 (DsImage *, ws.n);
    ws.kept_id = g_new0 (guint64, ws.n);
    ws.kept_ts = g_new0 (guint64, ws.n);
    ws.kept_push = g_new0 (guint64, ws.n);
  }
  g_autoptr (GError) error = NULL;
  gboolean ok = setup (&ws, &error);
  if (ok)
    note_settings (acq, &ws.settings);
  ok = ok && run_frames (&ws, &error);
  if (ws.in_flight) {
    /* The worker must be idle before the window is touched again; its frame is counted. */
    g_autoptr (GError) ignored = NULL;
    collect (&ws, &ignored);
  }
  g_free (ws.confirm_error);
  g_free (ws.arrival);
  g_free (ws.retries_left);
  g_free (ws.confirmed);
  for (guint k = 0; ws.kept && k < ws.n; k++)
    ds_image_free (ws.kept[k]);
  g_free (ws.kept);
  g_free (ws.kept_id);
  g_free (ws.kept_ts);
  g_free (ws.kept_push);
  ds_image_free (ws.black);
  if (ws.black_ids)
    g_array_unref (ws.black_ids);
  if (!ok) {
    if (acq->phase_check.provisional)
      ds_phase_check_abandon (&acq->phase_check);
    ds_seq_account_unfinished (acq->shared, &ws.c, error);
    ds_seq_refresh_device_status (acq);
    ds_seq_emit (acq->shared, DS_SEQUENCER_EVENT_FAILED, 0, NULL, g_steal_pointer (&error), NULL);
    return;
  }
  /* A command came: the window's frames not yet in a result go down with it. */
  ds_frame_counters_abort_rest (&ws.c);
  ds_seq_account_frames (acq->shared, &ws.c);
  ds_seq_refresh_device_status (acq);
}
