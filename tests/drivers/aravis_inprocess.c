/* The Aravis backend against Aravis's own GigE Vision fake camera, run in this process on
 * 127.0.0.1 with a fill pattern the test controls: real GVCP/GVSP over loopback, no mocks.
 * Expectations are independent of the backend: the pixels the fill pattern wrote, ids counted
 * by the camera, the pool size the test asked for. */
#include <arv.h>
#include <dlfcn.h>
#include <string.h>

#include "drivers/aravis/aravis_camera.h"

#define ADDRESS "127.0.0.1"
#define N_BUFFERS 6

/* Frame n (counted by the fill callback) carries n in its first pixel and
 * (x + 3y + 7n) mod (max + 1) elsewhere. */
typedef struct {
  gint n;                  /* atomic: frames filled so far */
  gint width, height;      /* atomic: the ROI the test configured */
} Fill;

static guint
pattern_value (guint x, guint y, guint n, guint max)
{
  return (x + 3 * y + 7 * n) % (max + 1);
}

static void
fill (ArvBuffer *buffer, void *data, guint32 exposure_us, guint32 gain, ArvPixelFormat pf)
{
  (void) exposure_us;
  (void) gain;
  Fill *f = data;
  guint n = (guint) g_atomic_int_add (&f->n, 1);
  size_t size = 0;
  /* The whole buffer: the fake camera allocated it for the configured ROI, and describes its
   * size and image part only after the pattern is drawn (size reads 0 here). */
  guint8 *p = (guint8 *) arv_buffer_get_data (buffer, &size);
  guint w = (guint) g_atomic_int_get (&f->width), h = (guint) g_atomic_int_get (&f->height);
  gboolean wide = pf == ARV_PIXEL_FORMAT_MONO_16;
  guint max = wide ? 65535 : 255;
  if (!p || (size && size < (gsize) w * h * (wide ? 2 : 1)))
    return;
  for (guint y = 0; y < h; y++)
    for (guint x = 0; x < w; x++) {
      guint v = x == 0 && y == 0 ? n % (max + 1) : pattern_value (x, y, n, max);
      gsize i = (gsize) y * w + x;
      if (wide) {
        p[2 * i] = (guint8) (v & 0xff);
        p[2 * i + 1] = (guint8) (v >> 8);
      } else
        p[i] = (guint8) v;
    }
}

typedef struct {
  ArvGvFakeCamera *gv;
  Fill fill;
  DsCamera *cam;
} Rig;

static ArvGvFakeCamera *
start_fake (Fill *f)
{
  ArvGvFakeCamera *gv = arv_gv_fake_camera_new (ADDRESS, "DSTEST01");
  g_assert_nonnull (gv);
  g_assert_true (arv_gv_fake_camera_is_running (gv)); /* UDP 3956 on 127.0.0.1 was free */
  ArvFakeCamera *fake = arv_gv_fake_camera_get_fake_camera (gv);
  /* The fake checks for software triggers once per tick; 25 Hz would make the test slow. */
  arv_fake_camera_set_trigger_frequency (fake, 400.0);
  arv_fake_camera_set_fill_pattern (fake, fill, f);
  return gv;
}

static void
rig_setup (Rig *r, gconstpointer data)
{
  (void) data;
  r->gv = start_fake (&r->fill);
  g_autoptr (GError) error = NULL;
  r->cam = ds_aravis_camera_open (ADDRESS, N_BUFFERS, &error);
  g_assert_no_error (error);
  g_assert_nonnull (r->cam);
}

static void
rig_teardown (Rig *r, gconstpointer data)
{
  (void) data;
  ds_camera_close (r->cam);
  g_clear_object (&r->gv);
}

static DsCameraSettings
settings (const char *fmt, guint w, guint h)
{
  DsCameraSettings s = { 0 };
  s.exposure_us = 2000;
  s.gain_db = 0;
  s.roi_x = 8;
  s.roi_y = 4;
  s.roi_width = w;
  s.roi_height = h;
  g_strlcpy (s.pixel_format, fmt, sizeof s.pixel_format);
  s.trigger_source = DS_CAMERA_TRIGGER_SOFTWARE;
  return s;
}

static void
configure_and_start (Rig *r, const DsCameraSettings *s)
{
  DsCamera *cam = r->cam;
  g_autoptr (GError) error = NULL;
  g_atomic_int_set (&r->fill.width, (gint) s->roi_width);
  g_atomic_int_set (&r->fill.height, (gint) s->roi_height);
  cam->ops->configure (cam->backend, s, &error);
  g_assert_no_error (error);
  cam->ops->start (cam->backend, &error);
  g_assert_no_error (error);
}

static DsFrame *
trigger_and_grab (DsCamera *cam, GError **error)
{
  if (!cam->ops->trigger (cam->backend, error))
    return NULL;
  return cam->ops->grab (cam->backend, 2000, error);
}

