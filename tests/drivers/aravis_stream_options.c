/* The GigE Vision stream options of the Aravis backend (DsAravisStreamOptions) against Aravis's
 * own fake camera in this process, over loopback. The expectations are the kernel's and the
 * stream's documented rules, not the backend's: SO_RCVBUF reads back twice what was asked,
 * within net.core.rmem_max (socket(7)); a frame missing packets is given up frame-retention
 * after its last packet (ArvGvStream:frame-retention), so a retention far beyond the grab's
 * deadline turns it into a timeout, one far within into an incomplete frame. */
#include <arv.h>
#include <string.h>

#include "drivers/aravis/aravis_camera.h"

#define ADDRESS "127.0.0.1"

typedef struct {
  ArvGvFakeCamera *gv;
  DsCamera *cam;
} Rig;

static void
rig_start (Rig *r, guint receive_buffer_frames, guint frame_retention_ms)
{
  r->gv = arv_gv_fake_camera_new (ADDRESS, "DSTEST02");
  g_assert_nonnull (r->gv);
  g_assert_true (arv_gv_fake_camera_is_running (r->gv)); /* UDP 3956 on 127.0.0.1 was free */
  /* The fake checks for software triggers once per tick; 25 Hz would make the test slow. */
  arv_fake_camera_set_trigger_frequency (arv_gv_fake_camera_get_fake_camera (r->gv), 400.0);
  DsAravisStreamOptions o = DS_ARAVIS_STREAM_OPTIONS_DEFAULT;
  o.receive_buffer_frames = receive_buffer_frames;
  o.frame_retention_ms = frame_retention_ms;
  g_autoptr (GError) error = NULL;
  r->cam = ds_aravis_camera_open_with (ADDRESS, &o, &error);
  g_assert_no_error (error);
}

static void
rig_stop (Rig *r)
{
  ds_camera_close (r->cam);
  g_clear_object (&r->gv);
}

/* width x height Mono8 (one byte a pixel: the payload is width x height). */
static void
configure (Rig *r, guint width, guint height)
{
  DsCameraSettings s = { 0 };
  s.exposure_us = 1000;
  s.roi_width = width;
  s.roi_height = height;
  g_strlcpy (s.pixel_format, "Mono8", sizeof s.pixel_format);
  s.trigger_source = DS_CAMERA_TRIGGER_SOFTWARE;
  g_autoptr (GError) error = NULL;
  g_assert_true (r->cam->ops->configure (r->cam->backend, &s, &error));
  g_assert_no_error (error);
}

static DsFrame *
trigger_and_grab (Rig *r, guint timeout_ms, GError **error)
{
  if (!r->cam->ops->trigger (r->cam->backend, error))
    return NULL;
  return r->cam->ops->grab (r->cam->backend, timeout_ms, error);
}

static guint64
rmem_max (void)
{
  g_autofree char *text = NULL;
  g_assert_true (g_file_get_contents ("/proc/sys/net/core/rmem_max", &text, NULL, NULL));
  return g_ascii_strtoull (text, NULL, 10);
}

static void
count_cap_message (const char *domain, GLogLevelFlags level, const char *message, gpointer data)
{
  (void) domain;
  (void) level;
  if (strstr (message, "net.core.rmem_max") && strstr (message, "receive-buffer-frames"))
    (*(guint *) data)++;
}

/* The receive buffer the kernel granted the stream, for `frames` payloads of width x height,
 * over two captures (each configures a new stream); and whether the backend said, once, that
 * rmem_max cut it short. */
