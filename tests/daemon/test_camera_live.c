/* The `set` command at the acquisition thread (daemon/acquire/camera_live.c) against a mock
 * camera that records every configure and reports its own ranges, so that what reaches the
 * camera is seen call by call: a change within the ranges is configured on a stopped camera and
 * started again; a value out of range never reaches the camera; a value the camera itself
 * refuses (between its bounds, off its increments) leaves it configured as before. The ranges
 * and the refusal are the mock's, written here; the expected messages are the range check's
 * wording as docs/protocol.md gives it. */
#include <math.h>
#include <string.h>

#include "daemon/acquire/sequencer.h"
#include "daemon/protocol/protocol.h"
#include "tests/daemon/scripted_lab.h"

#define SENSOR_W 64
#define SENSOR_H 48
#define GAIN_MAX 10.0
#define EXPOSURE_MIN 10.0
#define EXPOSURE_MAX 100000.0
/* The mock refuses this exposure although it lies within its bounds (off its increments). */
#define EXPOSURE_REFUSED 777.0

typedef struct {
  GPtrArray *configured; /* DsCameraSettings *, in call order */
  gboolean started;
  guint starts_while_started;
} MockCam;

static gboolean
cam_configure (gpointer b, const DsCameraSettings *s, GError **error)
{
  MockCam *m = b;
  g_assert_false (m->started); /* the camera interface: configure only a stopped camera */
  if (s->exposure_us == EXPOSURE_REFUSED) {
    g_set_error (error, DS_DEVICE_ERROR, DS_DEVICE_ERROR_INVALID, "mock camera: exposure %g µs not on its 1 ms steps",
                 s->exposure_us);
    return FALSE;
  }
  g_ptr_array_add (m->configured, g_memdup2 (s, sizeof *s));
  return TRUE;
}

static gboolean
cam_start (gpointer b, GError **error)
{
  (void) error;
  MockCam *m = b;
  m->starts_while_started += m->started;
  m->started = TRUE;
  return TRUE;
}

static void
cam_stop (gpointer b)
{
  ((MockCam *) b)->started = FALSE;
}

static gboolean
cam_trigger (gpointer b, GError **error)
{
  (void) b;
  g_set_error (error, DS_DEVICE_ERROR, DS_DEVICE_ERROR_UNSUPPORTED, "mock camera: no frames");
  return FALSE;
}

static DsFrame *
cam_grab (gpointer b, guint timeout_ms, GError **error)
{
  (void) b;
  (void) timeout_ms;
  g_set_error (error, DS_DEVICE_ERROR, DS_DEVICE_ERROR_TIMEOUT, "mock camera: no frames");
  return NULL;
}

static guint
cam_flush (gpointer b)
{
  (void) b;
  return 0;
}

static gboolean
cam_reconnect (gpointer b, GError **error)
{
  (void) b;
  (void) error;
  return TRUE;
}

static void
cam_stats (gpointer b, DsCameraStats *s)
{
  (void) b;
  memset (s, 0, sizeof *s);
}

static void
cam_info (gpointer b, DsCameraInfo *i)
{
  (void) b;
  memset (i, 0, sizeof *i);
  g_strlcpy (i->vendor, "mock", sizeof i->vendor);
  i->sensor_width = SENSOR_W;
  i->sensor_height = SENSOR_H;
  i->connected = TRUE;
  i->has_gain = TRUE;
  i->gain_min_db = 0;
  i->gain_max_db = GAIN_MAX;
  i->exposure_min_us = EXPOSURE_MIN;
  i->exposure_max_us = EXPOSURE_MAX;
}

static void
cam_close (gpointer b)
{
  (void) b;
}

static const DsCameraOps cam_ops = { "mock", cam_configure, cam_start, cam_trigger, cam_grab, cam_flush,
                                     cam_stop, cam_reconnect, cam_stats, cam_info, cam_close, NULL };

static gboolean
ill_pattern (gpointer b, const DsStripePattern *p, GError **e)
{
  (void) b;
  (void) p;
  (void) e;
  return TRUE;
}

static gboolean
ill_phase (gpointer b, guint phase, guint timeout_ms, GError **e)
{
  (void) b;
  (void) phase;
  (void) timeout_ms;
  (void) e;
  return TRUE;
}

static gboolean
ill_off (gpointer b, guint timeout_ms, GError **e)
{
  (void) b;
  (void) timeout_ms;
  (void) e;
  return TRUE;
}

static gboolean
ill_status (gpointer b, DsIlluminatorStatus *s, GError **e)
{
  (void) b;
  (void) e;
  memset (s, 0, sizeof *s);
  s->ready = TRUE;
  s->applied_phase = -1;
  return TRUE;
}

static gboolean
ill_reconnect (gpointer b, GError **e)
{
  (void) b;
  (void) e;
  return TRUE;
}

static void
ill_close (gpointer b)
{
  (void) b;
}

/* No all_on: preview's "all" is not what this test drives. */
static const DsIlluminatorOps ill_ops = { "mock", ill_pattern, ill_phase, ill_off, ill_status, ill_reconnect,
                                          ill_close, NULL };

static DsDevices *
open_mock (gpointer data, GError **error)
{
  (void) error;
  return scripted_devices_new (&cam_ops, &ill_ops, data, "mock");
}

typedef struct {
  GMainLoop *loop;
  gboolean ready;
  GError *control_error;
  guint controls;
} Out;

static void
on_event (const DsSequencerEvent *ev, gpointer data)
{
  Out *o = data;
  if (ev->kind == DS_SEQUENCER_EVENT_READY) {
    o->ready = ev->error == NULL;
    g_main_loop_quit (o->loop);
  } else if (ev->kind == DS_SEQUENCER_EVENT_CONTROL) {
    o->controls++;
    g_clear_error (&o->control_error);
    if (ev->error)
      o->control_error = g_error_copy (ev->error);
    g_main_loop_quit (o->loop);
  }
}