/* Checks every pixel against the fill pattern; returns the frame's n. */
static guint
check_pixels (const DsFrame *f, guint max)
{
  const DsImage *im = f->image;
  guint n = max == 255 ? ((guint8 *) ds_image_row (im, 0))[0] : ((guint16 *) ds_image_row (im, 0))[0];
  for (guint y = 0; y < im->height; y++)
    for (guint x = 0; x < im->width; x++) {
      if (x == 0 && y == 0)
        continue;
      guint got = max == 255 ? ((guint8 *) ds_image_row (im, y))[x] : ((guint16 *) ds_image_row (im, y))[x];
      if (got != pattern_value (x, y, n, max))
        g_error ("pixel %u,%u of frame %u: %u, the fill pattern wrote %u", x, y, n, got,
                 pattern_value (x, y, n, max));
    }
  return n;
}

static void
test_pixels (Rig *r, const char *fmt, guint max, DsSampleType type)
{
  DsCameraSettings s = settings (fmt, 40, 24);
  configure_and_start (r, &s);
  gint prev_n = -1;
  for (guint i = 0; i < 8; i++) {
    g_autoptr (GError) error = NULL;
    g_autoptr (DsFrame) f = trigger_and_grab (r->cam, &error);
    g_assert_no_error (error);
    g_assert_cmpuint (f->image->width, ==, 40);
    g_assert_cmpuint (f->image->height, ==, 24);
    g_assert_cmpint (f->image->type, ==, type);
    g_assert_cmpfloat (f->exposure_us, ==, 2000);
    guint n = check_pixels (f, max);
    if (prev_n >= 0)
      g_assert_cmpuint (n, ==, (guint) prev_n + 1); /* one exposure per trigger */
    prev_n = (gint) n;
  }
  DsCameraStats st;
  r->cam->ops->get_stats (r->cam->backend, &st);
  g_assert_cmpuint (st.completed, ==, 8);
  g_assert_cmpuint (st.failures, ==, 0);
  DsCameraInfo info;
  r->cam->ops->get_info (r->cam->backend, &info);
  g_assert_true (info.connected);
  g_assert_cmpstr (info.serial, ==, "DSTEST01");
  r->cam->ops->stop (r->cam->backend);
}

static void
test_mono8 (Rig *r, gconstpointer data)
{
  (void) data;
  test_pixels (r, "Mono8", 255, DS_SAMPLE_U8);
}

static void
test_mono16 (Rig *r, gconstpointer data)
{
  (void) data;
  test_pixels (r, "Mono16", 65535, DS_SAMPLE_U16);
}

static void
test_bad_settings (Rig *r, gconstpointer data)
{
  (void) data;
  g_autoptr (GError) error = NULL;
  DsCameraSettings s = settings ("Mono9", 40, 24);
  g_assert_false (r->cam->ops->configure (r->cam->backend, &s, &error));
  g_assert_error (error, DS_CAMERA_ERROR, DS_DEVICE_ERROR_INVALID);
  g_clear_error (&error);
  s = settings ("Mono8", 100000, 24);
  g_assert_false (r->cam->ops->configure (r->cam->backend, &s, &error));
  g_assert_error (error, DS_CAMERA_ERROR, DS_DEVICE_ERROR_INVALID);
  g_assert_nonnull (strstr (error->message, "ROI"));
  g_clear_error (&error);
  s = settings ("Mono8", 40, 24);
  s.exposure_us = -5;
  g_assert_false (r->cam->ops->configure (r->cam->backend, &s, &error));
  g_assert_error (error, DS_CAMERA_ERROR, DS_DEVICE_ERROR_INVALID);
  g_clear_error (&error);
  /* The fake camera has Line0 only. */
  s = settings ("Mono8", 40, 24);
  s.trigger_source = DS_CAMERA_TRIGGER_LINE;
  s.trigger_line = 1;
  g_assert_false (r->cam->ops->configure (r->cam->backend, &s, &error));
  g_assert_error (error, DS_CAMERA_ERROR, DS_DEVICE_ERROR_UNSUPPORTED);
  g_assert_nonnull (strstr (error->message, "Line1"));
  g_clear_error (&error);
  /* A line-triggered camera refuses software triggers. */
  s.trigger_line = 0;
  configure_and_start (r, &s);
  g_assert_false (r->cam->ops->trigger (r->cam->backend, &error));
  g_assert_error (error, DS_CAMERA_ERROR, DS_DEVICE_ERROR_INVALID);
  r->cam->ops->stop (r->cam->backend);
}