static void
check_receive_buffer (guint frames, guint width, guint height)
{
  Rig r = { 0 };
  rig_start (&r, frames, 100);
  guint64 want = (guint64) frames * width * height, cap = rmem_max ();
  guint said = 0;
  for (guint capture = 0; capture < 2; capture++) {
    configure (&r, width, height);
    guint handler = g_log_set_handler (NULL, G_LOG_LEVEL_MESSAGE, count_cap_message, &said);
    g_autoptr (GError) error = NULL;
    g_assert_true (r.cam->ops->start (r.cam->backend, &error));
    g_log_remove_handler (NULL, handler);
    /* Aravis applies the size when a frame's first packet arrives. */
    g_autoptr (DsFrame) f = trigger_and_grab (&r, 2000, &error);
    g_assert_no_error (error);
    g_assert_nonnull (f);
    gsize granted = ds_aravis_camera_receive_buffer (r.cam);
    g_test_message ("%u frames of %ux%u Mono8: asked %" G_GUINT64_FORMAT ", rmem_max %" G_GUINT64_FORMAT
                    ", SO_RCVBUF %" G_GSIZE_FORMAT, frames, width, height, want, cap, granted);
    g_assert_cmpuint (granted, ==, 2 * MIN (want, cap));
    r.cam->ops->stop (r.cam->backend);
  }
  g_assert_cmpuint (said, ==, want > cap ? 1 : 0);
  rig_stop (&r);
}

static void
test_receive_buffer_frames (void)
{
  /* Small enough that Debian's default rmem_max (208 KiB) holds each: the size follows the
   * option, not Aravis's one payload. */
  check_receive_buffer (1, 128, 64);
  check_receive_buffer (3, 128, 64);
  check_receive_buffer (6, 128, 64);
}

static void
test_receive_buffer_capped (void)
{
  /* 64 frames of 512x512: 16 MiB, beyond rmem_max on most hosts (the test expects what the
   * host's rmem_max allows, and the message only when it cuts). */
  check_receive_buffer (64, 512, 512);
}

/* One trigger while every packet is lost with probability 1/2: of a frame's packets (leader,
 * data, trailer; over a dozen at this size) all arrive with probability below 1e-4, none with
 * the same, so the frame begins and misses packets. */
static GError *
grab_lossy_frame (guint frame_retention_ms, guint grab_timeout_ms)
{
  Rig r = { 0 };
  rig_start (&r, 4, frame_retention_ms);
  configure (&r, 512, 128);
  g_autoptr (GError) error = NULL;
  g_assert_true (r.cam->ops->start (r.cam->backend, &error));
  g_object_set (r.gv, "gvsp-lost-ratio", 0.5, NULL);
  g_autoptr (DsFrame) f = trigger_and_grab (&r, grab_timeout_ms, &error);
  g_assert_null (f);
  g_assert_nonnull (error);
  r.cam->ops->stop (r.cam->backend);
  rig_stop (&r);
  return g_steal_pointer (&error);
}

static void
test_frame_retention (void)
{
  /* Given up 20 ms after its last packet: well within a 1 s grab. */
  g_autoptr (GError) short_wait = grab_lossy_frame (20, 1000);
  g_assert_error (short_wait, DS_CAMERA_ERROR, DS_DEVICE_ERROR_INCOMPLETE);
  /* Kept for 5 s after its last packet: the 300 ms grab ends first. */
  g_autoptr (GError) long_wait = grab_lossy_frame (5000, 300);
  g_assert_error (long_wait, DS_CAMERA_ERROR, DS_DEVICE_ERROR_TIMEOUT);
}

static void
test_bad_options (void)
{
  const DsAravisStreamOptions bad[] = { { 8, 0, 100 }, { 8, 65, 100 }, { 8, 4, 0 }, { 8, 4, 10001 }, { 1, 4, 100 } };
  for (guint i = 0; i < G_N_ELEMENTS (bad); i++) {
    g_autoptr (GError) error = NULL;
    g_assert_null (ds_aravis_camera_open_with (ADDRESS, &bad[i], &error));
    g_assert_error (error, DS_CAMERA_ERROR, DS_DEVICE_ERROR_INVALID);
  }
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  g_test_add_func ("/aravis-stream/bad-options", test_bad_options);
  g_test_add_func ("/aravis-stream/receive-buffer-frames", test_receive_buffer_frames);
  g_test_add_func ("/aravis-stream/receive-buffer-capped", test_receive_buffer_capped);
  g_test_add_func ("/aravis-stream/frame-retention", test_frame_retention);
  int rc = g_test_run ();
  arv_shutdown ();
  return rc;
}
