#include "drivers/aravis/aravis_camera.h"

#include <arv.h>
#include <dirent.h>
#include <math.h>
#include <netinet/in.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>

#include "drivers/aravis/device_watch.h"
#include "proc/pixfmt.h"

typedef struct {
  char *address;           /* what the caller opened, used again by reconnect */
  DsAravisStreamOptions options;
  guint capped_said_for;   /* the payload whose capped receive buffer was logged (once each) */
  ArvCamera *camera;
  DsArvDeviceWatch *watch; /* our reference to the camera's device and its "control-lost" */
  ArvStream *stream;
  guint stream_payload;    /* payload the pool was allocated for */
  gboolean stream_running; /* its receiving thread runs (Aravis asserts on a double stop) */
  gboolean lost;           /* the camera stopped answering (seen here; Aravis's report: watch) */
  gboolean configured, started;
  DsCameraSettings settings;
  DsPixelFormat fmt;
  double exposure_us, gain_db; /* read back after configure */
  DsFrameIdTracker ids;
  DsCameraStats stats;     /* missing_packets / resend_requests: of streams already closed */
  DsCameraInfo info;
  DsFramePool *frames;     /* frame headers and unpacked images, reused */
  /* Frames whose first packet arrived (the stream thread's START_BUFFER), for frames_begun:
   * written by the stream thread, read by the acquisition thread. */
  GMutex begun_lock;
  GCond begun_cond;
  guint64 begun;
} AravisCam;

/* The stream's receiving thread: a new frame's first packet arrived. Its own lock only: the
 * camera may not be touched from this thread (arvstream.h). */
static void
on_stream_event (void *data, ArvStreamCallbackType type, ArvBuffer *buffer)
{
  (void) buffer; /* NULL for START_BUFFER in Aravis 0.8.26 */
  AravisCam *c = data;
  if (type != ARV_STREAM_CALLBACK_TYPE_START_BUFFER)
    return;
  g_mutex_lock (&c->begun_lock);
  c->begun++;
  g_cond_broadcast (&c->begun_cond);
  g_mutex_unlock (&c->begun_lock);
}

/* What a stream buffer held when the backend last took it from the stream. Aravis 0.8.26 can
 * hand back a buffer it never filled: a packet that begins no frame it can size (content it
 * cannot take, or any packet at all reaching the receiving thread, such as, as root, one of
 * loopback's other packets caught by the packet socket before its filter is attached) takes a
 * buffer from the input queue and puts it straight into the output queue, as it was: cleared if
 * new, else with the status, frame id and pixels of the frame it carried before
 * (arvgvstream.c, _find_frame_data). Such a buffer is no frame: neither grabbed nor flushed as
 * one (it was counted as a stale frame, or would come back as a copy of an old frame). */
typedef struct {
  ArvBufferStatus status;
  guint64 frame_id, system_timestamp;
} BufferSeen;

G_DEFINE_QUARK (ds-aravis-buffer-seen, buffer_seen)

/* TRUE when buf holds what the stream filled since the backend last took it: not cleared, and
 * not exactly as it was then (status, frame id and the host time of its leader). Records what
 * it holds now. */
static gboolean
freshly_filled (ArvBuffer *buf, guint64 *previous_id)
{
  BufferSeen now = { arv_buffer_get_status (buf), arv_buffer_get_frame_id (buf),
                     arv_buffer_get_system_timestamp (buf) };
  BufferSeen *seen = g_object_get_qdata (G_OBJECT (buf), buffer_seen_quark ());
  if (previous_id)
    *previous_id = seen ? seen->frame_id : 0;
  gboolean fresh = now.status != ARV_BUFFER_STATUS_CLEARED &&
                   !(seen && seen->status == now.status && seen->frame_id == now.frame_id &&
                     seen->system_timestamp == now.system_timestamp);
  if (seen)
    *seen = now;
  return fresh;
}

/* The id of a filled buffer, 0 when it carries none of its own: Aravis writes a buffer's frame id
 * from the frame's leader only (arvgvstream.c, _process_data_leader), so a frame whose leader
 * was lost comes back (not whole) with the id of the frame the buffer held before, or 0 if it
 * held none. That id is not this frame's: the frame counts as lost with its id unseen. A whole
 * frame had its leader. */
static guint64
own_frame_id (ArvBuffer *buf, guint64 previous_id)
{
  guint64 id = arv_buffer_get_frame_id (buf);
  if (arv_buffer_get_status (buf) != ARV_BUFFER_STATUS_SUCCESS && id == previous_id)
    return 0;
  return id;
}

/* Lost: seen by the backend (a command or a frame unanswered) or reported by Aravis. */
static gboolean
camera_lost (AravisCam *c)
{
  return c->lost || (c->watch && ds_arv_device_watch_lost (c->watch));
}

