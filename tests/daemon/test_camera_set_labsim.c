/* `set` against descatter-labsim: a real GigE Vision camera (Aravis's fake camera rendering the
 * simulator) and a Modbus TCP illuminator on loopback, driven by the daemon's Aravis and Modbus
 * backends. The expectations: the rendered light is linear in exposure below clipping, so the
 * dark-subtracted mean doubles with it; the region the camera streams is the result's size
 * (the stream is rebuilt for the new payload); a gain outside the range the camera itself
 * reports (GenICam Gain bounds, read here with Aravis, not through the daemon) is refused
 * naming that range, and nothing changes. Usage:
 *   test_camera_set_labsim LABSIM SCENE
 * Binds UDP 3956: ctest runs it in a private network namespace under RESOURCE_LOCK
 * gige_port_3956. */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include <arv.h>

#include "drivers/sim/scene.h"
#include "tests/common/daemon_harness.h"

static const char *labsim_path, *scene_path;

static double
mean_of (DsMessage *m)
{
  g_assert_cmpuint (m->reply->n_payloads, ==, 1);
  const DsPayloadInfo *pi = &m->reply->payloads[0];
  g_assert_cmpstr (pi->name, ==, "mean");
  const float *px = g_bytes_get_data (m->payloads[0], NULL);
  double sum = 0;
  for (guint64 i = 0; i < (guint64) pi->width * pi->height; i++)
    sum += px[i];
  return sum / ((double) pi->width * pi->height);
}

static DsMessage *
capture_mean_plane (DsClient *c)
{
  g_autoptr (JsonObject) args = json_object_new ();
  json_object_set_int_member (args, "phases", 4);
  g_autoptr (JsonArray) outputs = json_array_new ();
  json_array_add_string_element (outputs, "mean");
  json_object_set_array_member (args, "outputs", json_array_ref (outputs));
  return test_daemon_call_ok (c, "capture", args);
}

static void
test_set_over_the_wire (void)
{
  g_autoptr (GError) error = NULL;
  g_autoptr (DsScene) scene = ds_scene_load (scene_path, &error);
  g_assert_no_error (error);
  /* Half the scene's exposure: twice it is the scene's own, which it is made not to clip at. */
  double e0 = ds_scene_default_exposure_us (scene) / 2;
  TestLabsim *l = test_labsim_start (labsim_path, scene_path, NULL);

  /* The camera's gain range as the camera reports it, read before the daemon takes control. */
  double gmin = 0, gmax = 0;
  {
    g_autoptr (ArvCamera) cam = arv_camera_new ("127.0.0.1", &error);
    g_assert_no_error (error);
    arv_camera_get_gain_bounds (cam, &gmin, &gmax, &error);
    g_assert_no_error (error);
  }
  g_test_message ("the camera's gain range: [%g, %g] dB", gmin, gmax);

  g_autofree char *conf = g_strdup_printf (
    "[camera]\nbackend=aravis\naddress=127.0.0.1\npixel-format=Mono16\nexposure-us=%g\ngrab-timeout-ms=2000\n"
    "[illuminator]\nbackend=modbus\nmodbus-uri=tcp://127.0.0.1:%u\nmodbus-timeout-ms=300\nperiod-px=%g\nduty=%g\n"
    "[acquisition]\nphases=4\ndark-frame=true\nphase-retries=4\n",
    e0, l->modbus_port, ds_scene_period_px (scene), ds_scene_duty (scene));
  TestDaemon *d = test_daemon_start (conf, NULL);
  g_autoptr (DsClient) c = test_daemon_connect (d);

  g_autoptr (DsMessage) m1 = capture_mean_plane (c);
  double before = mean_of (m1);
  g_autoptr (JsonObject) exp_args = json_object_new ();
  json_object_set_double_member (exp_args, "exposure_us", 2 * e0);
  g_autoptr (DsMessage) r1 = test_daemon_call_ok (c, "set", exp_args);
  g_autoptr (DsMessage) m2 = capture_mean_plane (c);
  double after = mean_of (m2);
  g_test_message ("labsim: mean at %g µs %.2f, at %g µs %.2f: ratio %.4f", e0, before, 2 * e0, after, after / before);
  g_assert_cmpfloat (before, >, 0);
  g_assert_cmpfloat (fabs (after / before - 2.0), <, 0.05);

  /* Out of the camera's own range: refused naming it; nothing changed. */
  if (gmax < 48) {
    g_autoptr (JsonObject) g = json_object_new ();
    json_object_set_double_member (g, "gain_db", gmax + 1);
    g_autoptr (GError) e = NULL;
    g_autoptr (DsMessage) rg = ds_client_call (c, "set", g, NULL, NULL, &e);
    g_assert_no_error (e);
    g_assert_false (rg->reply->ok);
    g_test_message ("%s", rg->reply->error_message);
    g_assert_cmpint (rg->reply->error_code, ==, DS_PROTOCOL_ERROR_BAD_ARGUMENT);
    g_autofree char *range = g_strdup_printf ("gain %g dB outside [%g, %g]", gmax + 1, gmin, gmax);
    g_assert_nonnull (strstr (rg->reply->error_message, "aravis camera"));
    g_assert_nonnull (strstr (rg->reply->error_message, range));
  }
  g_autoptr (DsMessage) st = test_daemon_call_ok (c, "status", NULL);
  JsonObject *cam = json_object_get_object_member (json_node_get_object (st->reply->body), "camera");
  g_assert_cmpfloat (json_object_get_double_member (cam, "exposure_us"), ==, 2 * e0);
  g_assert_cmpfloat (json_object_get_double_member (cam, "gain_db"), ==, 0);
  JsonObject *ranges = json_object_get_object_member (cam, "ranges");
  g_assert_cmpfloat (json_object_get_double_member (ranges, "gain_max_db"), ==, gmax);

  /* A region: the camera streams it, the result has its size. */
  guint sw = (guint) json_object_get_int_member (ranges, "sensor_width");
  guint sh = (guint) json_object_get_int_member (ranges, "sensor_height");
  g_autoptr (JsonObject) roi_args = json_object_new ();
  g_autoptr (JsonObject) roi = json_object_new ();
  json_object_set_int_member (roi, "x", sw / 4);
  json_object_set_int_member (roi, "y", sh / 4);
  json_object_set_int_member (roi, "width", sw / 2);
  json_object_set_int_member (roi, "height", sh / 2);
  json_object_set_object_member (roi_args, "roi", json_object_ref (roi));
  g_autoptr (DsMessage) r2 = test_daemon_call_ok (c, "set", roi_args);
  g_autoptr (DsMessage) m3 = capture_mean_plane (c);
  g_assert_cmpuint (m3->reply->payloads[0].width, ==, sw / 2);
  g_assert_cmpuint (m3->reply->payloads[0].height, ==, sh / 2);
  g_assert_cmpint (test_json_int (m3->reply->body, "settings.roi.x"), ==, sw / 4);
  test_daemon_frames (c);
  test_daemon_stop_clean (d);
  test_labsim_stop (l);
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  if (argc < 3) {
    fprintf (stderr, "usage: test_camera_set_labsim LABSIM SCENE\n");
    return 2;
  }
  labsim_path = argv[1];
  scene_path = argv[2];
  g_test_add_func ("/camera-set-labsim/over-the-wire", test_set_over_the_wire);
  return g_test_run ();
}
