#include "daemon/protocol/protocol.h"

#include "daemon/protocol/json_text.h"

#include <math.h>
#include <string.h>

G_DEFINE_QUARK (ds-protocol-error-quark, ds_protocol_error)

static const char *const error_names[] = {
  [DS_PROTOCOL_ERROR_LINE_TOO_LONG] = "line_too_long",
  [DS_PROTOCOL_ERROR_BAD_JSON] = "bad_json",
  [DS_PROTOCOL_ERROR_TOO_DEEP] = "too_deep",
  [DS_PROTOCOL_ERROR_BAD_REQUEST] = "bad_request",
  [DS_PROTOCOL_ERROR_UNKNOWN_COMMAND] = "unknown_command",
  [DS_PROTOCOL_ERROR_BAD_ARGUMENT] = "bad_argument",
  [DS_PROTOCOL_ERROR_BUSY] = "busy",
  [DS_PROTOCOL_ERROR_DEVICE] = "device_error",
  [DS_PROTOCOL_ERROR_UNAUTHORIZED] = "unauthorized",
  [DS_PROTOCOL_ERROR_LIMIT] = "limit",
  [DS_PROTOCOL_ERROR_FAILED] = "failed",
  [DS_PROTOCOL_ERROR_CANCELLED] = "cancelled",
  [DS_PROTOCOL_ERROR_BAD_REPLY] = "bad_reply",
};

const char *
ds_protocol_error_name (DsProtocolError code)
{
  if ((guint) code < G_N_ELEMENTS (error_names) && error_names[code])
    return error_names[code];
  return "failed";
}

DsProtocolError
ds_protocol_error_from_name (const char *name)
{
  for (guint i = 0; name && i < G_N_ELEMENTS (error_names); i++)
    if (error_names[i] && strcmp (error_names[i], name) == 0)
      return (DsProtocolError) i;
  return DS_PROTOCOL_ERROR_FAILED;
}

gsize
ds_dtype_size (const char *dtype)
{
  if (!dtype)
    return 0;
  if (strcmp (dtype, "u8") == 0)
    return 1;
  if (strcmp (dtype, "u16") == 0)
    return 2;
  if (strcmp (dtype, "f32") == 0)
    return 4;
  return 0;
}

static JsonNode *
parse_object_line (const char *line, gsize len, GError **error)
{
  if (len > DS_PROTOCOL_MAX_LINE) {
    g_set_error (error, DS_PROTOCOL_ERROR, DS_PROTOCOL_ERROR_LINE_TOO_LONG,
                 "line of %zu bytes exceeds the limit of %d", len, DS_PROTOCOL_MAX_LINE);
    return NULL;
  }
  const char *nul = memchr (line, '\0', len);
  if (nul) {
    g_set_error (error, DS_PROTOCOL_ERROR, DS_PROTOCOL_ERROR_BAD_JSON, "NUL byte at byte %zu",
                 (gsize) (nul - line));
    return NULL;
  }
  const char *end = NULL;
  if (!g_utf8_validate (line, (gssize) len, &end)) {
    g_set_error (error, DS_PROTOCOL_ERROR, DS_PROTOCOL_ERROR_BAD_JSON, "invalid UTF-8 at byte %zu",
                 (gsize) (end - line));
    return NULL;
  }
  /* Strict (json_text.h): json-glib's parser accepts what JSON does not, and drops a second
   * request on the same line without a word. */
  g_autoptr (JsonNode) root = ds_json_parse_strict (line, len, DS_PROTOCOL_MAX_DEPTH, error);
  if (!root)
    return NULL;
  if (!JSON_NODE_HOLDS_OBJECT (root)) {
    g_set_error (error, DS_PROTOCOL_ERROR, DS_PROTOCOL_ERROR_BAD_REQUEST,
                 "a message must be one JSON object");
    return NULL;
  }
  return g_steal_pointer (&root);
}

void
ds_request_free (DsRequest *request)
{
  if (!request)
    return;
  if (request->id)
    json_node_unref (request->id);
  g_free (request->cmd);
  if (request->args)
    json_object_unref (request->args);
  g_free (request);
}