/* The fake camera's ids start near 65400 and wrap 65535 -> 1. */
static void
test_ids_across_wrap (Rig *r, gconstpointer data)
{
  (void) data;
  DsCameraSettings s = settings ("Mono8", 16, 8);
  configure_and_start (r, &s);
  guint64 first = 0, last = 0;
  for (guint i = 0; i < 400 && !(first && last > 65536 + 3); i++) {
    g_autoptr (GError) error = NULL;
    g_autoptr (DsFrame) f = trigger_and_grab (r->cam, &error);
    g_assert_no_error (error);
    g_assert_cmpuint (f->ids_skipped, ==, 0);
    if (first)
      g_assert_cmpuint (f->frame_id, ==, last + 1);
    else
      first = f->frame_id;
    last = f->frame_id;
  }
  /* The fake's first id is within 400 of the wrap: the loop must have crossed it. */
  g_assert_cmpuint (last, >, 65536 + 3);
  DsCameraStats st;
  r->cam->ops->get_stats (r->cam->backend, &st);
  g_assert_cmpuint (st.ids_skipped, ==, 0);
  r->cam->ops->stop (r->cam->backend);
}

/* GVSP packet loss: every failure is typed, good frames still hold the right pixels, and the
 * pool is whole afterwards. */
static void
test_packet_loss (Rig *r, gconstpointer data)
{
  (void) data;
  /* 256x64 Mono8 is a dozen or more GVSP packets (after packet-size negotiation): with 5 % of
   * them lost about half of the frames or more lose at least one. */
  g_object_set (r->gv, "gvsp-lost-ratio", 0.05, NULL);
  DsCameraSettings s = settings ("Mono8", 256, 64);
  configure_and_start (r, &s);
  guint ok = 0, incomplete = 0, timeouts = 0;
  for (guint i = 0; i < 40; i++) {
    g_autoptr (GError) error = NULL;
    g_autoptr (DsFrame) f = trigger_and_grab (r->cam, &error);
    if (f) {
      check_pixels (f, 255);
      ok++;
      continue;
    }
    g_assert_true (error->domain == DS_CAMERA_ERROR);
    if (error->code == DS_DEVICE_ERROR_INCOMPLETE)
      incomplete++;
    else if (error->code == DS_DEVICE_ERROR_TIMEOUT)
      timeouts++;
    else
      g_error ("unexpected error under packet loss: %s", error->message);
    guint in, out, pool;
    ds_aravis_camera_pool_counts (r->cam, &in, &out, &pool);
    g_assert_cmpuint (in + out, <=, pool);
  }
  g_test_message ("40 frames at 5%% packet loss: %u good, %u incomplete, %u timeouts", ok, incomplete,
                  timeouts);
  g_assert_cmpuint (ok, >, 0);
  g_assert_cmpuint (incomplete, >, 0);
  DsCameraStats st;
  r->cam->ops->get_stats (r->cam->backend, &st);
  g_assert_cmpuint (st.completed, ==, ok);
  g_assert_cmpuint (st.failures, ==, incomplete);
  g_assert_cmpuint (st.timeouts, ==, timeouts);
  g_assert_cmpuint (st.missing_packets, >, 0);
  g_assert_cmpuint (st.resend_requests, >, 0); /* asked, though the fake never resends */
  r->cam->ops->stop (r->cam->backend);
  guint in, out, pool;
  ds_aravis_camera_pool_counts (r->cam, &in, &out, &pool);
  g_assert_cmpuint (pool, ==, N_BUFFERS);
  g_assert_cmpuint (in, ==, N_BUFFERS);
  g_assert_cmpuint (out, ==, 0);
  /* And the camera still works once the link is clean again. */
  g_object_set (r->gv, "gvsp-lost-ratio", 0.0, NULL);
  configure_and_start (r, &s);
  g_autoptr (GError) error = NULL;
  g_autoptr (DsFrame) f = trigger_and_grab (r->cam, &error);
  g_assert_no_error (error);
  check_pixels (f, 255);
}

/* Every frame lost on the wire is counted once: an incomplete frame (INCOMPLETE) or a frame
 * never seen (TIMEOUT), and the next whole frame shows no gap for it. Frames of three GVSP
 * packets (leader, one data packet, trailer) at 10 % packet loss: about one in ten loses its
 * leader, and Aravis, which takes a buffer's frame id from the leader, hands such a buffer back
 * with the id of the frame it held before. Before, that id was taken for this frame's, and the
 * next whole frame was dropped as a frame gap of several ids. The expectation is the camera's
 * own count: each trigger makes one frame and one id, so between two whole frames the extended
 * id moves by one more than the triggers that failed between them. */