/* Statistics of the live stream (GV streams only: other stream types lack these infos). */
static void
stream_packet_stats (AravisCam *c, guint64 *missing, guint64 *resend)
{
  *missing = *resend = 0;
  if (c->stream && ARV_IS_GV_STREAM (c->stream)) {
    *missing = arv_stream_get_info_uint64_by_name (c->stream, "n_missing_packets");
    *resend = arv_stream_get_info_uint64_by_name (c->stream, "n_resend_requests");
  }
}

static void
destroy_stream (AravisCam *c)
{
  if (!c->stream)
    return;
  guint64 missing, resend;
  stream_packet_stats (c, &missing, &resend);
  c->stats.missing_packets += missing;
  c->stats.resend_requests += resend;
  /* The GV stream's finalize stops its thread unconditionally (and asserts that it runs). */
  if (!c->stream_running)
    arv_stream_start_thread (c->stream);
  c->stream_running = FALSE;
  g_clear_object (&c->stream); /* frees the buffers of both queues */
  c->stream_payload = 0;
}

static void
close_device (AravisCam *c)
{
  destroy_stream (c);
  g_clear_object (&c->camera);
  /* Never the device's finalize on Aravis's heartbeat thread, which it joins: device_watch.h */
  g_clear_pointer (&c->watch, ds_arv_device_watch_release);
  c->started = FALSE;
}

static gboolean
fail (GError **error, DsDeviceError code, GError *cause, const char *fmt, ...) G_GNUC_PRINTF (4, 5);

/* Sets a DS_CAMERA_ERROR whose message ends with Aravis's own message, and frees cause. */
static gboolean
fail (GError **error, DsDeviceError code, GError *cause, const char *fmt, ...)
{
  va_list ap;
  va_start (ap, fmt);
  g_autofree char *msg = g_strdup_vprintf (fmt, ap);
  va_end (ap);
  g_set_error (error, DS_CAMERA_ERROR, code, "aravis camera: %s%s%s", msg, cause ? ": " : "",
               cause ? cause->message : "");
  g_clear_error (&cause);
  return FALSE;
}

/* What the camera allows, for diagnostics (--check --probe); a feature it lacks or does not
 * answer about stays empty: configure is what refuses a setting. */
static void
read_limits (ArvCamera *cam, DsCameraInfo *info)
{
  guint n = 0;
  const char **formats = arv_camera_dup_available_pixel_formats_as_strings (cam, &n, NULL);
  for (guint i = 0; formats && i < n; i++) {
    if (i)
      g_strlcat (info->pixel_formats, ", ", sizeof info->pixel_formats);
    g_strlcat (info->pixel_formats, formats[i], sizeof info->pixel_formats);
  }
  g_free (formats);
  GError *e = NULL;
  info->has_gain = arv_camera_is_gain_available (cam, NULL);
  if (info->has_gain) {
    arv_camera_get_gain_bounds (cam, &info->gain_min_db, &info->gain_max_db, &e);
    g_clear_error (&e);
  }
  arv_camera_get_exposure_time_bounds (cam, &info->exposure_min_us, &info->exposure_max_us, &e);
  g_clear_error (&e);
  /* SFNC's SensorPixelWidth is the physical pitch in µm; optional, and many cameras lack it. */
  if (arv_camera_is_feature_available (cam, "SensorPixelWidth", NULL)) {
    double pitch = arv_camera_get_float (cam, "SensorPixelWidth", &e);
    info->pixel_pitch_um = e == NULL && pitch > 0 && pitch < 1000 ? pitch : 0;
    g_clear_error (&e);
  }
}

static gboolean
open_device (AravisCam *c, GError **error)
{
  GError *e = NULL;
  ArvCamera *cam = arv_camera_new (c->address, &e);
  if (!cam)
    return fail (error, DS_DEVICE_ERROR_DISCONNECTED, e, "no camera answers at \"%s\"", c->address);
  c->camera = cam;
  c->lost = FALSE;
  /* A camera may still be acquiring for a session that is gone (ours before a reconnect, or a
   * crashed one): it would keep streaming to that session's port. Stopping first makes the
   * next AcquisitionStart take the stream channel as configured now. */
  arv_camera_stop_acquisition (cam, NULL);
  c->watch = ds_arv_device_watch_new (arv_camera_get_device (cam));
  memset (&c->info, 0, sizeof c->info);
  const char *s;
  if ((s = arv_camera_get_vendor_name (cam, NULL)))
    g_strlcpy (c->info.vendor, s, sizeof c->info.vendor);
  if ((s = arv_camera_get_model_name (cam, NULL)))
    g_strlcpy (c->info.model, s, sizeof c->info.model);
  if ((s = arv_camera_get_device_serial_number (cam, NULL)))
    g_strlcpy (c->info.serial, s, sizeof c->info.serial);
  g_strlcpy (c->info.address, c->address, sizeof c->info.address);
  gint w = 0, h = 0;
  arv_camera_get_sensor_size (cam, &w, &h, NULL);
  c->info.sensor_width = (guint) MAX (w, 0);
  c->info.sensor_height = (guint) MAX (h, 0);
  read_limits (cam, &c->info);
  /* GigE Vision 1.x block ids are 16 bits; other transports count with 64. */
  ds_frame_id_tracker_init (&c->ids, arv_camera_is_gv_device (cam) ? 16 : 64);
  return TRUE;
}

