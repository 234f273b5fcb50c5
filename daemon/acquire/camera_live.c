/* Live camera settings (camera_live.h): the check against the camera's ranges (any thread), and
 * the `set` command as the acquisition thread runs it, between two sets. */
#include "daemon/acquire/camera_live.h"

#include <math.h>

#include "daemon/acquire/acquisition.h"
#include "daemon/protocol/protocol.h"

gboolean
ds_camera_live_validate (const char *backend, const DsCameraInfo *info, const DsCameraLive *want, GError **error)
{
  if (!(want->exposure_us > 0) || !isfinite (want->exposure_us)) {
    g_set_error (error, DS_PROTOCOL_ERROR, DS_PROTOCOL_ERROR_BAD_ARGUMENT,
                 "%s camera: exposure %g µs is not a positive time", backend, want->exposure_us);
    return FALSE;
  }
  if (info->exposure_max_us > 0 &&
      (want->exposure_us < info->exposure_min_us || want->exposure_us > info->exposure_max_us)) {
    g_set_error (error, DS_PROTOCOL_ERROR, DS_PROTOCOL_ERROR_BAD_ARGUMENT, "%s camera: exposure %g µs outside [%g, %g]",
                 backend, want->exposure_us, info->exposure_min_us, info->exposure_max_us);
    return FALSE;
  }
  if (!info->has_gain && want->gain_db != 0) {
    g_set_error (error, DS_PROTOCOL_ERROR, DS_PROTOCOL_ERROR_BAD_ARGUMENT,
                 "%s camera: gain %g dB asked, the camera has no Gain", backend, want->gain_db);
    return FALSE;
  }
  if (info->has_gain && info->gain_max_db > info->gain_min_db &&
      (want->gain_db < info->gain_min_db || want->gain_db > info->gain_max_db)) {
    g_set_error (error, DS_PROTOCOL_ERROR, DS_PROTOCOL_ERROR_BAD_ARGUMENT, "%s camera: gain %g dB outside [%g, %g]",
                 backend, want->gain_db, info->gain_min_db, info->gain_max_db);
    return FALSE;
  }
  guint sw = info->sensor_width, sh = info->sensor_height;
  if (want->roi_width == 0 || want->roi_height == 0 || (guint64) want->roi_x + want->roi_width > sw ||
      (guint64) want->roi_y + want->roi_height > sh) {
    g_set_error (error, DS_PROTOCOL_ERROR, DS_PROTOCOL_ERROR_BAD_ARGUMENT,
                 "%s camera: ROI %u,%u %ux%u outside the %ux%u sensor", backend, want->roi_x, want->roi_y,
                 want->roi_width, want->roi_height, sw, sh);
    return FALSE;
  }
  return TRUE;
}

void
ds_camera_live_apply_change (DsCameraLive *current, const DsCameraChange *change)
{
  if (change->has_exposure)
    current->exposure_us = change->exposure_us;
  if (change->has_gain)
    current->gain_db = change->gain_db;
  if (change->has_roi) {
    current->roi_x = change->roi_x;
    current->roi_y = change->roi_y;
    current->roi_width = change->roi_width;
    current->roi_height = change->roi_height;
  }
}

/* The camera's settings as the next set without its own exposure and gain takes them: the
 * defaults' exposure and gain, and the region from the devices' camera settings (the whole
 * sensor when none). Acquisition thread, devices open. */
static void
current_live (DsAcquisition *acq, const DsCameraInfo *info, DsCameraLive *out)
{
  g_mutex_lock (&acq->shared->lock);
  out->exposure_us = acq->shared->defaults.exposure_us;
  out->gain_db = acq->shared->defaults.gain_db;
  g_mutex_unlock (&acq->shared->lock);
  guint region[4];
  ds_seq_camera_region (acq, info, region);
  out->roi_x = region[0];
  out->roi_y = region[1];
  out->roi_width = region[2];
  out->roi_height = region[3];
}

void
ds_seq_camera_region (DsAcquisition *acq, const DsCameraInfo *info, guint region[4])
{
  const DsCameraSettings *cs = &acq->dev->camera_settings;
  gboolean whole = cs->roi_width == 0;
  region[0] = whole ? 0 : cs->roi_x;
  region[1] = whole ? 0 : cs->roi_y;
  region[2] = whole ? info->sensor_width : cs->roi_width;
  region[3] = whole ? info->sensor_height : cs->roi_height;
}

void
ds_seq_camera_live_overlay (DsAcquisition *acq)
{
  const DsCameraChange *live = &acq->live_camera;
  g_mutex_lock (&acq->shared->lock);
  if (live->has_exposure)
    acq->shared->defaults.exposure_us = live->exposure_us;
  if (live->has_gain)
    acq->shared->defaults.gain_db = live->gain_db;
  g_mutex_unlock (&acq->shared->lock);
  if (live->has_roi && acq->dev) {
    DsCameraSettings *cs = &acq->dev->camera_settings;
    cs->roi_x = live->roi_x;
    cs->roi_y = live->roi_y;
    cs->roi_width = live->roi_width;
    cs->roi_height = live->roi_height;
  }
}

void
ds_seq_camera_live_report (DsAcquisition *acq)
{
  if (!acq->dev)
    return;
  DsCameraInfo info = { 0 };
  acq->dev->camera->ops->get_info (acq->dev->camera->backend, &info);
  DsCameraLive now;
  current_live (acq, &info, &now);
  g_mutex_lock (&acq->shared->lock);
  acq->shared->status.camera_live = now;
  acq->shared->status.camera_live_known = TRUE;
  g_mutex_unlock (&acq->shared->lock);
}

