/* The `preview` command and preview frames on the socket (docs/protocol.md, `preview`).
 *
 * Preview is for a person aligning the rig: it refuses to start over work somebody asked for
 * (a capture, calibrate or dark queued or running, or continuous acquisition) with `busy`,
 * since silently pausing a run would lose its sets; a capture, start or dark sent while preview
 * runs ends preview instead (the acquisition thread does that), because the user who asks for a
 * set wants it now, and preview is only looking.
 *
 * Frames for `subscribe {"frames": true}` connections: the acquisition thread copies a frame
 * only when such a connection exists and the previous copy was published (one in flight), so a
 * slow main loop or client costs frames, never memory or the camera's rate. */
#include "daemon/service/service_private.h"

#include <string.h>

#include "daemon/output/result_meta.h"
#include "daemon/protocol/protocol.h"
#include "daemon/service/json_build.h"

/* The wire's lights, in DsPreviewLight order. */
static const char *const light_names[] = { "all", "off", "phase", NULL };

static gboolean
work_in_progress (DsService *svc, const char **what)
{
  if (svc->in_run) {
    *what = "continuous acquisition is running (send stop or cancel first)";
    return TRUE;
  }
  GHashTableIter it;
  gpointer value;
  g_hash_table_iter_init (&it, svc->pending);
  while (g_hash_table_iter_next (&it, NULL, &value))
    if (((PendingCapture *) value)->cancellable) {
      *what = "a capture, calibrate or dark frame is queued or running (wait for it, or send cancel)";
      return TRUE;
    }
  return FALSE;
}

void
ds_service_handle_preview (DsService *svc, DsConnection *conn, DsRequest *req)
{
  static const char *const keys[] = { "state", "light", "phase", NULL };
  static const char *const states[] = { "on", "off", NULL };
  g_autoptr (GError) error = NULL;
  const char *state = NULL, *light = NULL;
  guint64 phase = 0;
  DsCaptureSettings defaults;
  ds_capture_settings_from_config (&defaults, svc->config);
  if (!ds_request_check_keys (req, keys, &error) ||
      !ds_request_get_choice (req, "state", states, NULL, &state, &error) ||
      !ds_request_get_choice (req, "light", light_names, "all", &light, &error) ||
      !ds_request_get_uint (req, "phase", 0, defaults.phases - 1, 0, &phase, &error)) {
    ds_server_reply_error (svc->server, conn, req->id, error);
    return;
  }
  if (!state)
    g_set_error (&error, DS_PROTOCOL_ERROR, DS_PROTOCOL_ERROR_BAD_ARGUMENT,
                 "preview: \"state\" is required (\"on\" or \"off\")");
  gboolean on = state && strcmp (state, "on") == 0;
  gboolean has_phase = json_object_has_member (req->args, "phase");
  DsPreviewLight l = DS_PREVIEW_LIGHT_ALL;
  while (l < DS_PREVIEW_LIGHT_N && strcmp (ds_preview_light_name (l), light) != 0)
    l++;
  if (!error && !on && (json_object_has_member (req->args, "light") || has_phase))
    g_set_error (&error, DS_PROTOCOL_ERROR, DS_PROTOCOL_ERROR_BAD_ARGUMENT,
                 "preview: \"light\" and \"phase\" go with \"state\": \"on\" only");
  else if (!error && on && (l == DS_PREVIEW_LIGHT_PHASE) != has_phase)
    g_set_error (&error, DS_PROTOCOL_ERROR, DS_PROTOCOL_ERROR_BAD_ARGUMENT,
                 "preview: \"phase\" (0..%u, of the %u configured phases) goes with \"light\": \"phase\", and only "
                 "with it",
                 defaults.phases - 1, defaults.phases);
  const char *what;
  if (!error && on && work_in_progress (svc, &what))
    g_set_error (&error, DS_PROTOCOL_ERROR, DS_PROTOCOL_ERROR_BUSY, "preview: %s", what);
  if (error) {
    ds_server_reply_error (svc->server, conn, req->id, error);
    return;
  }
  guint64 tag = ++svc->next_tag;
  /* While the devices open, preview waits in the queue like every request: the thread takes it
   * once they are open, or answers device_error when they fail to open. busy is the full queue. */
  if (!ds_sequencer_preview (svc->sequencer, on, l, (guint) phase, tag)) {
    g_set_error (&error, DS_PROTOCOL_ERROR, DS_PROTOCOL_ERROR_BUSY, "preview: too many requests queued; try again "
                 "later");
    ds_server_reply_error (svc->server, conn, req->id, error);
    return;
  }
  PendingCapture *p = ds_service_pending_add (svc, conn, req, tag);
  p->preview = TRUE;
}