static void
test_loss_counted_once (Rig *r, gconstpointer data)
{
  (void) data;
  g_object_set (r->gv, "gvsp-lost-ratio", 0.1, NULL);
  DsCameraSettings s = settings ("Mono8", 16, 8);
  configure_and_start (r, &s);
  guint ok = 0, failed_between = 0, incomplete = 0, timeouts = 0, unknown_id = 0;
  guint64 last_id = 0;
  for (guint i = 0; i < 120; i++) {
    g_autoptr (GError) error = NULL;
    g_autoptr (DsFrame) f = trigger_and_grab (r->cam, &error);
    if (!f) {
      g_assert_true (error->domain == DS_CAMERA_ERROR);
      if (error->code == DS_DEVICE_ERROR_INCOMPLETE)
        incomplete++;
      else if (error->code == DS_DEVICE_ERROR_TIMEOUT)
        timeouts++;
      else
        g_error ("unexpected error under packet loss: %s", error->message);
      unknown_id += strstr (error->message, "id unknown") != NULL;
      failed_between++;
      continue;
    }
    check_pixels (f, 255);
    g_assert_cmpuint (f->ids_skipped, ==, 0);
    if (ok)
      g_assert_cmpuint (f->frame_id, ==, last_id + 1 + failed_between);
    last_id = f->frame_id;
    failed_between = 0;
    ok++;
  }
  g_test_message ("120 frames of 3 packets at 10%% packet loss: %u whole, %u incomplete (%u without their "
                  "leader), %u timeouts", ok, incomplete, unknown_id, timeouts);
  g_assert_cmpuint (ok, >, 10);
  g_assert_cmpuint (unknown_id, >, 0); /* the case this test is for happened (p > 0.99999) */
  DsCameraStats st;
  r->cam->ops->get_stats (r->cam->backend, &st);
  g_assert_cmpuint (st.ids_skipped, ==, 0);
  r->cam->ops->stop (r->cam->backend);
}

static void
test_flush (Rig *r, gconstpointer data)
{
  (void) data;
  DsCameraSettings s = settings ("Mono8", 16, 8);
  configure_and_start (r, &s);
  g_autoptr (GError) error = NULL;
  for (guint i = 0; i < 3; i++) {
    g_assert_true (r->cam->ops->trigger (r->cam->backend, &error));
    g_assert_no_error (error);
    /* Wait for the frame to land so that flush has something to drop (30 s: a bound for a
     * hang; the stream thread can take seconds on a loaded machine). */
    guint in = 0, out = 0, pool = 0;
    gint64 deadline = g_get_monotonic_time () + 30 * G_USEC_PER_SEC;
    for (;;) {
      ds_aravis_camera_pool_counts (r->cam, &in, &out, &pool);
      if (out == i + 1 || g_get_monotonic_time () >= deadline)
        break;
      g_usleep (10000);
    }
    g_assert_cmpuint (out, ==, i + 1);
  }
  g_assert_cmpuint (r->cam->ops->flush (r->cam->backend), ==, 3);
  g_assert_null (r->cam->ops->grab (r->cam->backend, 50, &error));
  g_assert_error (error, DS_CAMERA_ERROR, DS_DEVICE_ERROR_TIMEOUT);
  g_clear_error (&error);
  DsCameraStats st;
  r->cam->ops->get_stats (r->cam->backend, &st);
  g_assert_cmpuint (st.timeouts, ==, 1);
  /* Flushed frames are not gaps: the next one follows without a skip. */
  g_autoptr (DsFrame) f = trigger_and_grab (r->cam, &error);
  g_assert_no_error (error);
  g_assert_cmpuint (f->ids_skipped, ==, 0);
}

/* The camera vanishes: Aravis's heartbeat reports control lost, the backend fails
 * DISCONNECTED, and reconnect works once the camera is back. */
static void
test_disconnect_reconnect (Rig *r, gconstpointer data)
{
  (void) data;
  DsCameraSettings s = settings ("Mono8", 16, 8);
  configure_and_start (r, &s);
  g_clear_object (&r->gv);
  DsCameraInfo info = { .connected = TRUE };
  for (guint i = 0; i < 300 && info.connected; i++) {
    g_usleep (100 * 1000);
    r->cam->ops->get_info (r->cam->backend, &info);
  }
  g_assert_false (info.connected);
  g_autoptr (GError) error = NULL;
  g_assert_false (r->cam->ops->trigger (r->cam->backend, &error));
  g_assert_error (error, DS_CAMERA_ERROR, DS_DEVICE_ERROR_DISCONNECTED);
  g_clear_error (&error);
  g_assert_null (r->cam->ops->grab (r->cam->backend, 100, &error));
  g_assert_error (error, DS_CAMERA_ERROR, DS_DEVICE_ERROR_DISCONNECTED);
  g_clear_error (&error);
  r->cam->ops->stop (r->cam->backend);
  /* Still gone: reconnect fails DISCONNECTED. */
  g_assert_false (r->cam->ops->reconnect (r->cam->backend, &error));
  g_assert_error (error, DS_CAMERA_ERROR, DS_DEVICE_ERROR_DISCONNECTED);
  g_clear_error (&error);
  r->fill.n = 0;
  r->gv = start_fake (&r->fill);
  g_assert_true (r->cam->ops->reconnect (r->cam->backend, &error));
  g_assert_no_error (error);
  g_assert_true (r->cam->ops->start (r->cam->backend, &error));
  g_assert_no_error (error);
  g_autoptr (DsFrame) f = trigger_and_grab (r->cam, &error);
  g_assert_no_error (error);
  g_assert_cmpuint (f->image->width, ==, 16); /* the last settings were reapplied */
  check_pixels (f, 255);
  DsCameraStats st;
  r->cam->ops->get_stats (r->cam->backend, &st);
  g_assert_cmpuint (st.reconnects, ==, 1);
}