/* A refusal by the camera itself (a value between the bounds it reported, on no increment of
 * it; a feature it lacks) is the client's argument, as the range check's; a lost camera stays
 * a device error. */
static void
refused_as_argument (GError **error)
{
  if (*error && (*error)->domain == DS_DEVICE_ERROR &&
      ((*error)->code == DS_DEVICE_ERROR_INVALID || (*error)->code == DS_DEVICE_ERROR_UNSUPPORTED)) {
    GError *e = g_error_new (DS_PROTOCOL_ERROR, DS_PROTOCOL_ERROR_BAD_ARGUMENT, "%s", (*error)->message);
    g_clear_error (error);
    *error = e;
  }
}

/* Configures the stopped camera with the devices' settings at this exposure and gain. */
static gboolean
configure (DsAcquisition *acq, double exposure_us, double gain_db, GError **error)
{
  DsCamera *cam = acq->dev->camera;
  DsCameraSettings cs;
  ds_devices_camera_settings (acq->dev, exposure_us, gain_db, &cs);
  ds_seq_blocking (acq->shared, 2 * DS_SEQ_CONTROL_BOUND_MS);
  if (!cam->ops->configure (cam->backend, &cs, error)) {
    acq->camera_configured = FALSE;
    return FALSE;
  }
  acq->camera_configured = TRUE;
  acq->camera_exposure_us = exposure_us;
  acq->camera_gain_db = gain_db;
  return TRUE;
}

/* A new region: frames of another size and other stripe positions. The stripe phase learned for
 * the old region says nothing of the new one (it is learned again at the next set), and the
 * stored dark frame has the old region's size, so it goes. */
static void
forget_region_state (DsAcquisition *acq)
{
  acq->phase_check_period = NAN;
  g_clear_pointer (&acq->dark, ds_image_free);
  g_mutex_lock (&acq->shared->lock);
  acq->shared->status.has_dark = FALSE;
  acq->shared->status.stored_dark = (DsDarkFrameInfo) { 0 };
  acq->shared->status.stored_dark_applies = FALSE;
  g_mutex_unlock (&acq->shared->lock);
}

gboolean
ds_seq_camera_set (DsAcquisition *acq, const DsCameraChange *change, GError **error)
{
  if (!acq->dev) {
    g_set_error (error, DS_SEQUENCER_ERROR, DS_SEQUENCER_ERROR_NOT_READY,
                 "set: the devices are released (another program may hold the camera): send acquire first");
    return FALSE;
  }
  DsCamera *cam = acq->dev->camera;
  DsCameraInfo info = { 0 };
  cam->ops->get_info (cam->backend, &info);
  DsCameraLive before, want;
  current_live (acq, &info, &before);
  want = before;
  ds_camera_live_apply_change (&want, change);
  if (!ds_camera_live_validate (cam->ops->name, &info, &want, error))
    return FALSE;

  /* Between two sets the camera may be started: configuring needs it stopped. */
  if (acq->camera_started) {
    cam->ops->stop (cam->backend);
    acq->camera_started = FALSE;
  }
  DsCameraSettings *cs = &acq->dev->camera_settings;
  DsCameraSettings old_cs = *cs;
  cs->roi_x = want.roi_x;
  cs->roi_y = want.roi_y;
  cs->roi_width = want.roi_width;
  cs->roi_height = want.roi_height;
  if (!configure (acq, want.exposure_us, want.gain_db, error)) {
    /* Nothing changed: the camera goes back to what it had (a lost camera is reconnected
     * before the next command instead). */
    *cs = old_cs;
    ds_seq_fatal_device_error (acq, *error);
    if (!acq->need_reconnect) {
      g_autoptr (GError) back = NULL;
      if (!configure (acq, before.exposure_us, before.gain_db, &back))
        g_warning ("set: the camera did not take its previous settings back: %s", back->message);
    }
    refused_as_argument (error);
    return FALSE;
  }
  gboolean region_changed = want.roi_x != before.roi_x || want.roi_y != before.roi_y ||
                            want.roi_width != before.roi_width || want.roi_height != before.roi_height;
  if (region_changed)
    forget_region_state (acq);

  /* Kept for later reopenings and reloads (ds_seq_camera_live_overlay), and the defaults of the
   * sets that follow, a running stream's included. */
  DsCameraChange *live = &acq->live_camera;
  if (change->has_exposure) {
    live->has_exposure = TRUE;
    live->exposure_us = want.exposure_us;
  }
  if (change->has_gain) {
    live->has_gain = TRUE;
    live->gain_db = want.gain_db;
  }
  if (change->has_roi) {
    live->has_roi = TRUE;
    live->roi_x = want.roi_x;
    live->roi_y = want.roi_y;
    live->roi_width = want.roi_width;
    live->roi_height = want.roi_height;
  }
  ds_seq_camera_live_overlay (acq);
  if (acq->run.mode == DS_RUN_STREAM) {
    acq->run.settings.exposure_us = want.exposure_us;
    acq->run.settings.gain_db = want.gain_db;
  }
  ds_seq_camera_live_report (acq);
  if (!cam->ops->start (cam->backend, error)) {
    ds_seq_fatal_device_error (acq, *error);
    return FALSE;
  }
  acq->camera_started = TRUE;
  return TRUE;
}