void
ds_service_reply_preview (DsService *svc, DsConnection *conn, JsonNode *id, const char *message)
{
  DsSequencerStatus st;
  ds_sequencer_get_status (svc->sequencer, &st);
  g_autoptr (JsonBuilder) b = ds_json_object_begin ();
  ds_json_add_string (b, "state", ds_sequencer_state_name (st.state));
  ds_json_add_string (b, "light", st.preview.on ? ds_preview_light_name (st.preview.light) : NULL);
  if (st.preview.on && st.preview.light == DS_PREVIEW_LIGHT_PHASE)
    ds_json_add_uint (b, "phase", st.preview.phase);
  else
    ds_json_add_node (b, "phase", NULL);
  ds_json_add_string (b, "message", message);
  g_autoptr (JsonNode) body = ds_json_object_end (b);
  ds_service_reply_ok (svc, conn, id, body);
}

JsonNode *
ds_service_preview_status_json (const DsSequencerStatus *st)
{
  const DsPreviewStatus *p = &st->preview;
  g_autoptr (JsonBuilder) b = ds_json_object_begin ();
  ds_json_add_bool (b, "on", p->on);
  ds_json_add_string (b, "light", p->on ? ds_preview_light_name (p->light) : NULL);
  if (p->on && p->light == DS_PREVIEW_LIGHT_PHASE)
    ds_json_add_uint (b, "phase", p->phase);
  else
    ds_json_add_node (b, "phase", NULL);
  ds_json_add_uint (b, "phases", p->n_phases);
  ds_json_add_uint (b, "frames", p->frames);
  ds_json_add_double_or_null (b, "fps", p->fps);
  return ds_json_object_end (b);
}

/* ---- frames to the socket ---- */

typedef struct {
  DsService *svc;
  JsonNode *body;
  DsPayloadInfo info;
  GBytes *pixels;
} PreviewFrame;

static void
preview_frame_free (gpointer data)
{
  PreviewFrame *f = data;
  json_node_unref (f->body);
  g_bytes_unref (f->pixels);
  g_free (f);
}

static gboolean
publish_frame (gpointer data)
{
  PreviewFrame *f = data;
  ds_server_publish_frame (f->svc->server, f->body, &f->info, f->pixels);
  g_atomic_int_set (&f->svc->preview_frame_in_flight, 0);
  return G_SOURCE_REMOVE;
}

void
ds_service_on_preview_frame (const DsFrame *frame, DsPreviewLight light, guint phase, guint n_phases,
                             gpointer user_data)
{
  DsService *svc = user_data;
  if (ds_server_frame_subscribers (svc->server) == 0 ||
      !g_atomic_int_compare_and_exchange (&svc->preview_frame_in_flight, 0, 1))
    return;
  const DsImage *img = frame->image;
  gsize row = img->width * ds_sample_size (img->type);
  guint8 *pixels = g_malloc (row * img->height);
  /* Rows packed, as every payload (the camera's buffer may pad them). */
  for (guint y = 0; y < img->height; y++)
    memcpy (pixels + y * row, ds_image_row (img, y), row);
  PreviewFrame *f = g_new0 (PreviewFrame, 1);
  f->svc = svc;
  f->pixels = g_bytes_new_take (pixels, row * img->height);
  f->info = (DsPayloadInfo) { .name = "frame", .dtype = img->type == DS_SAMPLE_U8 ? "u8" : "u16",
                              .width = img->width, .height = img->height, .bytes = row * img->height };
  g_autoptr (JsonBuilder) b = ds_json_object_begin ();
  ds_json_add_uint (b, "frame_id", frame->frame_id);
  ds_json_add_uint (b, "timestamp_ns", frame->timestamp_ns);
  ds_json_add_string (b, "light", ds_preview_light_name (light));
  if (light == DS_PREVIEW_LIGHT_PHASE)
    ds_json_add_uint (b, "phase", phase);
  else
    ds_json_add_node (b, "phase", NULL);
  ds_json_add_uint (b, "phases", n_phases);
  ds_json_add_double_or_null (b, "exposure_us", frame->exposure_us);
  ds_json_add_double_or_null (b, "gain_db", frame->gain_db);
  ds_json_add_uint (b, "bit_depth", img->bit_depth);
  f->body = ds_json_object_end (b);
  g_main_context_invoke_full (g_main_loop_get_context (svc->loop), G_PRIORITY_DEFAULT, publish_frame, f,
                              preview_frame_free);
}