static gboolean
check_connected (AravisCam *c, GError **error)
{
  if (!c->camera || camera_lost (c))
    return fail (error, DS_DEVICE_ERROR_DISCONNECTED, NULL, "control of \"%s\" lost: reconnect",
                 c->address);
  return TRUE;
}

/* Aravis errors on a live link: a GVCP timeout means the camera stopped answering. */
static DsDeviceError
code_of (const GError *e)
{
  if (e && e->domain == ARV_DEVICE_ERROR &&
      (e->code == ARV_DEVICE_ERROR_TIMEOUT || e->code == ARV_DEVICE_ERROR_NOT_CONNECTED))
    return DS_DEVICE_ERROR_TIMEOUT;
  return DS_DEVICE_ERROR_INVALID;
}

/* What the camera offers ("Mono8, Mono16"), so that a refusal says what is allowed; the
 * array is Aravis's (freed here), the strings are not. */
static char *
offered (const char **entries, guint n)
{
  if (!entries || n == 0) {
    g_free (entries);
    return g_strdup ("the camera lists none");
  }
  GString *out = g_string_new ("the camera offers ");
  for (guint i = 0; i < n; i++)
    g_string_append_printf (out, "%s%s", i ? ", " : "", entries[i]);
  g_free (entries);
  return g_string_free (out, FALSE);
}

static gboolean
apply_settings (AravisCam *c, const DsCameraSettings *s, GError **error)
{
  GError *e = NULL;
  DsPixelFormat fmt;
  if (!ds_pixfmt_from_name (s->pixel_format, &fmt))
    return fail (error, DS_DEVICE_ERROR_INVALID, NULL,
                 "pixel format \"%s\" unknown (Mono8, Mono10, Mono12, Mono16, Mono10p, Mono12p, "
                 "Mono12Packed)", s->pixel_format);
  ArvCamera *cam = c->camera;
  arv_camera_set_acquisition_mode (cam, ARV_ACQUISITION_MODE_CONTINUOUS, &e);
  if (e)
    return fail (error, code_of (e), e, "AcquisitionMode Continuous");
  arv_camera_set_pixel_format_from_string (cam, ds_pixfmt_name (fmt), &e);
  if (e) {
    guint n = 0;
    const char **formats = arv_camera_dup_available_pixel_formats_as_strings (cam, &n, NULL);
    g_autofree char *allowed = offered (formats, n);
    return fail (error, e->domain == ARV_DEVICE_ERROR ? code_of (e) : DS_DEVICE_ERROR_UNSUPPORTED, e,
                 "PixelFormat %s refused (%s)", ds_pixfmt_name (fmt), allowed);
  }

  guint sw = c->info.sensor_width, sh = c->info.sensor_height;
  guint x = s->roi_x, y = s->roi_y, w = s->roi_width, h = s->roi_height;
  if (w == 0) {
    x = y = 0;
    w = sw;
    h = sh;
  }
  if (h == 0 || (guint64) x + w > sw || (guint64) y + h > sh)
    return fail (error, DS_DEVICE_ERROR_INVALID, NULL, "ROI %u,%u %ux%u outside the %ux%u sensor", x, y,
                 w, h, sw, sh);
  /* Offsets can only grow once the size leaves room: shrink first. */
  arv_camera_set_region (cam, 0, 0, (gint) w, (gint) h, &e);
  if (!e)
    arv_camera_set_region (cam, (gint) x, (gint) y, (gint) w, (gint) h, &e);
  if (e)
    return fail (error, code_of (e), e, "ROI %u,%u %ux%u", x, y, w, h);
  gint rx = 0, ry = 0, rw = 0, rh = 0;
  arv_camera_get_region (cam, &rx, &ry, &rw, &rh, &e);
  if (e)
    return fail (error, code_of (e), e, "reading ROI back");
  if ((guint) rx != x || (guint) ry != y || (guint) rw != w || (guint) rh != h)
    return fail (error, DS_DEVICE_ERROR_INVALID, NULL,
                 "ROI %u,%u %ux%u not on the camera's increments (it applied %d,%d %dx%d)", x, y, w, h,
                 rx, ry, rw, rh);

  double lo = 0, hi = 0;
  arv_camera_get_exposure_time_bounds (cam, &lo, &hi, &e);
  if (e)
    return fail (error, code_of (e), e, "ExposureTime bounds");
  if (!(s->exposure_us >= lo && s->exposure_us <= hi))
    return fail (error, DS_DEVICE_ERROR_INVALID, NULL, "exposure %g µs outside [%g, %g]", s->exposure_us,
                 lo, hi);
  if (arv_camera_is_exposure_auto_available (cam, NULL))
    arv_camera_set_exposure_time_auto (cam, ARV_AUTO_OFF, NULL);
  arv_camera_set_exposure_time (cam, s->exposure_us, &e);
  if (e)
    return fail (error, code_of (e), e, "ExposureTime %g µs", s->exposure_us);
  c->exposure_us = arv_camera_get_exposure_time (cam, NULL);

  c->gain_db = 0;
  if (arv_camera_is_gain_available (cam, NULL)) {
    arv_camera_get_gain_bounds (cam, &lo, &hi, &e);
    if (e)
      return fail (error, code_of (e), e, "Gain bounds");
    if (!(s->gain_db >= lo && s->gain_db <= hi))
      return fail (error, DS_DEVICE_ERROR_INVALID, NULL, "gain %g dB outside [%g, %g]", s->gain_db, lo,
                   hi);
    if (arv_camera_is_gain_auto_available (cam, NULL))
      arv_camera_set_gain_auto (cam, ARV_AUTO_OFF, NULL);
    arv_camera_set_gain (cam, s->gain_db, &e);
    if (e)
      return fail (error, code_of (e), e, "Gain %g dB", s->gain_db);
    c->gain_db = arv_camera_get_gain (cam, NULL);
  } else if (s->gain_db != 0)
    return fail (error, DS_DEVICE_ERROR_UNSUPPORTED, NULL, "gain %g dB asked, the camera has no Gain",
                 s->gain_db);

  g_autofree char *source = s->trigger_source == DS_CAMERA_TRIGGER_LINE
                                ? g_strdup_printf ("Line%u", s->trigger_line)
                                : g_strdup ("Software");
  /* arv_camera_set_trigger turns every other trigger off, then FrameStart: Mode On, rising
   * edge, this source. */
  arv_camera_set_trigger (cam, source, &e);
  if (e) {
    guint n = 0;
    const char **sources = arv_camera_dup_available_trigger_sources (cam, &n, NULL);
    g_autofree char *allowed = offered (sources, n);
    return fail (error, e->domain == ARV_DEVICE_ERROR ? code_of (e) : DS_DEVICE_ERROR_UNSUPPORTED, e,
                 "TriggerSource %s refused (%s)", source, allowed);
  }
  /* The largest GVSP packet the path carries (jumbo frames where the NIC has them): fewer
   * packets per frame, fewer to lose. Best effort: the camera's default still works. */
  if (arv_camera_is_gv_device (cam)) {
    arv_camera_gv_auto_packet_size (cam, &e);
    if (e)
      g_debug ("aravis camera %s: packet size negotiation failed: %s", c->address, e->message);
    g_clear_error (&e);
    /* Worth knowing when rates differ: a frame takes payload / packet size packets. */
    g_message ("aravis camera %s: GVSP packet size %u bytes", c->address,
               arv_camera_gv_get_packet_size (cam, NULL));
  }
  c->fmt = fmt;
  return TRUE;
}

