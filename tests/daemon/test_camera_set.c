/* `set` end to end on the in-process simulated lab (docs/protocol.md, `set`): exposure, gain and
 * region applied to the open camera. The expectations are physics and the camera's own ranges:
 * the simulated sensor is linear in exposure below clipping, so the mean of the dark-subtracted
 * phase frames doubles with the exposure; a region gives frames of its size; a value outside the
 * camera's range is refused naming it and the range, and nothing changes. */
#include <math.h>
#include <string.h>

#include "tests/common/daemon_harness.h"

static char *
config_text (void)
{
  /* An exposure well below clipping, so that twice it is still linear; every set subtracts its
   * own dark frame, so the mean is the light alone. */
  return g_strdup_printf ("[camera]\nbackend=sim\nexposure-us=1000\n[illuminator]\nbackend=sim\n"
                          "[acquisition]\ndark-frame=true\n[sim]\nscene=%s\nseed=7\n",
                          SCENE_FILE);
}

/* The mean over the result's "mean" plane (the average of its phase frames). */
static double
capture_mean (DsClient *c, guint *width, guint *height, DsMessage **keep)
{
  g_autoptr (JsonObject) args = json_object_new ();
  json_object_set_int_member (args, "phases", 4);
  g_autoptr (JsonArray) outputs = json_array_new ();
  json_array_add_string_element (outputs, "mean");
  json_object_set_array_member (args, "outputs", json_array_ref (outputs));
  DsMessage *m = test_daemon_call_ok (c, "capture", args);
  g_assert_cmpuint (m->reply->n_payloads, ==, 1);
  const DsPayloadInfo *pi = &m->reply->payloads[0];
  g_assert_cmpstr (pi->name, ==, "mean");
  g_assert_cmpstr (pi->dtype, ==, "f32");
  const float *px = g_bytes_get_data (m->payloads[0], NULL);
  double sum = 0;
  for (guint64 i = 0; i < (guint64) pi->width * pi->height; i++)
    sum += px[i];
  if (width)
    *width = pi->width;
  if (height)
    *height = pi->height;
  *keep = m;
  return sum / ((double) pi->width * pi->height);
}

static DsMessage *
call (DsClient *c, const char *cmd, JsonObject *args)
{
  g_autoptr (GError) error = NULL;
  DsMessage *m = ds_client_call (c, cmd, args, NULL, NULL, &error);
  g_assert_no_error (error);
  return m;
}

static JsonObject *
status_camera (DsClient *c, DsMessage **keep)
{
  *keep = test_daemon_call_ok (c, "status", NULL);
  JsonObject *st = json_node_get_object ((*keep)->reply->body);
  g_assert_true (json_object_has_member (st, "camera"));
  return json_object_get_object_member (st, "camera");
}

/* Exposure doubled by `set`: the next capture without an exposure of its own has twice the
 * light, reports the new exposure in its settings, and status shows it; a capture's explicit
 * exposure still wins. */
static void
test_set_exposure_scales_light (void)
{
  g_autofree char *conf = config_text ();
  TestDaemon *d = test_daemon_start (conf, NULL);
  g_autoptr (DsClient) c = test_daemon_connect (d);
  g_autoptr (DsMessage) m1 = NULL, m2 = NULL, m3 = NULL, st = NULL;
  double before = capture_mean (c, NULL, NULL, &m1);
  g_assert_cmpfloat (test_json_int (m1->reply->body, "settings.exposure_us"), ==, 1000);

  g_autoptr (JsonObject) args = json_object_new ();
  json_object_set_double_member (args, "exposure_us", 2000);
  g_autoptr (DsMessage) r = test_daemon_call_ok (c, "set", args);
  JsonObject *cam = json_object_get_object_member (json_node_get_object (r->reply->body), "camera");
  g_assert_cmpfloat (json_object_get_double_member (cam, "exposure_us"), ==, 2000);

  double after = capture_mean (c, NULL, NULL, &m2);
  g_test_message ("mean at 1000 µs %.3f, at 2000 µs %.3f: ratio %.4f", before, after, after / before);
  g_assert_cmpfloat (test_json_int (m2->reply->body, "settings.exposure_us"), ==, 2000);
  g_assert_cmpfloat (before, >, 0);
  g_assert_cmpfloat (fabs (after / before - 2.0), <, 0.05);
  JsonObject *sc = status_camera (c, &st);
  g_assert_cmpfloat (json_object_get_double_member (sc, "exposure_us"), ==, 2000);

  /* A capture's own exposure wins over the set one. */
  g_autoptr (JsonObject) own = json_object_new ();
  json_object_set_double_member (own, "exposure_us", 1000);
  json_object_set_int_member (own, "phases", 4);
  m3 = test_daemon_call_ok (c, "capture", own);
  g_assert_cmpfloat (test_json_int (m3->reply->body, "settings.exposure_us"), ==, 1000);
  test_daemon_stop_clean (d);
}

/* Values outside the camera's own range (status.camera.ranges, the simulated camera's gain
 * 0..SIM max) are refused bad_argument naming the value and the range; nothing changes. */