/* Aravis's heartbeat thread reports "control-lost" while holding a reference on the device for
 * the emission. The camera is closed meanwhile (a reconnect after the loss, as descatterd's
 * acquisition thread does): were the backend's reference dropped then, the emission's would be
 * the last, and the device's finalize, which joins the heartbeat thread, would run on that very
 * thread (GLib-ERROR "Resource deadlock avoided" in g_thread_join: daemon/labsim-faults under
 * load). An emission hook holds the heartbeat thread inside the emission until the backend's
 * close is over or the emission's reference is the last one, which makes the interleaving
 * certain instead of a matter of load. The device must then be finalized, and not on the
 * heartbeat thread. */
typedef struct {
  GMutex lock;
  GCond cond;
  ArvDevice *device;           /* weak: for its reference count */
  GThread *heartbeat;          /* the thread that emitted */
  GThread *finalized_on;
  gboolean entered, closed, finalized;
} LostEmission;

/* Data on the device, freed by GObject's own finalize: after Aravis's (heartbeat joined). */
static void
on_device_finalized (gpointer data)
{
  LostEmission *e = data;
  g_mutex_lock (&e->lock);
  e->finalized = TRUE;
  e->finalized_on = g_thread_self ();
  g_cond_broadcast (&e->cond);
  g_mutex_unlock (&e->lock);
}

static gboolean
hold_control_lost (GSignalInvocationHint *hint, guint n_values, const GValue *values, gpointer data)
{
  (void) hint;
  (void) n_values;
  LostEmission *e = data;
  GObject *device = g_value_get_object (&values[0]);
  g_object_set_data_full (device, "ds-test-finalized", e, on_device_finalized);
  g_mutex_lock (&e->lock);
  e->device = ARV_DEVICE (device);
  e->heartbeat = g_thread_self ();
  e->entered = TRUE;
  g_cond_broadcast (&e->cond);
  gint64 deadline = g_get_monotonic_time () + 60 * G_TIME_SPAN_SECOND;
  /* The emission's reference (taken by GLib for the emission) left alone: the bug. */
  while (!e->closed && g_atomic_int_get ((gint *) &device->ref_count) > 1 &&
         g_get_monotonic_time () < deadline)
    g_cond_wait_until (&e->cond, &e->lock, g_get_monotonic_time () + G_TIME_SPAN_MILLISECOND);
  g_mutex_unlock (&e->lock);
  /* Removed by the test: a hook that removes itself by returning FALSE leaves GLib 2.74's
   * signal off its fast path for good (g_hook_destroy_link does not invalidate the node's
   * single_va_closure), and every later emission would reference the device. */
  return TRUE;
}

static void
test_control_lost_during_close (Rig *r, gconstpointer data)
{
  (void) data;
  DsCameraSettings s = settings ("Mono8", 16, 8);
  configure_and_start (r, &s);
  LostEmission e = { 0 };
  g_mutex_init (&e.lock);
  g_cond_init (&e.cond);
  guint signal_id = g_signal_lookup ("control-lost", ARV_TYPE_DEVICE);
  gulong hook = g_signal_add_emission_hook (signal_id, 0, hold_control_lost, &e, NULL);
  g_clear_object (&r->gv); /* the camera vanishes: the heartbeat reports it within seconds */
  gint64 deadline = g_get_monotonic_time () + 60 * G_TIME_SPAN_SECOND;
  g_mutex_lock (&e.lock);
  while (!e.entered && g_get_monotonic_time () < deadline)
    g_cond_wait_until (&e.cond, &e.lock, deadline);
  gboolean entered = e.entered;
  g_mutex_unlock (&e.lock);
  if (!entered)
    g_signal_remove_emission_hook (signal_id, hook);
  g_assert_true (entered);
  /* The heartbeat thread is inside the emission: the backend reconnects (closing the device;
   * the camera is still gone, so opening it again fails). */
  g_autoptr (GError) error = NULL;
  g_assert_false (r->cam->ops->reconnect (r->cam->backend, &error));
  g_assert_error (error, DS_CAMERA_ERROR, DS_DEVICE_ERROR_DISCONNECTED);
  g_mutex_lock (&e.lock);
  e.closed = TRUE;
  g_cond_broadcast (&e.cond);
  deadline = g_get_monotonic_time () + 30 * G_TIME_SPAN_SECOND;
  while (!e.finalized && g_get_monotonic_time () < deadline)
    g_cond_wait_until (&e.cond, &e.lock, deadline);
  gboolean finalized = e.finalized;
  GThread *finalized_on = e.finalized_on;
  g_mutex_unlock (&e.lock);
  g_signal_remove_emission_hook (signal_id, hook); /* the emission is over: finalized after */
  g_assert_true (finalized);                       /* released, not leaked */
  g_assert_true (finalized_on != e.heartbeat);     /* and never by the thread it joins */
  g_mutex_clear (&e.lock);
  g_cond_clear (&e.cond);
}