static gboolean
cam_configure (gpointer b, const DsCameraSettings *s, GError **error)
{
  AravisCam *c = b;
  if (!check_connected (c, error))
    return FALSE;
  if (c->started)
    return fail (error, DS_DEVICE_ERROR_INVALID, NULL, "configure while acquiring: stop first");
  /* A new configuration gets a new pool: payload and packet size may change, and the GV stream
   * takes them at creation. stop/start without configure keeps the pool. */
  destroy_stream (c);
  if (!apply_settings (c, s, error)) {
    c->configured = FALSE;
    return FALSE;
  }
  c->settings = *s;
  c->configured = TRUE;
  return TRUE;
}

/* The kernel grants a receive buffer up to net.core.rmem_max without a word: say what that
 * leaves, since a buffer short of a frame loses packets whenever the stream's thread waits for
 * a CPU (docs/drivers.md). Once per payload: every capture configures a new stream. Unreadable
 * (no procfs): nothing to say. */
static void
say_if_capped (AravisCam *c, guint payload, gsize want)
{
  g_autofree char *text = NULL;
  if (c->capped_said_for == payload || !g_file_get_contents ("/proc/sys/net/core/rmem_max", &text, NULL, NULL))
    return;
  guint64 cap = g_ascii_strtoull (text, NULL, 10);
  if (cap == 0 || cap >= want)
    return;
  c->capped_said_for = payload;
  g_message ("aravis camera %s: the UDP receive buffer holds %.2f frames of %u bytes, not the %u of "
             "[camera] receive-buffer-frames: net.core.rmem_max (%" G_GUINT64_FORMAT " bytes) caps it; "
             "raise it to at least %" G_GSIZE_FORMAT " (the package's 60-descatter-gige.conf sets 64 MiB)",
             c->address, (double) cap / payload, payload, c->options.receive_buffer_frames, cap, want);
}