DsRequest *
ds_request_parse (const char *line, gsize len, JsonNode **id_out, GError **error)
{
  if (id_out)
    *id_out = NULL;
  g_autoptr (JsonNode) root = parse_object_line (line, len, error);
  if (!root)
    return NULL;
  JsonObject *obj = json_node_get_object (root);
  JsonNode *id = json_object_get_member (obj, "id");
  GType id_type = id && JSON_NODE_HOLDS_VALUE (id) ? json_node_get_value_type (id) : G_TYPE_INVALID;
  if (id && !JSON_NODE_HOLDS_NULL (id) && id_type != G_TYPE_INT64 && id_type != G_TYPE_DOUBLE &&
      id_type != G_TYPE_STRING) {
    g_set_error (error, DS_PROTOCOL_ERROR, DS_PROTOCOL_ERROR_BAD_REQUEST,
                 "\"id\" must be a number or a string");
    return NULL;
  }
  if (id_out && id)
    *id_out = json_node_copy (id);
  JsonNode *cmd = json_object_get_member (obj, "cmd");
  if (!cmd || !JSON_NODE_HOLDS_VALUE (cmd) || json_node_get_value_type (cmd) != G_TYPE_STRING) {
    g_set_error (error, DS_PROTOCOL_ERROR, DS_PROTOCOL_ERROR_BAD_REQUEST,
                 "missing string member \"cmd\"");
    return NULL;
  }
  JsonNode *args = json_object_get_member (obj, "args");
  if (args && !JSON_NODE_HOLDS_OBJECT (args)) {
    g_set_error (error, DS_PROTOCOL_ERROR, DS_PROTOCOL_ERROR_BAD_REQUEST, "\"args\" must be an object");
    return NULL;
  }
  GList *members = json_object_get_members (obj);
  for (GList *l = members; l; l = l->next) {
    const char *m = l->data;
    if (strcmp (m, "id") != 0 && strcmp (m, "cmd") != 0 && strcmp (m, "args") != 0) {
      g_set_error (error, DS_PROTOCOL_ERROR, DS_PROTOCOL_ERROR_BAD_REQUEST,
                   "unknown member \"%s\" (a request has id, cmd, args)", m);
      g_list_free (members);
      return NULL;
    }
  }
  g_list_free (members);
  DsRequest *req = g_new0 (DsRequest, 1);
  req->id = id ? json_node_copy (id) : NULL;
  req->cmd = g_strdup (json_node_get_string (cmd));
  req->args = args ? json_object_ref (json_node_get_object (args)) : json_object_new ();
  return req;
}

gboolean
ds_request_check_keys (const DsRequest *request, const char *const *allowed, GError **error)
{
  GList *members = json_object_get_members (request->args);
  for (GList *l = members; l; l = l->next) {
    if (!g_strv_contains (allowed, l->data)) {
      g_autofree char *list = g_strjoinv (", ", (char **) allowed);
      g_set_error (error, DS_PROTOCOL_ERROR, DS_PROTOCOL_ERROR_BAD_ARGUMENT,
                   "%s: unknown argument \"%s\" (allowed: %s)", request->cmd,
                   (const char *) l->data, list[0] ? list : "none");
      g_list_free (members);
      return FALSE;
    }
  }
  g_list_free (members);
  return TRUE;
}

static JsonNode *
get_value (const DsRequest *request, const char *key)
{
  return json_object_get_member (request->args, key);
}

gboolean
ds_request_get_uint (const DsRequest *request, const char *key, guint64 min, guint64 max,
                     guint64 def, guint64 *out, GError **error)
{
  JsonNode *n = get_value (request, key);
  if (!n) {
    *out = def;
    return TRUE;
  }
  /* json-glib stores integers as gint64 and non-integral numbers as double; only the former
   * is an unsigned integer argument. */
  if (!JSON_NODE_HOLDS_VALUE (n) || json_node_get_value_type (n) != G_TYPE_INT64) {
    g_set_error (error, DS_PROTOCOL_ERROR, DS_PROTOCOL_ERROR_BAD_ARGUMENT,
                 "%s: \"%s\" must be an integer in %" G_GUINT64_FORMAT "..%" G_GUINT64_FORMAT,
                 request->cmd, key, min, max);
    return FALSE;
  }
  gint64 v = json_node_get_int (n);
  if (v < 0 || (guint64) v < min || (guint64) v > max) {
    g_set_error (error, DS_PROTOCOL_ERROR, DS_PROTOCOL_ERROR_BAD_ARGUMENT,
                 "%s: \"%s\" = %" G_GINT64_FORMAT " is outside %" G_GUINT64_FORMAT "..%" G_GUINT64_FORMAT,
                 request->cmd, key, v, min, max);
    return FALSE;
  }
  *out = (guint64) v;
  return TRUE;
}