/* The narrower window of the same race. "control-lost" has no va marshaller (Aravis registers
 * it with g_cclosure_marshal_VOID__VOID), so with a handler connected GLib 2.74's
 * g_signal_emit_valist decides on its slow path under the signal lock, releases the lock and
 * only then references the device; nothing shows that the emission has begun. A close that
 * sees a reference count of 1 in between finalizes the device: its finalize joins the
 * heartbeat thread, which then references a device whose count is 0 (GLib-CRITICAL
 * "g_object_ref: assertion '!object_already_finalized' failed", and the emission's unref would
 * finalize it once more, on the heartbeat thread). No emission hook may be used here (a hook
 * changes GLib's path): this binary interposes g_thread_new, to know Aravis's heartbeat
 * threads, and g_mutex_unlock (libgobject and libaravis call both through their PLT). The
 * release of the signal lock inside g_signal_emit_valist on the heartbeat thread (its decision
 * made) holds that thread until the backend's close is over or the device's finalize has
 * begun. */
static struct {
  gint armed;                 /* atomic: until the window has been held once */
  GObject *device;            /* the armed device (borrowed) */
  GMutex lock;
  GCond cond;
  GThread *heartbeat;         /* the thread held in the window */
  GThread *finalized_on;
  gboolean entered, closed, finalized;
} window;

static __thread gboolean on_heartbeat_thread, in_window_check;

typedef struct {
  GThreadFunc func;
  gpointer data;
} ThreadStart;

static gpointer
heartbeat_start (gpointer data)
{
  ThreadStart start = *(ThreadStart *) data;
  g_free (data);
  on_heartbeat_thread = TRUE;
  return start.func (start.data);
}

GThread *
g_thread_new (const gchar *name, GThreadFunc func, gpointer data)
{
  GThread *(*real_new) (const gchar *, GThreadFunc, gpointer);
  *(void **) &real_new = dlsym (RTLD_NEXT, "g_thread_new");
  if (name && strcmp (name, "arv_gv_heartbeat") == 0) {
    ThreadStart *start = g_new (ThreadStart, 1);
    start->func = func;
    start->data = data;
    return real_new (name, heartbeat_start, start);
  }
  return real_new (name, func, data);
}

static void
hold_in_window (void)
{
  if (!g_atomic_int_compare_and_exchange (&window.armed, 1, 0))
    return;
  g_mutex_lock (&window.lock);
  window.heartbeat = g_thread_self ();
  window.entered = TRUE;
  g_cond_broadcast (&window.cond);
  gint64 deadline = g_get_monotonic_time () + 60 * G_TIME_SPAN_SECOND;
  /* The device's memory stays valid while this thread lives: its finalize joins it. */
  while (!window.closed && g_atomic_int_get ((gint *) &window.device->ref_count) > 0 &&
         g_get_monotonic_time () < deadline)
    g_cond_wait_until (&window.cond, &window.lock, g_get_monotonic_time () + G_TIME_SPAN_MILLISECOND);
  g_mutex_unlock (&window.lock);
}

void
g_mutex_unlock (GMutex *mutex)
{
  static void (*real_unlock) (GMutex *);
  void (*unlock) (GMutex *) = g_atomic_pointer_get (&real_unlock);
  if (!unlock) {
    *(void **) &unlock = dlsym (RTLD_NEXT, "g_mutex_unlock");
    g_atomic_pointer_set (&real_unlock, unlock);
  }
  unlock (mutex);
  if (!on_heartbeat_thread || in_window_check || !g_atomic_int_get (&window.armed))
    return;
  in_window_check = TRUE;
  Dl_info info;
  if (dladdr (__builtin_return_address (0), &info) && info.dli_sname &&
      strcmp (info.dli_sname, "g_signal_emit_valist") == 0)
    hold_in_window ();
  in_window_check = FALSE;
}

static void
on_window_device_finalized (gpointer data)
{
  (void) data;
  g_mutex_lock (&window.lock);
  window.finalized = TRUE;
  window.finalized_on = g_thread_self ();
  g_cond_broadcast (&window.cond);
  g_mutex_unlock (&window.lock);
}