/* Sends change and waits for its answer. */
static void
set_and_wait (DsSequencer *seq, Out *o, const DsCameraChange *change)
{
  guint before = o->controls;
  g_assert_true (ds_sequencer_set_camera (seq, change, 7));
  while (o->controls == before)
    g_main_loop_run (o->loop);
}

static const DsCameraSettings *
last_configured (MockCam *m)
{
  g_assert_cmpuint (m->configured->len, >, 0);
  return m->configured->pdata[m->configured->len - 1];
}

static void
test_set_reaches_the_camera (void)
{
  MockCam m = { .configured = g_ptr_array_new_with_free_func (g_free) };
  Out o = { .loop = g_main_loop_new (NULL, FALSE) };
  DsCaptureSettings s = { .phases = 8, .averages = 1, .exposure_us = 1000, .gain_db = 0,
                          .phase_tolerance_deg = 22.5 };
  DsSequencer *seq = ds_sequencer_new (open_mock, &m, &s, g_main_context_default (), on_event, &o);
  g_main_loop_run (o.loop);
  g_assert_true (o.ready);
  guint configured_at_open = m.configured->len;
  g_assert_cmpuint (configured_at_open, >, 0);

  /* Within the ranges: configured (on a stopped camera), started again, in status. */
  DsCameraChange c = { .has_exposure = TRUE, .exposure_us = 2000, .has_gain = TRUE, .gain_db = 6,
                       .has_roi = TRUE, .roi_x = 8, .roi_y = 4, .roi_width = 32, .roi_height = 16 };
  set_and_wait (seq, &o, &c);
  g_assert_no_error (o.control_error);
  const DsCameraSettings *cs = last_configured (&m);
  g_assert_cmpfloat (cs->exposure_us, ==, 2000);
  g_assert_cmpfloat (cs->gain_db, ==, 6);
  g_assert_cmpuint (cs->roi_x, ==, 8);
  g_assert_cmpuint (cs->roi_y, ==, 4);
  g_assert_cmpuint (cs->roi_width, ==, 32);
  g_assert_cmpuint (cs->roi_height, ==, 16);
  g_assert_true (m.started);
  g_assert_cmpuint (m.starts_while_started, ==, 0);
  DsSequencerStatus st;
  ds_sequencer_get_status (seq, &st);
  g_assert_true (st.camera_live_known);
  g_assert_cmpfloat (st.camera_live.exposure_us, ==, 2000);
  g_assert_cmpuint (st.camera_live.roi_width, ==, 32);

  /* Out of the camera's ranges: refused with the range, the camera never asked. */
  struct {
    DsCameraChange change;
    const char *message;
  } refused[] = {
    { { .has_gain = TRUE, .gain_db = GAIN_MAX + 2 }, "mock camera: gain 12 dB outside [0, 10]" },
    { { .has_exposure = TRUE, .exposure_us = EXPOSURE_MIN / 2 }, "mock camera: exposure 5 µs outside [10, 100000]" },
    { { .has_roi = TRUE, .roi_x = 40, .roi_y = 0, .roi_width = 32, .roi_height = 8 },
      "mock camera: ROI 40,0 32x8 outside the 64x48 sensor" },
  };
  for (guint i = 0; i < G_N_ELEMENTS (refused); i++) {
    guint n = m.configured->len;
    set_and_wait (seq, &o, &refused[i].change);
    g_assert_error (o.control_error, DS_PROTOCOL_ERROR, DS_PROTOCOL_ERROR_BAD_ARGUMENT);
    g_assert_cmpstr (o.control_error->message, ==, refused[i].message);
    g_assert_cmpuint (m.configured->len, ==, n);
  }

  /* Refused by the camera itself: bad_argument with its words; configured back as it was. */
  DsCameraChange off_steps = { .has_exposure = TRUE, .exposure_us = EXPOSURE_REFUSED };
  set_and_wait (seq, &o, &off_steps);
  g_assert_error (o.control_error, DS_PROTOCOL_ERROR, DS_PROTOCOL_ERROR_BAD_ARGUMENT);
  g_assert_nonnull (strstr (o.control_error->message, "not on its 1 ms steps"));
  cs = last_configured (&m);
  g_assert_cmpfloat (cs->exposure_us, ==, 2000);
  g_assert_cmpuint (cs->roi_width, ==, 32);
  ds_sequencer_get_status (seq, &st);
  g_assert_cmpfloat (st.camera_live.exposure_us, ==, 2000);
  g_assert_cmpfloat (st.camera_live.gain_db, ==, 6);

  /* New defaults (a reload) keep what set changed. */
  DsCaptureSettings reload = s;
  reload.exposure_us = 3000;
  ds_sequencer_set_defaults (seq, &reload);
  DsCameraChange gain_only = { .has_gain = TRUE, .gain_db = 3 };
  set_and_wait (seq, &o, &gain_only);
  g_assert_no_error (o.control_error);
  cs = last_configured (&m);
  g_assert_cmpfloat (cs->exposure_us, ==, 2000);
  g_assert_cmpfloat (cs->gain_db, ==, 3);
  g_assert_cmpuint (cs->roi_width, ==, 32);

  ds_sequencer_free (seq);
  g_clear_error (&o.control_error);
  g_main_loop_unref (o.loop);
  g_ptr_array_unref (m.configured);
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  g_test_add_func ("/camera-live/set-reaches-the-camera", test_set_reaches_the_camera);
  return g_test_run ();
}