static gboolean
create_pool (AravisCam *c, guint payload, GError **error)
{
  GError *e = NULL;
  ArvStream *stream = arv_camera_create_stream (c->camera, on_stream_event, c, &e);
  if (!stream)
    return fail (error, code_of (e) == DS_DEVICE_ERROR_TIMEOUT ? DS_DEVICE_ERROR_DISCONNECTED
                                                               : DS_DEVICE_ERROR_FAULT,
                 e, "creating the stream");
  if (ARV_IS_GV_STREAM (stream)) {
    gsize want = (gsize) payload * c->options.receive_buffer_frames;
    g_object_set (stream, "socket-buffer", ARV_GV_STREAM_SOCKET_BUFFER_FIXED, "socket-buffer-size",
                  (int) MIN (want, (gsize) G_MAXINT), "frame-retention", c->options.frame_retention_ms * 1000,
                  "packet-resend", ARV_GV_STREAM_PACKET_RESEND_ALWAYS, NULL);
    say_if_capped (c, payload, want);
  }
  /* Each buffer knows its stream (user data), so that a frame lending it can give it back. */
  for (guint i = 0; i < c->options.n_buffers; i++) {
    ArvBuffer *buf = arv_buffer_new_full (payload, NULL, stream, NULL);
    BufferSeen *seen = g_new (BufferSeen, 1);
    *seen = (BufferSeen) { ARV_BUFFER_STATUS_CLEARED, 0, 0 };
    g_object_set_qdata_full (G_OBJECT (buf), buffer_seen_quark (), seen, g_free);
    arv_stream_push_buffer (stream, buf);
  }
  c->stream = stream;
  c->stream_payload = payload;
  c->stream_running = TRUE; /* created streams start receiving at once */
  return TRUE;
}

/* Every buffer the stream delivered goes back to its input queue. Their ids still count for
 * continuity: a flushed frame is accounted for by the caller, not a gap. */
static guint
drain_output (AravisCam *c)
{
  guint n = 0;
  ArvBuffer *buf;
  while (c->stream && (buf = arv_stream_try_pop_buffer (c->stream))) {
    guint64 previous_id;
    if (!freshly_filled (buf, &previous_id)) {
      arv_stream_push_buffer (c->stream, buf);
      c->stats.unfilled_buffers++;
      continue;
    }
    guint64 raw_id = own_frame_id (buf, previous_id);
    guint32 skipped = 0;
    if (raw_id) {
      ds_frame_id_tracker_update (&c->ids, raw_id, &skipped);
      c->stats.ids_skipped += skipped;
    } else
      ds_frame_id_tracker_note_lost (&c->ids); /* flushed (counted), its id unseen */
    arv_stream_push_buffer (c->stream, buf);
    n++;
  }
  return n;
}

static gboolean
cam_start (gpointer b, GError **error)
{
  AravisCam *c = b;
  if (!check_connected (c, error))
    return FALSE;
  if (!c->configured)
    return fail (error, DS_DEVICE_ERROR_INVALID, NULL, "start before configure");
  if (c->started)
    return TRUE;
  GError *e = NULL;
  guint payload = arv_camera_get_payload (c->camera, &e);
  if (e)
    return fail (error, code_of (e), e, "PayloadSize");
  if (c->stream && c->stream_payload != payload)
    destroy_stream (c); /* the camera changed its payload on its own */
  if (!c->stream) {
    if (!create_pool (c, payload, error))
      return FALSE;
  } else if (!c->stream_running) {
    arv_stream_start_thread (c->stream);
    c->stream_running = TRUE;
  }
  arv_camera_start_acquisition (c->camera, &e);
  if (e) {
    arv_stream_stop_thread (c->stream, FALSE);
    c->stream_running = FALSE;
    drain_output (c);
    return fail (error, code_of (e), e, "AcquisitionStart");
  }
  c->started = TRUE;
  return TRUE;
}

static void
cam_stop (gpointer b)
{
  AravisCam *c = b;
  if (!c->started)
    return;
  if (c->camera && !camera_lost (c))
    arv_camera_stop_acquisition (c->camera, NULL);
  /* Stopping the thread hands frames in progress to the output queue; all go back to the
   * input queue, so the pool is whole while stopped. */
  if (c->stream && c->stream_running) {
    arv_stream_stop_thread (c->stream, FALSE);
    c->stream_running = FALSE;
  }
  drain_output (c);
  c->started = FALSE;
}

/* A frame or a command timed out: is the camera still there? One read on the control
 * channel (register 0: the GigE Vision bootstrap's Version, GenCP's on USB3 Vision) answers
 * within Aravis's control timeout; a camera that does not answer is lost, and says so now
 * (DISCONNECTED) instead of through retries that each wait a grab timeout until Aravis's
 * heartbeat gives up (a camera unplug took 10-13 s to show, longer than the watchdog). */
static gboolean
still_there (AravisCam *c)
{
  if (camera_lost (c))
    return FALSE;
  GError *e = NULL;
  guint32 version = 0;
  arv_device_read_register (arv_camera_get_device (c->camera), 0x0000, &version, &e);
  if (!e)
    return TRUE;
  gboolean gone = code_of (e) == DS_DEVICE_ERROR_TIMEOUT;
  g_error_free (e);
  if (gone)
    c->lost = TRUE;
  return !gone;
}