static void
test_control_lost_window (Rig *r, gconstpointer data)
{
  (void) data;
  DsCameraSettings s = settings ("Mono8", 16, 8);
  configure_and_start (r, &s);
  window.device = ds_aravis_camera_device (r->cam);
  g_assert_nonnull (window.device);
  /* Freed by GObject's own finalize: after Aravis's (heartbeat joined). */
  g_object_set_data_full (window.device, "ds-test-finalized", &window, on_window_device_finalized);
  g_atomic_int_set (&window.armed, 1);
  g_clear_object (&r->gv); /* the camera vanishes: the heartbeat reports it within seconds */
  gint64 deadline = g_get_monotonic_time () + 60 * G_TIME_SPAN_SECOND;
  g_mutex_lock (&window.lock);
  while (!window.entered && g_get_monotonic_time () < deadline)
    g_cond_wait_until (&window.cond, &window.lock, deadline);
  gboolean entered = window.entered;
  g_mutex_unlock (&window.lock);
  g_atomic_int_set (&window.armed, 0);
  g_assert_true (entered);
  /* The heartbeat thread has decided how to emit "control-lost" and holds no reference on the
   * device yet: the backend reconnects (closing the device; the camera is gone, so opening it again fails). */
  g_autoptr (GError) error = NULL;
  g_assert_false (r->cam->ops->reconnect (r->cam->backend, &error));
  g_assert_error (error, DS_CAMERA_ERROR, DS_DEVICE_ERROR_DISCONNECTED);
  g_mutex_lock (&window.lock);
  window.closed = TRUE;
  g_cond_broadcast (&window.cond);
  deadline = g_get_monotonic_time () + 30 * G_TIME_SPAN_SECOND;
  while (!window.finalized && g_get_monotonic_time () < deadline)
    g_cond_wait_until (&window.cond, &window.lock, deadline);
  gboolean finalized = window.finalized;
  GThread *finalized_on = window.finalized_on;
  g_mutex_unlock (&window.lock);
  g_assert_true (finalized);                        /* released, not leaked */
  g_assert_true (finalized_on != window.heartbeat); /* and never by the thread it joins */
}

/* Mono16 frames lend the camera's buffer: while a frame is held its buffer is out of the
 * stream and its pixels stay those of its own exposure (later frames do not overwrite them);
 * freeing a frame gives the buffer back; a frame held past the camera's close stays valid. */
static void
test_lent_buffers (Rig *r, gconstpointer data)
{
  (void) data;
  DsCameraSettings s = settings ("Mono16", 40, 24);
  configure_and_start (r, &s);
  DsFrame *held[N_BUFFERS - 2];
  guint held_n[N_BUFFERS - 2];
  for (guint i = 0; i < G_N_ELEMENTS (held); i++) {
    g_autoptr (GError) error = NULL;
    held[i] = trigger_and_grab (r->cam, &error);
    g_assert_no_error (error);
    held_n[i] = check_pixels (held[i], 65535);
    guint in, out, pool;
    ds_aravis_camera_pool_counts (r->cam, &in, &out, &pool);
    g_assert_cmpuint (in + out, <=, pool - (i + 1));
  }
  /* Two buffers are left for the stream: frames keep coming, through those two. */
  for (guint i = 0; i < 6; i++) {
    g_autoptr (GError) error = NULL;
    g_autoptr (DsFrame) f = trigger_and_grab (r->cam, &error);
    g_assert_no_error (error);
    check_pixels (f, 65535);
  }
  for (guint i = 0; i < G_N_ELEMENTS (held); i++)
    g_assert_cmpuint (check_pixels (held[i], 65535), ==, held_n[i]);
  for (guint i = 0; i + 1 < G_N_ELEMENTS (held); i++)
    ds_frame_free (held[i]);
  r->cam->ops->stop (r->cam->backend);
  guint in, out, pool;
  ds_aravis_camera_pool_counts (r->cam, &in, &out, &pool);
  g_assert_cmpuint (in + out, ==, pool - 1); /* the one still held */
  DsFrame *last = held[G_N_ELEMENTS (held) - 1];
  ds_camera_close (g_steal_pointer (&r->cam));
  g_assert_cmpuint (check_pixels (last, 65535), ==, held_n[G_N_ELEMENTS (held) - 1]);
  ds_frame_free (last); /* gives the buffer back to a stream only this frame still holds */
}

/* One GVSP packet to the stream's address, as the camera would send it: status OK, frame id
 * `id`, content type H.264 (0x05), packet 0. Aravis 0.8.26 sizes no frame from it and moves
 * the next input buffer, unfilled, to the output queue. */
static void
send_stray_packet (Rig *r, guint16 id)
{
  g_autoptr (GError) error = NULL;
  g_autoptr (GSocketAddress) to = arv_fake_camera_get_stream_address (arv_gv_fake_camera_get_fake_camera (r->gv));
  g_assert_cmpuint (g_inet_socket_address_get_port (G_INET_SOCKET_ADDRESS (to)), >, 0);
  g_autoptr (GSocket) sock = g_socket_new (G_SOCKET_FAMILY_IPV4, G_SOCKET_TYPE_DATAGRAM, G_SOCKET_PROTOCOL_UDP, &error);
  g_assert_no_error (error);
  g_autoptr (GSocketAddress) from = g_inet_socket_address_new_from_string (ADDRESS, 0);
  g_assert_true (g_socket_bind (sock, from, FALSE, &error));
  const guint8 packet[8] = { 0, 0, (guint8) (id >> 8), (guint8) (id & 0xff), 0x05, 0, 0, 0 };
  g_assert_cmpint (g_socket_send_to (sock, to, (const char *) packet, sizeof packet, NULL, &error), ==, sizeof packet);
  g_assert_no_error (error);
  /* Wait until the stream has handed the buffer out (30 s: a bound for a hang). */
  gint64 deadline = g_get_monotonic_time () + 30 * G_USEC_PER_SEC;
  while (g_get_monotonic_time () < deadline) {
    guint in, out, pool;
    ds_aravis_camera_pool_counts (r->cam, &in, &out, &pool);
    if (out == 1)
      return;
    g_usleep (10000);
  }
  g_error ("the stream handed out no buffer for the stray packet within 30 s");
}

