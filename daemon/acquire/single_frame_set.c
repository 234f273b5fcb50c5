/* A single-frame set (settings.single_frame): one frame lit with phase 0, separated from its
 * own stripes (proc/single_frame.h) instead of from N frames in time. Nothing in the scene has
 * to hold still beyond one exposure, so a moving scene leaves no stripe residue; the price is
 * resolution along x, one stripe period, which the result states (settings.single_frame).
 *
 * The frame is not phase-checked: the spatial estimator fits the stripes where they are, so any
 * phase serves; what must hold is that one phase lit the whole exposure, which the illuminator's
 * settle (ds_seq_set_phase) and the stale check here ensure. A frame that fails is re-acquired
 * under the one retry rule (retry.c). */
#include <math.h>
#include <string.h>

#include "daemon/acquire/acquisition.h"

/* The plan for these settings and this frame size, kept from the set before when they match. */
static gboolean
prepare_plan (DsAcquisition *acq, const DsCaptureSettings *s, guint w, guint h, GError **error)
{
  DsSeparationParams p;
  ds_capture_settings_separation_params (s, &p);
  if (acq->single && w == acq->single_width && h == acq->single_height &&
      memcmp (&p, &acq->single_params, sizeof p) == 0)
    return TRUE;
  g_clear_pointer (&acq->single, ds_single_frame_free);
  /* Refusals (robust, a period the window cannot hold) are the separation's, as a phase
   * set's are. */
  acq->single = ds_single_frame_new (&p, w, h, error);
  if (!acq->single)
    return FALSE;
  acq->single_params = p;
  acq->single_width = w;
  acq->single_height = h;
  return TRUE;
}

/* Phase 0 lit and one frame exposed wholly after it, or NULL with error once the retries are
 * spent (or a device fails for good). */
static DsFrame *
lit_frame (DsAcquisition *acq, const DsCaptureSettings *s, DsFrameCounters *c, GError **error)
{
  guint retries_left = s->phase_retries;
  for (;;) {
    GError *why = NULL;
    if (!ds_seq_check_quit (acq, error))
      return NULL;
    if (!ds_seq_set_phase (acq, 0, &why)) {
      c->device_errors++;
      g_prefix_error (&why, "illuminator: ");
      if (!ds_seq_retry_or_fail (acq, &retries_left, c, &why, error, "single frame"))
        return NULL;
      continue;
    }
    ds_seq_flush_stale (acq, c);
    gint64 lit_at = g_get_monotonic_time ();
    DsFrame *f = ds_seq_trigger_and_grab (acq, c, &why);
    if (f && f->host_time_us != 0 && (gint64) f->host_time_us < lit_at) {
      ds_frame_counters_drop (c, DS_DROP_STALE, 1);
      why = g_error_new (DS_SEQUENCER_ERROR, DS_SEQUENCER_ERROR_FRAME_REJECTED, "stale frame");
      g_clear_pointer (&f, ds_frame_free);
    }
    if (f)
      return f;
    if (!ds_seq_retry_or_fail (acq, &retries_left, c, &why, error, "single frame"))
      return NULL;
  }
}

DsSeparation *
ds_seq_acquire_single_frame (DsAcquisition *acq, const DsCaptureSettings *s, const DsImage *dark, guint width,
                             guint height, DsFrameCounters *c, gint64 *last_frame_us, GError **error)
{
  /* No raw frames are kept: none left from an earlier set may go out with this result. */
  g_clear_pointer (&acq->raw, ds_raw_frames_free);
  acq->raw_incomplete = FALSE;
  if (!prepare_plan (acq, s, width, height, error))
    return NULL;
  /* The planes before the frame, as for a phase set: no page fault after it. */
  DsSeparation *planes = ds_plane_pool_take (acq->planes, width, height, error);
  if (!planes)
    return NULL;
  g_autoptr (DsFrame) frame = lit_frame (acq, s, c, error);
  if (!frame) {
    ds_plane_pool_give (acq->planes, planes);
    return NULL;
  }
  gint64 arrived = frame->host_time_us ? (gint64) frame->host_time_us : g_get_monotonic_time ();
  if (!ds_single_frame_separate_into (acq->single, frame->image, dark, planes, error)) {
    /* A frame of another size than the camera reported, or a dark frame of another shape: the
     * caller counts the frame as aborted with the set. */
    ds_plane_pool_give (acq->planes, planes);
    return NULL;
  }
  acq->last_frame_us = *last_frame_us = arrived;
  /* No fold job ran: the result has no per-job stamps of its last frame. */
  memset (&acq->last_frame_times, 0, sizeof acq->last_frame_times);
  return planes;
}