static gboolean
cam_trigger (gpointer b, GError **error)
{
  AravisCam *c = b;
  if (!check_connected (c, error))
    return FALSE;
  if (!c->started)
    return fail (error, DS_DEVICE_ERROR_INVALID, NULL, "trigger before start");
  if (c->settings.trigger_source == DS_CAMERA_TRIGGER_LINE)
    return fail (error, DS_DEVICE_ERROR_INVALID, NULL,
                 "triggered by Line%u, not by software: pulse the trigger device",
                 c->settings.trigger_line);
  GError *e = NULL;
  arv_camera_software_trigger (c->camera, &e);
  /* A control command that timed out went unanswered through all of Aravis's retries: the
   * camera is gone (asking it again would only wait as long once more). */
  if (e && code_of (e) == DS_DEVICE_ERROR_TIMEOUT) {
    c->lost = TRUE;
    return fail (error, DS_DEVICE_ERROR_DISCONNECTED, e, "TriggerSoftware: \"%s\" does not answer: lost",
                 c->address);
  }
  if (e)
    return fail (error, code_of (e), e, "TriggerSoftware");
  return TRUE;
}

static const char *
status_name (ArvBufferStatus st)
{
  switch (st) {
  case ARV_BUFFER_STATUS_SUCCESS: return "success";
  case ARV_BUFFER_STATUS_CLEARED: return "cleared";
  case ARV_BUFFER_STATUS_TIMEOUT: return "timeout (frame retention expired)";
  case ARV_BUFFER_STATUS_MISSING_PACKETS: return "missing packets";
  case ARV_BUFFER_STATUS_WRONG_PACKET_ID: return "wrong packet id";
  case ARV_BUFFER_STATUS_SIZE_MISMATCH: return "size mismatch";
  case ARV_BUFFER_STATUS_FILLING: return "still filling";
  case ARV_BUFFER_STATUS_ABORTED: return "aborted";
  default: return "unknown";
  }
}

/* A lent buffer comes back (ds_frame_free on the acquisition thread): into its stream's input
 * queue, whatever became of the backend's stream pointer meanwhile; the frame held a
 * reference on the stream. */
static void
return_buffer (gpointer data)
{
  ArvBuffer *buf = data;
  ArvStream *stream = ARV_STREAM ((gpointer) arv_buffer_get_user_data (buf));
  arv_stream_push_buffer (stream, buf);
  g_object_unref (stream);
}