/* A frame id ahead of frame f's on the 16-bit circle without 0, as a new frame's would be. */
static guint16
id_ahead (const DsFrame *f)
{
  guint id = (guint) ((f->frame_id + 100) % 65536);
  return (guint16) (id ? id : 1);
}

/* A buffer the stream hands back without filling it is no frame: flush does not count it, and
 * grab waits on for the frame the trigger made, whether the buffer was new (cleared) or still
 * held an earlier frame's pixels. Without the check a flush counted a stale frame (what
 * drivers/daemon-gpio-trigger saw as root, where loopback's other packets reached the stream),
 * and a grab returned a copy of an old frame. */
static void
test_unfilled_buffers (Rig *r, gconstpointer data)
{
  (void) data;
  DsCameraSettings s = settings ("Mono8", 16, 8);
  configure_and_start (r, &s);
  g_autoptr (GError) error = NULL;
  guint n;
  {
    g_autoptr (DsFrame) f = trigger_and_grab (r->cam, &error);
    g_assert_no_error (error);
    n = check_pixels (f, 255);
    /* The next input buffer was never filled: it comes back cleared. */
    send_stray_packet (r, id_ahead (f));
  }
  g_assert_cmpuint (r->cam->ops->flush (r->cam->backend), ==, 0);
  /* Every buffer has held a frame... */
  guint64 last_id = 0;
  for (guint i = 0; i < N_BUFFERS + 1; i++) {
    g_autoptr (DsFrame) f = trigger_and_grab (r->cam, &error);
    g_assert_no_error (error);
    g_assert_cmpuint (check_pixels (f, 255), ==, ++n);
    last_id = f->frame_id;
  }
  /* ... so the next one comes back as it was, success, with an old frame in it. */
  DsFrame probe = { .frame_id = last_id };
  send_stray_packet (r, id_ahead (&probe));
  g_autoptr (DsFrame) f = trigger_and_grab (r->cam, &error);
  g_assert_no_error (error);
  g_assert_cmpuint (check_pixels (f, 255), ==, n + 1); /* the trigger's frame, not a copy */
  g_assert_cmpuint (f->frame_id, ==, last_id + 1);
  g_assert_cmpuint (f->ids_skipped, ==, 0);
  g_assert_cmpuint (r->cam->ops->flush (r->cam->backend), ==, 0);
  DsCameraStats st;
  r->cam->ops->get_stats (r->cam->backend, &st);
  g_assert_cmpuint (st.unfilled_buffers, ==, 2);
  g_assert_cmpuint (st.completed, ==, N_BUFFERS + 3);
  g_assert_cmpuint (st.failures, ==, 0);
  g_clear_pointer (&f, ds_frame_free);
  r->cam->ops->stop (r->cam->backend);
  guint in, out, pool;
  ds_aravis_camera_pool_counts (r->cam, &in, &out, &pool);
  g_assert_cmpuint (in, ==, N_BUFFERS);
}

static void
test_open_bad_arguments (void)
{
  g_autoptr (GError) error = NULL;
  DsCamera *cam = ds_aravis_camera_open ("", 4, &error);
  g_assert_null (cam);
  g_assert_error (error, DS_CAMERA_ERROR, DS_DEVICE_ERROR_INVALID);
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  g_test_add_func ("/aravis/open-bad-arguments", test_open_bad_arguments);
#define ADD(path, fn) g_test_add (path, Rig, NULL, rig_setup, fn, rig_teardown)
  ADD ("/aravis/mono8-pixels", test_mono8);
  ADD ("/aravis/mono16-pixels", test_mono16);
  ADD ("/aravis/bad-settings", test_bad_settings);
  ADD ("/aravis/ids-across-wrap", test_ids_across_wrap);
  ADD ("/aravis/packet-loss", test_packet_loss);
  ADD ("/aravis/loss-counted-once", test_loss_counted_once);
  ADD ("/aravis/flush", test_flush);
  ADD ("/aravis/unfilled-buffers", test_unfilled_buffers);
  ADD ("/aravis/disconnect-reconnect", test_disconnect_reconnect);
  ADD ("/aravis/lent-buffers", test_lent_buffers);
  ADD ("/aravis/control-lost-during-close", test_control_lost_during_close);
  ADD ("/aravis/control-lost-window", test_control_lost_window);
  int rc = g_test_run ();
  arv_shutdown ();
  return rc;
}