gboolean
ds_request_get_double (const DsRequest *request, const char *key, double min, double max,
                       double def, double *out, GError **error)
{
  JsonNode *n = get_value (request, key);
  if (!n) {
    *out = def;
    return TRUE;
  }
  GType t = JSON_NODE_HOLDS_VALUE (n) ? json_node_get_value_type (n) : G_TYPE_INVALID;
  if (t != G_TYPE_INT64 && t != G_TYPE_DOUBLE) {
    g_set_error (error, DS_PROTOCOL_ERROR, DS_PROTOCOL_ERROR_BAD_ARGUMENT,
                 "%s: \"%s\" must be a number in %g..%g", request->cmd, key, min, max);
    return FALSE;
  }
  double v = t == G_TYPE_INT64 ? (double) json_node_get_int (n) : json_node_get_double (n);
  if (!isfinite (v) || v < min || v > max) {
    g_set_error (error, DS_PROTOCOL_ERROR, DS_PROTOCOL_ERROR_BAD_ARGUMENT,
                 "%s: \"%s\" = %g is outside %g..%g", request->cmd, key, v, min, max);
    return FALSE;
  }
  *out = v;
  return TRUE;
}

gboolean
ds_request_get_bool (const DsRequest *request, const char *key, gboolean def, gboolean *out,
                     GError **error)
{
  JsonNode *n = get_value (request, key);
  if (!n) {
    *out = def;
    return TRUE;
  }
  if (!JSON_NODE_HOLDS_VALUE (n) || json_node_get_value_type (n) != G_TYPE_BOOLEAN) {
    g_set_error (error, DS_PROTOCOL_ERROR, DS_PROTOCOL_ERROR_BAD_ARGUMENT,
                 "%s: \"%s\" must be true or false", request->cmd, key);
    return FALSE;
  }
  *out = json_node_get_boolean (n);
  return TRUE;
}

gboolean
ds_request_get_choice (const DsRequest *request, const char *key, const char *const *allowed,
                       const char *def, const char **out, GError **error)
{
  JsonNode *n = get_value (request, key);
  const char *v = def;
  if (n) {
    if (!JSON_NODE_HOLDS_VALUE (n) || json_node_get_value_type (n) != G_TYPE_STRING)
      v = NULL;
    else
      v = json_node_get_string (n);
  }
  for (guint i = 0; v && allowed[i]; i++)
    if (strcmp (allowed[i], v) == 0) {
      *out = allowed[i];
      return TRUE;
    }
  g_autofree char *list = g_strjoinv ("|", (char **) allowed);
  g_set_error (error, DS_PROTOCOL_ERROR, DS_PROTOCOL_ERROR_BAD_ARGUMENT,
               "%s: \"%s\" must be one of %s", request->cmd, key, list);
  return FALSE;
}

static void
add_payloads (JsonBuilder *b, const DsPayloadInfo *payloads, guint n)
{
  json_builder_set_member_name (b, "payloads");
  json_builder_begin_array (b);
  for (guint i = 0; i < n; i++) {
    json_builder_begin_object (b);
    json_builder_set_member_name (b, "name");
    json_builder_add_string_value (b, payloads[i].name);
    json_builder_set_member_name (b, "dtype");
    json_builder_add_string_value (b, payloads[i].dtype);
    json_builder_set_member_name (b, "width");
    json_builder_add_int_value (b, payloads[i].width);
    json_builder_set_member_name (b, "height");
    json_builder_add_int_value (b, payloads[i].height);
    json_builder_set_member_name (b, "bytes");
    json_builder_add_int_value (b, (gint64) payloads[i].bytes);
    json_builder_end_object (b);
  }
  json_builder_end_array (b);
}