static DsFrame *
cam_grab (gpointer b, guint timeout_ms, GError **error)
{
  AravisCam *c = b;
  if (!check_connected (c, error))
    return NULL;
  if (!c->started) {
    fail (error, DS_DEVICE_ERROR_INVALID, NULL, "grab before start");
    return NULL;
  }
  gint64 deadline = g_get_monotonic_time () + (gint64) timeout_ms * 1000;
  ArvBuffer *buf;
  guint64 previous_id = 0;
  for (;;) {
    gint64 left = MAX (deadline - g_get_monotonic_time (), 0);
    buf = arv_stream_timeout_pop_buffer (c->stream, (guint64) left);
    if (!buf || freshly_filled (buf, &previous_id))
      break;
    arv_stream_push_buffer (c->stream, buf); /* no frame: wait on for one */
    c->stats.unfilled_buffers++;
  }
  if (!buf) {
    if (!check_connected (c, error))
      return NULL;
    c->stats.timeouts++;
    /* Counted as a timeout: if the trigger's frame went, its id is missing from now on. */
    ds_frame_id_tracker_note_lost (&c->ids);
    if (!still_there (c))
      fail (error, DS_DEVICE_ERROR_DISCONNECTED, NULL,
            "no frame within %u ms, and \"%s\" does not answer on its control channel: lost", timeout_ms,
            c->address);
    else
      fail (error, DS_DEVICE_ERROR_TIMEOUT, NULL, "no frame within %u ms", timeout_ms);
    return NULL;
  }
  ArvBufferStatus st = arv_buffer_get_status (buf);
  guint64 raw_id = own_frame_id (buf, previous_id);
  guint32 skipped = 0;
  guint64 id = 0;
  if (raw_id)
    id = ds_frame_id_tracker_update (&c->ids, raw_id, &skipped);
  else
    ds_frame_id_tracker_note_lost (&c->ids); /* counted below as incomplete, its id unseen */
  c->stats.ids_skipped += skipped;
  if (st != ARV_BUFFER_STATUS_SUCCESS) {
    arv_stream_push_buffer (c->stream, buf);
    c->stats.failures++;
    /* Every failed buffer is a frame that exists but is not whole (Aravis's TIMEOUT status is
     * a frame whose missing packets never came): INCOMPLETE. TIMEOUT is kept for "no frame". */
    if (raw_id)
      fail (error, DS_DEVICE_ERROR_INCOMPLETE, NULL, "frame %" G_GUINT64_FORMAT ": %s", raw_id,
            status_name (st));
    else
      fail (error, DS_DEVICE_ERROR_INCOMPLETE, NULL, "a frame without its leader (id unknown): %s",
            status_name (st));
    return NULL;
  }
  DsPixelFormat fmt;
  guint32 pfnc = (guint32) arv_buffer_get_image_pixel_format (buf);
  gint w = arv_buffer_get_image_width (buf), h = arv_buffer_get_image_height (buf);
  size_t size = 0;
  const void *data = arv_buffer_get_image_data (buf, &size);
  if (!ds_pixfmt_from_pfnc (pfnc, &fmt) || w <= 0 || h <= 0 || !data) {
    arv_stream_push_buffer (c->stream, buf);
    c->stats.failures++;
    fail (error, DS_DEVICE_ERROR_INVALID, NULL,
          "frame %" G_GUINT64_FORMAT ": pixel format 0x%08x %dx%d is not a monochrome image", raw_id,
          pfnc, w, h);
    return NULL;
  }
  guint64 ts = arv_buffer_get_timestamp (buf);
  if (!ts)
    ts = arv_buffer_get_system_timestamp (buf);
  DsFrame *f = NULL;
  gsize bytes = (fmt == DS_PIXFMT_MONO8 ? 1u : 2u) * (gsize) w;
  if ((fmt == DS_PIXFMT_MONO8 || fmt == DS_PIXFMT_MONO16) && G_BYTE_ORDER == G_LITTLE_ENDIAN &&
      size >= bytes * (gsize) h) {
    /* The samples are already what DsImage holds: fold straight from the camera's buffer,
     * which goes back to the stream when the frame is freed. */
    ArvStream *stream = ARV_STREAM ((gpointer) arv_buffer_get_user_data (buf));
    g_object_ref (stream);
    f = ds_frame_pool_take_borrowed (c->frames, ds_pixfmt_sample_type (fmt),
                                     (guint) w, (guint) h, bytes, fmt == DS_PIXFMT_MONO8 ? 8 : 16,
                                     (void *) data, return_buffer, buf);
  } else {
    /* Packed or narrower formats: unpacked into a pooled image, the buffer returned at once. */
    GError *e = NULL;
    f = ds_frame_pool_take (c->frames, ds_pixfmt_sample_type (fmt), (guint) w,
                            (guint) h, &e);
    if (f && !ds_pixfmt_unpack_into (fmt, data, size, 0, f->image, &e))
      g_clear_pointer (&f, ds_frame_free);
    arv_stream_push_buffer (c->stream, buf);
    if (!f) {
      c->stats.failures++;
      fail (error, DS_DEVICE_ERROR_INCOMPLETE, e, "frame %" G_GUINT64_FORMAT, raw_id);
      return NULL;
    }
  }
  f->frame_id = id;
  f->ids_skipped = skipped;
  f->timestamp_ns = ts;
  f->host_time_us = (guint64) g_get_monotonic_time ();
  f->exposure_us = c->exposure_us;
  f->gain_db = c->gain_db;
  c->stats.completed++;
  return f;
}

/* A frame's first packet leaves the camera after its readout, hence after its exposure
 * (GigE Vision cameras send a frame once read out; docs/design.md, "The pipeline"). */
static guint64
cam_frames_begun (gpointer b, guint64 after, guint timeout_ms)
{
  AravisCam *c = b;
  gint64 until = g_get_monotonic_time () + (gint64) timeout_ms * 1000;
  g_mutex_lock (&c->begun_lock);
  while (c->begun <= after && timeout_ms > 0 && g_cond_wait_until (&c->begun_cond, &c->begun_lock, until))
    ;
  guint64 n = c->begun;
  g_mutex_unlock (&c->begun_lock);
  return n;
}

static guint
cam_flush (gpointer b)
{
  AravisCam *c = b;
  return drain_output (c);
}

static gboolean
cam_reconnect (gpointer b, GError **error)
{
  AravisCam *c = b;
  close_device (c);
  if (!open_device (c, error))
    return FALSE;
  c->stats.reconnects++;
  if (c->configured && !apply_settings (c, &c->settings, error)) {
    g_prefix_error (error, "reapplying settings after reconnect: ");
    return FALSE;
  }
  return TRUE;
}

static void
cam_get_stats (gpointer b, DsCameraStats *s)
{
  AravisCam *c = b;
  *s = c->stats;
  guint64 missing, resend;
  stream_packet_stats (c, &missing, &resend);
  s->missing_packets += missing;
  s->resend_requests += resend;
}

static void
cam_get_info (gpointer b, DsCameraInfo *i)
{
  AravisCam *c = b;
  *i = c->info;
  i->connected = c->camera && !camera_lost (c);
}

static void
cam_close (gpointer b)
{
  AravisCam *c = b;
  cam_stop (c);
  close_device (c);
  ds_frame_pool_unref (c->frames);
  g_mutex_clear (&c->begun_lock);
  g_cond_clear (&c->begun_cond);
  g_free (c->address);
  g_free (c);
}