static void
test_set_out_of_range_refused (void)
{
  g_autofree char *conf = config_text ();
  TestDaemon *d = test_daemon_start (conf, NULL);
  g_autoptr (DsClient) c = test_daemon_connect (d);
  g_autoptr (DsMessage) st0 = NULL, st1 = NULL;
  JsonObject *cam0 = status_camera (c, &st0);
  JsonObject *ranges = json_object_get_object_member (cam0, "ranges");
  double gmax = json_object_get_double_member (ranges, "gain_max_db");
  guint sw = (guint) json_object_get_int_member (ranges, "sensor_width");
  guint sh = (guint) json_object_get_int_member (ranges, "sensor_height");
  g_assert_cmpuint (sw, >, 0);

  /* A region past the sensor's right edge, with a valid exposure in the same request. */
  g_autoptr (JsonObject) args = json_object_new ();
  json_object_set_double_member (args, "exposure_us", 3000);
  g_autoptr (JsonObject) roi = json_object_new ();
  json_object_set_int_member (roi, "x", sw / 2);
  json_object_set_int_member (roi, "y", 0);
  json_object_set_int_member (roi, "width", sw);
  json_object_set_int_member (roi, "height", sh);
  json_object_set_object_member (args, "roi", json_object_ref (roi));
  g_autoptr (DsMessage) r = call (c, "set", args);
  g_assert_false (r->reply->ok);
  g_test_message ("%s", r->reply->error_message);
  g_assert_cmpint (r->reply->error_code, ==, DS_PROTOCOL_ERROR_BAD_ARGUMENT);
  g_autofree char *sensor = g_strdup_printf ("outside the %ux%u sensor", sw, sh);
  g_assert_nonnull (strstr (r->reply->error_message, sensor));

  /* A gain above the camera's maximum, when the camera's maximum is below the wire's 48 dB. */
  if (gmax < 48) {
    g_autoptr (JsonObject) g = json_object_new ();
    json_object_set_double_member (g, "gain_db", gmax + 1);
    g_autoptr (DsMessage) rg = call (c, "set", g);
    g_assert_false (rg->reply->ok);
    g_assert_cmpint (rg->reply->error_code, ==, DS_PROTOCOL_ERROR_BAD_ARGUMENT);
    g_autofree char *range = g_strdup_printf ("outside [%g, %g]", json_object_get_double_member (ranges, "gain_min_db"),
                                              gmax);
    g_test_message ("%s", rg->reply->error_message);
    g_assert_nonnull (strstr (rg->reply->error_message, range));
  }
  JsonObject *cam1 = status_camera (c, &st1);
  g_assert_cmpfloat (json_object_get_double_member (cam1, "exposure_us"), ==,
                     json_object_get_double_member (cam0, "exposure_us"));
  g_assert_cmpfloat (json_object_get_double_member (cam1, "gain_db"), ==,
                     json_object_get_double_member (cam0, "gain_db"));
  JsonObject *roi1 = json_object_get_object_member (cam1, "roi");
  g_assert_cmpint (json_object_get_int_member (roi1, "width"), ==, sw);
  g_assert_cmpint (json_object_get_int_member (roi1, "x"), ==, 0);

  /* Nothing to set, and a malformed region: refused before the camera. */
  g_autoptr (DsMessage) empty = call (c, "set", NULL);
  g_assert_cmpint (empty->reply->error_code, ==, DS_PROTOCOL_ERROR_BAD_ARGUMENT);
  g_autoptr (JsonObject) bad = json_object_new ();
  g_autoptr (JsonObject) half = json_object_new ();
  json_object_set_int_member (half, "x", 0);
  json_object_set_object_member (bad, "roi", json_object_ref (half));
  g_autoptr (DsMessage) rb = call (c, "set", bad);
  g_assert_cmpint (rb->reply->error_code, ==, DS_PROTOCOL_ERROR_BAD_ARGUMENT);
  test_daemon_stop_clean (d);
}

/* A region: the next result has its size and reports it in settings.roi; the light per pixel of
 * the region equals the whole frame's there (the same scene, the same exposure). */
static void
test_set_roi_sizes_result (void)
{
  g_autofree char *conf = config_text ();
  TestDaemon *d = test_daemon_start (conf, NULL);
  g_autoptr (DsClient) c = test_daemon_connect (d);
  g_autoptr (DsMessage) m1 = NULL, m2 = NULL;
  guint w0, h0, w1, h1;
  capture_mean (c, &w0, &h0, &m1);
  guint rw = w0 / 2, rh = h0 / 2, rx = w0 / 4, ry = h0 / 4;
  g_autoptr (JsonObject) args = json_object_new ();
  g_autoptr (JsonObject) roi = json_object_new ();
  json_object_set_int_member (roi, "x", rx);
  json_object_set_int_member (roi, "y", ry);
  json_object_set_int_member (roi, "width", rw);
  json_object_set_int_member (roi, "height", rh);
  json_object_set_object_member (args, "roi", json_object_ref (roi));
  g_autoptr (DsMessage) r = test_daemon_call_ok (c, "set", args);
  capture_mean (c, &w1, &h1, &m2);
  g_assert_cmpuint (w1, ==, rw);
  g_assert_cmpuint (h1, ==, rh);
  g_assert_cmpint (test_json_int (m2->reply->body, "settings.roi.x"), ==, rx);
  g_assert_cmpint (test_json_int (m2->reply->body, "settings.roi.y"), ==, ry);
  g_assert_cmpint (test_json_int (m2->reply->body, "settings.roi.width"), ==, rw);
  g_assert_cmpint (test_json_int (m2->reply->body, "settings.roi.height"), ==, rh);
  g_assert_cmpint (test_json_int (m1->reply->body, "settings.roi.width"), ==, w0);
  test_daemon_stop_clean (d);
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  g_test_add_func ("/camera-set/exposure-scales-light", test_set_exposure_scales_light);
  g_test_add_func ("/camera-set/out-of-range-refused", test_set_out_of_range_refused);
  g_test_add_func ("/camera-set/roi-sizes-result", test_set_roi_sizes_result);
  return g_test_run ();
}