static char *
finish_line (JsonBuilder *b, gsize *len)
{
  g_autoptr (JsonNode) root = json_builder_get_root (b);
  /* json_text.h: every string escaped, so the line holds no raw newline and is valid JSON
   * whatever a client put in its id or a camera in its vendor name. */
  gsize n = 0;
  char *text = ds_json_to_text (root, &n);
  char *line = g_realloc (text, n + 2);
  line[n] = '\n';
  line[n + 1] = '\0';
  if (len)
    *len = n + 1;
  return line;
}

static void
add_id (JsonBuilder *b, JsonNode *id)
{
  json_builder_set_member_name (b, "id");
  if (id)
    json_builder_add_value (b, json_node_copy (id));
  else
    json_builder_add_null_value (b);
}

/* "ok": true and the named member: a copy of node, or an empty object so that a reader may
 * always index it. */
static void
add_ok_member (JsonBuilder *b, const char *name, JsonNode *node)
{
  json_builder_set_member_name (b, "ok");
  json_builder_add_boolean_value (b, TRUE);
  json_builder_set_member_name (b, name);
  if (node)
    json_builder_add_value (b, json_node_copy (node));
  else {
    json_builder_begin_object (b);
    json_builder_end_object (b);
  }
}

char *
ds_reply_build_ok (JsonNode *id, JsonNode *result, const DsPayloadInfo *payloads, guint n_payloads,
                   gsize *len)
{
  g_autoptr (JsonBuilder) b = json_builder_new ();
  json_builder_begin_object (b);
  add_id (b, id);
  add_ok_member (b, "result", result);
  add_payloads (b, payloads, n_payloads);
  json_builder_end_object (b);
  return finish_line (b, len);
}

char *
ds_reply_build_error (JsonNode *id, const GError *error, gsize *len)
{
  DsProtocolError code = error && error->domain == DS_PROTOCOL_ERROR ? (DsProtocolError) error->code
                                                                     : DS_PROTOCOL_ERROR_FAILED;
  g_autoptr (JsonBuilder) b = json_builder_new ();
  json_builder_begin_object (b);
  add_id (b, id);
  json_builder_set_member_name (b, "ok");
  json_builder_add_boolean_value (b, FALSE);
  json_builder_set_member_name (b, "error");
  json_builder_begin_object (b);
  json_builder_set_member_name (b, "code");
  json_builder_add_string_value (b, ds_protocol_error_name (code));
  json_builder_set_member_name (b, "message");
  json_builder_add_string_value (b, error ? error->message : "unknown error");
  json_builder_end_object (b);
  add_payloads (b, NULL, 0);
  json_builder_end_object (b);
  return finish_line (b, len);
}

/* skipped < 0: no such member (events other than `result`). */
static char *
event_build (const char *event, guint64 seq, gint64 skipped, JsonNode *body, const DsPayloadInfo *payloads,
             guint n_payloads, gsize *len)
{
  g_autoptr (JsonBuilder) b = json_builder_new ();
  json_builder_begin_object (b);
  json_builder_set_member_name (b, "event");
  json_builder_add_string_value (b, event);
  json_builder_set_member_name (b, "seq");
  json_builder_add_int_value (b, (gint64) seq);
  if (skipped >= 0) {
    json_builder_set_member_name (b, "skipped");
    json_builder_add_int_value (b, skipped);
  }
  add_ok_member (b, "body", body);
  add_payloads (b, payloads, n_payloads);
  json_builder_end_object (b);
  return finish_line (b, len);
}

char *
ds_event_build (const char *event, guint64 seq, JsonNode *body, const DsPayloadInfo *payloads,
                guint n_payloads, gsize *len)
{
  return event_build (event, seq, -1, body, payloads, n_payloads, len);
}

char *
ds_result_event_build (guint64 seq, guint64 skipped, JsonNode *body, const DsPayloadInfo *payloads,
                       guint n_payloads, gsize *len)
{
  return event_build ("result", seq, (gint64) MIN (skipped, (guint64) G_MAXINT64), body, payloads, n_payloads, len);
}

void
ds_reply_free (DsReply *reply)
{
  if (!reply)
    return;
  g_free (reply->event);
  if (reply->id)
    json_node_unref (reply->id);
  if (reply->body)
    json_node_unref (reply->body);
  g_free (reply->error_message);
  for (guint i = 0; i < reply->n_payloads; i++) {
    g_free ((char *) reply->payloads[i].name);
    g_free ((char *) reply->payloads[i].dtype);
  }
  g_free (reply->payloads);
  g_free (reply);
}