static const DsCameraOps aravis_camera_ops = {
  .name = "aravis", .configure = cam_configure, .start = cam_start, .trigger = cam_trigger,
  .grab = cam_grab, .flush = cam_flush, .stop = cam_stop, .reconnect = cam_reconnect,
  .get_stats = cam_get_stats, .get_info = cam_get_info, .close = cam_close,
  .frames_begun = cam_frames_begun,
};

DsCamera *
ds_aravis_camera_open_with (const char *address_or_id, const DsAravisStreamOptions *o, GError **error)
{
  const char *what = address_or_id ? address_or_id : "(null)";
  if (!address_or_id || !*address_or_id || o->n_buffers < 2 || o->n_buffers > 1024) {
    fail (error, DS_DEVICE_ERROR_INVALID, NULL, "open \"%s\" with %u buffers: need an address and 2..1024 buffers",
          what, o->n_buffers);
    return NULL;
  }
  if (o->receive_buffer_frames < 1 || o->receive_buffer_frames > 64 || o->frame_retention_ms < 1 ||
      o->frame_retention_ms > 10000) {
    fail (error, DS_DEVICE_ERROR_INVALID, NULL,
          "open \"%s\" with a receive buffer of %u frames and a frame retention of %u ms: need 1..64 "
          "frames and 1..10000 ms", what, o->receive_buffer_frames, o->frame_retention_ms);
    return NULL;
  }
  AravisCam *c = g_new0 (AravisCam, 1);
  c->address = g_strdup (address_or_id);
  c->frames = ds_frame_pool_new ();
  c->options = *o;
  g_mutex_init (&c->begun_lock);
  g_cond_init (&c->begun_cond);
  if (!open_device (c, error)) {
    g_mutex_clear (&c->begun_lock);
    g_cond_clear (&c->begun_cond);
    ds_frame_pool_unref (c->frames);
    g_free (c->address);
    g_free (c);
    return NULL;
  }
  DsCamera *cam = g_new0 (DsCamera, 1);
  cam->ops = &aravis_camera_ops;
  cam->backend = c;
  return cam;
}

DsCamera *
ds_aravis_camera_open (const char *address_or_id, guint n_buffers, GError **error)
{
  DsAravisStreamOptions o = DS_ARAVIS_STREAM_OPTIONS_DEFAULT;
  o.n_buffers = n_buffers;
  return ds_aravis_camera_open_with (address_or_id, &o, error);
}

gboolean
ds_aravis_camera_is_aravis (const DsCamera *camera)
{
  return camera && camera->ops == &aravis_camera_ops;
}

void
ds_aravis_camera_pool_counts (const DsCamera *camera, guint *n_input, guint *n_output, guint *n_pool)
{
  *n_input = *n_output = *n_pool = 0;
  if (!ds_aravis_camera_is_aravis (camera))
    return;
  AravisCam *c = camera->backend;
  if (!c->stream)
    return;
  gint in = 0, out = 0;
  arv_stream_get_n_buffers (c->stream, &in, &out);
  *n_input = (guint) MAX (in, 0);
  *n_output = (guint) MAX (out, 0);
  *n_pool = c->options.n_buffers;
}

GObject *
ds_aravis_camera_device (const DsCamera *camera)
{
  if (!ds_aravis_camera_is_aravis (camera))
    return NULL;
  AravisCam *c = camera->backend;
  return c->camera ? G_OBJECT (arv_camera_get_device (c->camera)) : NULL;
}

gsize
ds_aravis_camera_receive_buffer (const DsCamera *camera)
{
  if (!ds_aravis_camera_is_aravis (camera))
    return 0;
  AravisCam *c = camera->backend;
  if (!c->stream || !ARV_IS_GV_STREAM (c->stream))
    return 0;
  /* Aravis keeps the socket to itself: the datagram socket of this process bound to the
   * stream's port. */
  guint16 port = arv_gv_stream_get_port (ARV_GV_STREAM (c->stream));
  DIR *dir = opendir ("/proc/self/fd");
  if (!dir)
    return 0;
  gsize size = 0;
  struct dirent *d;
  while (size == 0 && (d = readdir (dir))) {
    int fd = atoi (d->d_name);
    struct sockaddr_in a;
    socklen_t alen = sizeof a;
    int type = 0, rcvbuf = 0;
    socklen_t tlen = sizeof type, rlen = sizeof rcvbuf;
    if (d->d_name[0] < '0' || d->d_name[0] > '9' || fd == dirfd (dir) ||
        getsockopt (fd, SOL_SOCKET, SO_TYPE, &type, &tlen) != 0 || type != SOCK_DGRAM ||
        getsockname (fd, (struct sockaddr *) &a, &alen) != 0 || a.sin_family != AF_INET ||
        ntohs (a.sin_port) != port || getsockopt (fd, SOL_SOCKET, SO_RCVBUF, &rcvbuf, &rlen) != 0)
      continue;
    size = (gsize) MAX (rcvbuf, 0);
  }
  closedir (dir);
  return size;
}
