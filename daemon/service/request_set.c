/* The `set` command (docs/protocol.md, `set`): exposure, gain and region of interest applied to
 * the open camera by the acquisition thread between two sets (daemon/acquire/camera_live.h),
 * and the camera's settings as status and the captures without their own exposure and gain
 * see them. Main thread. */
#include "daemon/service/service_private.h"

#include <string.h>

#include "daemon/protocol/protocol.h"
#include "daemon/service/json_build.h"

/* One member of "roi": a whole number 0..65535. */
static gboolean
roi_member (JsonObject *roi, const char *key, guint min, guint *out, GError **error)
{
  JsonNode *n = json_object_get_member (roi, key);
  gboolean is_number = n && JSON_NODE_HOLDS_VALUE (n) &&
                       (json_node_get_value_type (n) == G_TYPE_INT64 || json_node_get_value_type (n) == G_TYPE_DOUBLE);
  double v = is_number ? json_node_get_double (n) : -1;
  if (!is_number || v != (double) (gint64) v || v < min || v > 65535) {
    g_set_error (error, DS_PROTOCOL_ERROR, DS_PROTOCOL_ERROR_BAD_ARGUMENT,
                 "\"roi\".%s must be a whole number in [%u, 65535]", key, min);
    return FALSE;
  }
  *out = (guint) v;
  return TRUE;
}

/* "roi": {"x", "y", "width", "height"}, all four; absent: no change. */
static gboolean
roi_from_request (const DsRequest *req, DsCameraChange *c, GError **error)
{
  JsonNode *node = json_object_get_member (req->args, "roi");
  if (!node)
    return TRUE;
  static const char *const keys[] = { "x", "y", "width", "height" };
  if (!JSON_NODE_HOLDS_OBJECT (node) || json_object_get_size (json_node_get_object (node)) != G_N_ELEMENTS (keys)) {
    g_set_error (error, DS_PROTOCOL_ERROR, DS_PROTOCOL_ERROR_BAD_ARGUMENT,
                 "\"roi\" must be an object with x, y, width and height (pixels on the sensor)");
    return FALSE;
  }
  JsonObject *roi = json_node_get_object (node);
  guint *fields[] = { &c->roi_x, &c->roi_y, &c->roi_width, &c->roi_height };
  for (guint i = 0; i < G_N_ELEMENTS (keys); i++)
    if (!roi_member (roi, keys[i], i < 2 ? 0 : 1, fields[i], error))
      return FALSE;
  c->has_roi = TRUE;
  return TRUE;
}

void
ds_service_handle_set (DsService *svc, DsConnection *conn, DsRequest *req)
{
  static const char *const keys[] = { "exposure_us", "gain_db", "roi", NULL };
  g_autoptr (GError) error = NULL;
  DsCameraChange c = { 0 };
  /* The wire's bounds are the capture's; the camera's own range is checked where the camera is
   * (the acquisition thread), against what it reported. */
  if (!ds_request_check_keys (req, keys, &error) ||
      !ds_request_get_double (req, "exposure_us", 1.0, 10e6, 0, &c.exposure_us, &error) ||
      !ds_request_get_double (req, "gain_db", 0.0, 48.0, 0, &c.gain_db, &error) ||
      !roi_from_request (req, &c, &error)) {
    ds_server_reply_error (svc->server, conn, req->id, error);
    return;
  }
  c.has_exposure = json_object_has_member (req->args, "exposure_us");
  c.has_gain = json_object_has_member (req->args, "gain_db");
  if (!c.has_exposure && !c.has_gain && !c.has_roi) {
    g_set_error (&error, DS_PROTOCOL_ERROR, DS_PROTOCOL_ERROR_BAD_ARGUMENT,
                 "set: nothing to set: give exposure_us, gain_db or roi (status shows them as they are)");
    ds_server_reply_error (svc->server, conn, req->id, error);
    return;
  }
  guint64 tag = ++svc->next_tag;
  if (!ds_sequencer_set_camera (svc->sequencer, &c, tag)) {
    g_set_error (&error, DS_PROTOCOL_ERROR, DS_PROTOCOL_ERROR_BUSY, "set: too many requests queued; try again later");
    ds_server_reply_error (svc->server, conn, req->id, error);
    return;
  }
  ds_service_pending_add (svc, conn, req, tag)->camera_set = TRUE;
}

/* exposure_us, gain_db, roi {x, y, width, height}: the object `set` replies and status shows. */
static void
add_live (JsonBuilder *b, const DsCameraLive *live)
{
  ds_json_add_double (b, "exposure_us", live->exposure_us);
  ds_json_add_double (b, "gain_db", live->gain_db);
  ds_json_begin_member_object (b, "roi");
  ds_json_add_uint (b, "x", live->roi_x);
  ds_json_add_uint (b, "y", live->roi_y);
  ds_json_add_uint (b, "width", live->roi_width);
  ds_json_add_uint (b, "height", live->roi_height);
  json_builder_end_object (b);
}

void
ds_service_reply_camera_set (DsService *svc, DsConnection *conn, JsonNode *id)
{
  DsSequencerStatus st;
  ds_sequencer_get_status (svc->sequencer, &st);
  g_autoptr (JsonBuilder) b = ds_json_object_begin ();
  ds_json_begin_member_object (b, "camera");
  add_live (b, &st.camera_live);
  json_builder_end_object (b);
  g_autoptr (JsonNode) body = ds_json_object_end (b);
  ds_service_reply_ok (svc, conn, id, body);
}

void
ds_service_status_add_camera_live (JsonBuilder *b, const DsSequencerStatus *st)
{
  json_builder_set_member_name (b, "camera");
  if (!st->camera_live_known) {
    json_builder_add_null_value (b);
    return;
  }
  json_builder_begin_object (b);
  add_live (b, &st->camera_live);
  /* The camera's own ranges, as it reported them when it opened: what `set` accepts. */
  const DsCameraInfo *i = &st->camera_info;
  ds_json_begin_member_object (b, "ranges");
  ds_json_add_double (b, "exposure_min_us", i->exposure_min_us);
  ds_json_add_double (b, "exposure_max_us", i->exposure_max_us);
  ds_json_add_bool (b, "has_gain", i->has_gain);
  ds_json_add_double (b, "gain_min_db", i->gain_min_db);
  ds_json_add_double (b, "gain_max_db", i->gain_max_db);
  ds_json_add_uint (b, "sensor_width", i->sensor_width);
  ds_json_add_uint (b, "sensor_height", i->sensor_height);
  json_builder_end_object (b);
  json_builder_end_object (b);
}

void
ds_service_camera_defaults (DsService *svc, DsCaptureSettings *s)
{
  DsSequencerStatus st;
  ds_sequencer_get_status (svc->sequencer, &st);
  if (!st.camera_live_known)
    return;
  s->exposure_us = st.camera_live.exposure_us;
  s->gain_db = st.camera_live.gain_db;
}