static gboolean
bad_reply (GError **error, const char *what)
{
  g_set_error (error, DS_PROTOCOL_ERROR, DS_PROTOCOL_ERROR_BAD_REPLY, "malformed reply: %s", what);
  return FALSE;
}

static gboolean
parse_payloads (JsonObject *obj, DsReply *reply, GError **error)
{
  JsonNode *pn = json_object_get_member (obj, "payloads");
  if (!pn)
    return TRUE;
  if (!JSON_NODE_HOLDS_ARRAY (pn))
    return bad_reply (error, "payloads is not an array");
  JsonArray *arr = json_node_get_array (pn);
  guint n = json_array_get_length (arr);
  reply->payloads = g_new0 (DsPayloadInfo, n);
  for (guint i = 0; i < n; i++) {
    JsonNode *en = json_array_get_element (arr, i);
    if (!JSON_NODE_HOLDS_OBJECT (en))
      return bad_reply (error, "payload entry is not an object");
    JsonObject *e = json_node_get_object (en);
    const char *name = json_object_get_string_member_with_default (e, "name", NULL);
    const char *dtype = json_object_get_string_member_with_default (e, "dtype", NULL);
    gint64 w = json_object_get_int_member_with_default (e, "width", -1);
    gint64 h = json_object_get_int_member_with_default (e, "height", -1);
    gint64 bytes = json_object_get_int_member_with_default (e, "bytes", -1);
    gsize ds = ds_dtype_size (dtype);
    if (!name || ds == 0 || w <= 0 || h <= 0 || w > 65536 || h > 65536 || bytes != w * h * (gint64) ds)
      return bad_reply (error, "payload entry with missing or inconsistent name/dtype/shape/bytes");
    reply->payloads[i].name = g_strdup (name);
    reply->payloads[i].dtype = g_strdup (dtype);
    reply->payloads[i].width = (guint) w;
    reply->payloads[i].height = (guint) h;
    reply->payloads[i].bytes = (guint64) bytes;
    reply->n_payloads = i + 1;
  }
  return TRUE;
}

DsReply *
ds_reply_parse (const char *line, gsize len, GError **error)
{
  g_autoptr (GError) local = NULL;
  g_autoptr (JsonNode) root = parse_object_line (line, len, &local);
  if (!root) {
    g_set_error (error, DS_PROTOCOL_ERROR, DS_PROTOCOL_ERROR_BAD_REPLY, "malformed reply: %s",
                 local->message);
    return NULL;
  }
  JsonObject *obj = json_node_get_object (root);
  g_autoptr (DsReply) reply = g_new0 (DsReply, 1);
  JsonNode *okn = json_object_get_member (obj, "ok");
  if (!okn || !JSON_NODE_HOLDS_VALUE (okn) || json_node_get_value_type (okn) != G_TYPE_BOOLEAN) {
    bad_reply (error, "no boolean \"ok\"");
    return NULL;
  }
  reply->ok = json_node_get_boolean (okn);
  const char *event = json_object_get_string_member_with_default (obj, "event", NULL);
  reply->event = g_strdup (event);
  if (event) {
    reply->seq = (guint64) MAX (0, json_object_get_int_member_with_default (obj, "seq", 0));
    reply->skipped = (guint64) MAX (0, json_object_get_int_member_with_default (obj, "skipped", 0));
  }
  JsonNode *id = json_object_get_member (obj, "id");
  if (id)
    reply->id = json_node_copy (id);
  JsonNode *body = json_object_get_member (obj, event ? "body" : "result");
  if (body)
    reply->body = json_node_copy (body);
  if (!reply->ok) {
    JsonNode *en = json_object_get_member (obj, "error");
    if (!en || !JSON_NODE_HOLDS_OBJECT (en)) {
      bad_reply (error, "ok is false but there is no error object");
      return NULL;
    }
    JsonObject *eo = json_node_get_object (en);
    reply->error_code =
      ds_protocol_error_from_name (json_object_get_string_member_with_default (eo, "code", NULL));
    reply->error_message = g_strdup (json_object_get_string_member_with_default (eo, "message", ""));
  }
  if (!parse_payloads (obj, reply, error))
    return NULL;
  return g_steal_pointer (&reply);
}
