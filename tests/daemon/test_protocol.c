/* The protocol's parsing and building, against literal wire text written in the test. */
#include "daemon/protocol/protocol.h"

#include <string.h>

static DsRequest *
parse (const char *line, JsonNode **id, GError **error)
{
  return ds_request_parse (line, strlen (line), id, error);
}

static void
test_request_minimal (void)
{
  g_autoptr (GError) error = NULL;
  g_autoptr (DsRequest) req = parse ("{\"id\":7,\"cmd\":\"hello\"}", NULL, &error);
  g_assert_no_error (error);
  g_assert_cmpstr (req->cmd, ==, "hello");
  g_assert_cmpint (json_node_get_int (req->id), ==, 7);
  g_assert_cmpuint (json_object_get_size (req->args), ==, 0);
}

static void
test_request_errors (void)
{
  struct { const char *line; DsProtocolError code; gboolean has_id; } cases[] = {
    { "not json", DS_PROTOCOL_ERROR_BAD_JSON, FALSE },
    { "[1,2]", DS_PROTOCOL_ERROR_BAD_REQUEST, FALSE },
    { "{\"id\":1}", DS_PROTOCOL_ERROR_BAD_REQUEST, TRUE },
    { "{\"id\":\"a\",\"cmd\":3}", DS_PROTOCOL_ERROR_BAD_REQUEST, TRUE },
    { "{\"id\":2,\"cmd\":\"x\",\"args\":[]}", DS_PROTOCOL_ERROR_BAD_REQUEST, TRUE },
    { "{\"id\":2,\"cmd\":\"x\",\"extra\":1}", DS_PROTOCOL_ERROR_BAD_REQUEST, TRUE },
    { "{\"id\":{\"a\":1},\"cmd\":\"x\"}", DS_PROTOCOL_ERROR_BAD_REQUEST, FALSE },
    { "{\"cmd\":\"x\",\"args\":{\"a\":[[[[[[[[1]]]]]]]]}}", DS_PROTOCOL_ERROR_TOO_DEEP, FALSE },
  };
  for (guint i = 0; i < G_N_ELEMENTS (cases); i++) {
    g_autoptr (GError) error = NULL;
    JsonNode *id = NULL;
    DsRequest *req = parse (cases[i].line, &id, &error);
    g_assert_null (req);
    g_assert_error (error, DS_PROTOCOL_ERROR, (gint) cases[i].code);
    g_assert_true ((id != NULL) == cases[i].has_id);
    if (id)
      json_node_unref (id);
  }
}

static void
test_depth_counts_only_outside_strings (void)
{
  /* Brackets inside strings (with escaped quotes) must not count towards the depth limit. */
  g_autoptr (GError) error = NULL;
  g_autoptr (DsRequest) req =
    parse ("{\"cmd\":\"x\",\"args\":{\"s\":\"[[[[[[[[[[\\\"[[[[[[[[[[\"}}", NULL, &error);
  g_assert_no_error (error);
  /* Exactly the limit is accepted, one more is refused. */
  GString *ok = g_string_new ("{\"cmd\":\"x\",\"args\":{\"a\":");
  for (int i = 0; i < DS_PROTOCOL_MAX_DEPTH - 2; i++)
    g_string_append_c (ok, '[');
  for (int i = 0; i < DS_PROTOCOL_MAX_DEPTH - 2; i++)
    g_string_append_c (ok, ']');
  g_string_append (ok, "}}");
  g_autoptr (DsRequest) r1 = parse (ok->str, NULL, &error);
  g_assert_no_error (error);
  g_string_insert_c (ok, strlen ("{\"cmd\":\"x\",\"args\":{\"a\":"), '[');
  g_string_insert_c (ok, ok->len - 2, ']');
  g_autoptr (DsRequest) r2 = parse (ok->str, NULL, &error);
  g_assert_error (error, DS_PROTOCOL_ERROR, DS_PROTOCOL_ERROR_TOO_DEEP);
  g_string_free (ok, TRUE);
}

static void
test_line_limit_and_bytes (void)
{
  g_autoptr (GError) error = NULL;
  gsize n = DS_PROTOCOL_MAX_LINE + 1;
  g_autofree char *big = g_malloc (n);
  memset (big, ' ', n);
  g_assert_null (ds_request_parse (big, n, NULL, &error));
  g_assert_error (error, DS_PROTOCOL_ERROR, DS_PROTOCOL_ERROR_LINE_TOO_LONG);
  g_clear_error (&error);
  const char bad_utf8[] = "{\"cmd\":\"\xff\"}";
  g_assert_null (ds_request_parse (bad_utf8, sizeof bad_utf8 - 1, NULL, &error));
  g_assert_error (error, DS_PROTOCOL_ERROR, DS_PROTOCOL_ERROR_BAD_JSON);
  g_clear_error (&error);
  const char nul[] = "{\"cmd\":\"a\"}\0x";
  g_assert_null (ds_request_parse (nul, sizeof nul - 1, NULL, &error));
  g_assert_error (error, DS_PROTOCOL_ERROR, DS_PROTOCOL_ERROR_BAD_JSON);
}

static void
test_typed_arguments (void)
{
  g_autoptr (GError) error = NULL;
  g_autoptr (DsRequest) req = parse ("{\"cmd\":\"capture\",\"args\":{\"phases\":8,\"exposure_us\":1500.5,"
                                     "\"estimator\":\"sine\",\"keep\":true,\"neg\":-1,\"frac\":2.5}}",
                                     NULL, &error);
  g_assert_no_error (error);
  guint64 u = 0;
  g_assert_true (ds_request_get_uint (req, "phases", 2, 64, 4, &u, &error));
  g_assert_cmpuint (u, ==, 8);
  g_assert_true (ds_request_get_uint (req, "averages", 1, 16, 3, &u, &error));
  g_assert_cmpuint (u, ==, 3);
  g_assert_false (ds_request_get_uint (req, "phases", 2, 4, 4, &u, &error));
  g_assert_error (error, DS_PROTOCOL_ERROR, DS_PROTOCOL_ERROR_BAD_ARGUMENT);
  g_assert_nonnull (strstr (error->message, "phases"));
  g_clear_error (&error);
  g_assert_false (ds_request_get_uint (req, "neg", 0, 10, 0, &u, &error));
  g_clear_error (&error);
  g_assert_false (ds_request_get_uint (req, "frac", 0, 10, 0, &u, &error));
  g_clear_error (&error);
  double d = 0;
  g_assert_true (ds_request_get_double (req, "exposure_us", 1, 1e6, 1000, &d, &error));
  g_assert_cmpfloat (d, ==, 1500.5);
  g_assert_true (ds_request_get_double (req, "phases", 0, 100, 0, &d, &error));
  g_assert_cmpfloat (d, ==, 8.0);
  g_assert_false (ds_request_get_double (req, "estimator", 0, 1, 0, &d, &error));
  g_clear_error (&error);
  const char *const est[] = { "maxmin", "sine", "robust", NULL };
  const char *choice = NULL;
  g_assert_true (ds_request_get_choice (req, "estimator", est, "maxmin", &choice, &error));
  g_assert_true (choice == est[1]);
  gboolean keep = FALSE;
  g_assert_true (ds_request_get_bool (req, "keep", FALSE, &keep, &error));
  g_assert_true (keep);
  const char *const allowed[] = { "phases", "exposure_us", "estimator", "keep", "neg", NULL };
  g_assert_false (ds_request_check_keys (req, allowed, &error));
  g_assert_nonnull (strstr (error->message, "frac"));
}

/* Issue 10: what a hostile client sent and json-glib's lenient parser let through. Each line
 * is refused with the code docs/protocol.md gives, never read as something else. */
static void
test_request_strict_json (void)
{
  struct { const char *line; DsProtocolError code; } cases[] = {
    /* a second request on the same line was silently dropped */
    { "{\"cmd\":\"status\"}{\"cmd\":\"stop\"}", DS_PROTOCOL_ERROR_BAD_JSON },
    { "{\"cmd\":\"status\"} {\"cmd\":\"stop\"}", DS_PROTOCOL_ERROR_BAD_JSON },
    { "{\"cmd\":\"status\"} x", DS_PROTOCOL_ERROR_BAD_JSON },
    /* single-quoted pseudo-JSON was accepted */
    { "{'cmd':'status'}", DS_PROTOCOL_ERROR_BAD_JSON },
    { "{\"cmd\":'status'}", DS_PROTOCOL_ERROR_BAD_JSON },
    /* 1e999 came back as inf.0 */
    { "{\"id\":1e999,\"cmd\":\"status\"}", DS_PROTOCOL_ERROR_BAD_JSON },
    { "{\"id\":-1e400,\"cmd\":\"status\"}", DS_PROTOCOL_ERROR_BAD_JSON },
    /* json-glib read 99999999999999999999 as -1 */
    { "{\"id\":99999999999999999999,\"cmd\":\"status\"}", DS_PROTOCOL_ERROR_BAD_JSON },
    /* lone surrogates */
    { "{\"id\":\"\\ud800\",\"cmd\":\"status\"}", DS_PROTOCOL_ERROR_BAD_JSON },
    { "{\"id\":\"\\udc00x\",\"cmd\":\"status\"}", DS_PROTOCOL_ERROR_BAD_JSON },
    { "{\"id\":\"\\ud800\\u0041\",\"cmd\":\"status\"}", DS_PROTOCOL_ERROR_BAD_JSON },
    /* raw control characters inside strings */
    { "{\"id\":\"a\tb\",\"cmd\":\"status\"}", DS_PROTOCOL_ERROR_BAD_JSON },
    { "{\"id\":\"a\x01" "b\",\"cmd\":\"status\"}", DS_PROTOCOL_ERROR_BAD_JSON },
    /* an embedded NUL ran the prefix ("maxmin") */
    { "{\"cmd\":\"capture\",\"args\":{\"estimator\":\"maxmin\\u0000junk\"}}", DS_PROTOCOL_ERROR_BAD_JSON },
    { "{\"cmd\":\"status\\u0000x\"}", DS_PROTOCOL_ERROR_BAD_JSON },
    /* ambiguous or lenient forms */
    { "{\"cmd\":\"status\",\"cmd\":\"stop\"}", DS_PROTOCOL_ERROR_BAD_JSON },
    { "{\"cmd\":\"capture\",\"args\":{\"phases\":8,\"phases\":4}}", DS_PROTOCOL_ERROR_BAD_JSON },
    { "/* c */{\"cmd\":\"status\"}", DS_PROTOCOL_ERROR_BAD_JSON },
    { "{\"cmd\":\"capture\",\"args\":{\"phases\":0x10}}", DS_PROTOCOL_ERROR_BAD_JSON },
    { "{\"cmd\":\"capture\",\"args\":{\"phases\":010}}", DS_PROTOCOL_ERROR_BAD_JSON },
    { "{\"cmd\":\"capture\",\"args\":{\"gain_db\":.5}}", DS_PROTOCOL_ERROR_BAD_JSON },
    { "{\"cmd\":\"capture\",\"args\":{\"gain_db\":+1}}", DS_PROTOCOL_ERROR_BAD_JSON },
    { "{\"cmd\":\"capture\",\"args\":{\"gain_db\":NaN}}", DS_PROTOCOL_ERROR_BAD_JSON },
    { "{\"cmd\":\"capture\",\"args\":{\"gain_db\":1.}}", DS_PROTOCOL_ERROR_BAD_JSON },
    { "{\"cmd\":\"capture\",\"args\":{\"gain_db\":1e}}", DS_PROTOCOL_ERROR_BAD_JSON },
    { "{\"cmd\":\"capture\",}", DS_PROTOCOL_ERROR_BAD_JSON },
    { "{\"cmd\":\"capture\",\"args\":{\"outputs\":[\"mask\",]}}", DS_PROTOCOL_ERROR_BAD_JSON },
    { "{cmd:\"status\"}", DS_PROTOCOL_ERROR_BAD_JSON },
    { "{\"cmd\":\"st\\x41tus\"}", DS_PROTOCOL_ERROR_BAD_JSON },
    { "{\"cmd\":\"status\\u12\"}", DS_PROTOCOL_ERROR_BAD_JSON },
    { "{\"cmd\":\"status", DS_PROTOCOL_ERROR_BAD_JSON },
    { "{\"cmd\":tru}", DS_PROTOCOL_ERROR_BAD_JSON },
    { "", DS_PROTOCOL_ERROR_BAD_JSON },
    { "   ", DS_PROTOCOL_ERROR_BAD_JSON },
    /* valid JSON, not a request */
    { "\"status\"", DS_PROTOCOL_ERROR_BAD_REQUEST },
    { "{\"id\":true,\"cmd\":\"status\"}", DS_PROTOCOL_ERROR_BAD_REQUEST },
    { "{\"id\":[1],\"cmd\":\"status\"}", DS_PROTOCOL_ERROR_BAD_REQUEST },
  };
  for (guint i = 0; i < G_N_ELEMENTS (cases); i++) {
    g_autoptr (GError) error = NULL;
    JsonNode *id = NULL;
    DsRequest *req = parse (cases[i].line, &id, &error);
    if (req || !g_error_matches (error, DS_PROTOCOL_ERROR, (gint) cases[i].code))
      g_error ("line %u <%s>: expected %s, got %s", i, cases[i].line,
               ds_protocol_error_name (cases[i].code),
               req ? "accepted" : ds_protocol_error_name ((DsProtocolError) error->code));
    if (id)
      json_node_unref (id);
  }
  /* What strict JSON allows still passes: escapes, surrogate pairs, exponents, whitespace. */
  g_autoptr (GError) error = NULL;
  g_autoptr (DsRequest) ok = parse (" {\"id\" : \"\\ud83d\\ude00\\t\\u00e9\\/\" ,\r\n\"cmd\":\"st\\u0061tus\","
                                    "\"args\":{\"a\":-0.5e+2,\"b\":[],\"c\":{},\"d\":null,\"e\":false}} ",
                                    NULL, &error);
  g_assert_no_error (error);
  g_assert_cmpstr (ok->cmd, ==, "status");
  g_assert_cmpstr (json_node_get_string (ok->id), ==, "\xf0\x9f\x98\x80\t\xc3\xa9/");
  g_assert_cmpfloat (json_object_get_double_member (ok->args, "a"), ==, -50.0);
  g_assert_false (json_object_get_boolean_member (ok->args, "e"));
}

/* Every reply is valid JSON whatever the request's id holds: the reply is read back with the
 * same strict parser and must give the id back unchanged. */
static void
test_reply_always_valid_json (void)
{
  const char *const ids[] = {
    "\"\\u0001\\u001f\\u007f\\b\\f\\n\\r\\t\"", /* control characters, escaped in the request */
    "\"\\\"\\\\ quote and backslash\"",
    "\"\\u2028\\u2029 line separators\"",
    "\"\\ud83d\\ude00 astral\"",
    "-9223372036854775808",
    "9223372036854775807",
    "1.7976931348623157e308",
    "5e-324",
    "0.1",
    "-0.0",
    "3.0",
  };
  for (guint i = 0; i < G_N_ELEMENTS (ids); i++) {
    g_autofree char *line = g_strdup_printf ("{\"id\":%s,\"cmd\":\"status\"}", ids[i]);
    g_autoptr (GError) error = NULL;
    g_autoptr (DsRequest) req = parse (line, NULL, &error);
    g_assert_no_error (error);
    gsize len = 0;
    g_autofree char *ok = ds_reply_build_ok (req->id, NULL, NULL, 0, &len);
    g_autoptr (GError) e = g_error_new (DS_PROTOCOL_ERROR, DS_PROTOCOL_ERROR_FAILED, "x\x01y");
    gsize elen = 0;
    g_autofree char *err = ds_reply_build_error (req->id, e, &elen);
    const char *lines[] = { ok, err };
    gsize lens[] = { len, elen };
    for (guint k = 0; k < 2; k++) {
      g_assert_null (memchr (lines[k], '\n', lens[k] - 1));
      for (gsize j = 0; j + 1 < lens[k]; j++)
        g_assert_cmpuint ((guchar) lines[k][j], >=, 0x20);
      g_autoptr (DsReply) r = ds_reply_parse (lines[k], lens[k] - 1, &error);
      g_assert_no_error (error);
      g_assert_true (json_node_equal (r->id, req->id));
    }
  }
  /* Invalid UTF-8 in a message (a camera's vendor string) becomes U+FFFD, not invalid JSON. */
  g_autoptr (GError) e = g_error_new (DS_PROTOCOL_ERROR, DS_PROTOCOL_ERROR_DEVICE, "camera \xff\xfe");
  gsize len = 0;
  g_autofree char *line = ds_reply_build_error (NULL, e, &len);
  g_autoptr (GError) error = NULL;
  g_autoptr (DsReply) r = ds_reply_parse (line, len - 1, &error);
  g_assert_no_error (error);
  g_assert_cmpstr (r->error_message, ==, "camera \xef\xbf\xbd\xef\xbf\xbd");
}

static void
test_reply_round_trip (void)
{
  g_autoptr (JsonNode) id = json_node_new (JSON_NODE_VALUE);
  json_node_set_string (id, "req-1");
  g_autoptr (JsonBuilder) b = json_builder_new ();
  json_builder_begin_object (b);
  json_builder_set_member_name (b, "phases");
  json_builder_add_int_value (b, 8);
  json_builder_end_object (b);
  g_autoptr (JsonNode) result = json_builder_get_root (b);
  DsPayloadInfo p[] = { { "transmissive", "f32", 3, 2, 24 }, { "mask", "u8", 3, 2, 6 } };
  gsize len = 0;
  g_autofree char *line = ds_reply_build_ok (id, result, p, 2, &len);
  g_assert_cmpuint (len, ==, strlen (line));
  g_assert_true (line[len - 1] == '\n');
  g_assert_null (memchr (line, '\n', len - 1));
  g_autoptr (GError) error = NULL;
  g_autoptr (DsReply) r = ds_reply_parse (line, len - 1, &error);
  g_assert_no_error (error);
  g_assert_true (r->ok);
  g_assert_cmpstr (json_node_get_string (r->id), ==, "req-1");
  g_assert_cmpint (json_object_get_int_member (json_node_get_object (r->body), "phases"), ==, 8);
  g_assert_cmpuint (r->n_payloads, ==, 2);
  g_assert_cmpstr (r->payloads[1].name, ==, "mask");
  g_assert_cmpuint (r->payloads[0].bytes, ==, 24);
}

static void
test_error_reply_and_event (void)
{
  g_autoptr (GError) e = g_error_new (DS_PROTOCOL_ERROR, DS_PROTOCOL_ERROR_BUSY, "a set \"is\"\nrunning");
  gsize len = 0;
  g_autofree char *line = ds_reply_build_error (NULL, e, &len);
  g_assert_null (memchr (line, '\n', len - 1));
  g_autoptr (GError) error = NULL;
  g_autoptr (DsReply) r = ds_reply_parse (line, len - 1, &error);
  g_assert_no_error (error);
  g_assert_false (r->ok);
  g_assert_cmpint (r->error_code, ==, DS_PROTOCOL_ERROR_BUSY);
  g_assert_cmpstr (r->error_message, ==, "a set \"is\"\nrunning");
  g_assert_cmpstr (ds_protocol_error_name (DS_PROTOCOL_ERROR_BUSY), ==, "busy");

  g_autofree char *ev = ds_event_build ("result", 42, NULL, NULL, 0, &len);
  g_autoptr (DsReply) re = ds_reply_parse (ev, len - 1, &error);
  g_assert_no_error (error);
  g_assert_cmpstr (re->event, ==, "result");
  g_assert_cmpuint (re->seq, ==, 42);
  g_assert_cmpuint (re->skipped, ==, 0);

  /* A result event as docs/protocol.md, "Events", writes it: skipped right after seq. */
  g_autofree char *rev = ds_result_event_build (43, 7, NULL, NULL, 0, &len);
  g_assert_cmpstr (rev, ==, "{\"event\":\"result\",\"seq\":43,\"skipped\":7,\"ok\":true,\"body\":{},\"payloads\":[]}\n");
  g_autoptr (DsReply) rr = ds_reply_parse (rev, len - 1, &error);
  g_assert_no_error (error);
  g_assert_cmpuint (rr->seq, ==, 43);
  g_assert_cmpuint (rr->skipped, ==, 7);
}

static void
test_reply_payload_consistency (void)
{
  /* A byte count that does not match the shape would desynchronize the stream: refused. */
  const char *bad = "{\"ok\":true,\"payloads\":[{\"name\":\"t\",\"dtype\":\"f32\",\"width\":3,\"height\":2,\"bytes\":23}]}";
  g_autoptr (GError) error = NULL;
  g_assert_null (ds_reply_parse (bad, strlen (bad), &error));
  g_assert_error (error, DS_PROTOCOL_ERROR, DS_PROTOCOL_ERROR_BAD_REPLY);
  g_clear_error (&error);
  const char *dtype = "{\"ok\":true,\"payloads\":[{\"name\":\"t\",\"dtype\":\"f64\",\"width\":1,\"height\":1,\"bytes\":8}]}";
  g_assert_null (ds_reply_parse (dtype, strlen (dtype), &error));
  g_assert_error (error, DS_PROTOCOL_ERROR, DS_PROTOCOL_ERROR_BAD_REPLY);
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  g_test_add_func ("/protocol/request/minimal", test_request_minimal);
  g_test_add_func ("/protocol/request/errors", test_request_errors);
  g_test_add_func ("/protocol/request/depth", test_depth_counts_only_outside_strings);
  g_test_add_func ("/protocol/request/limits", test_line_limit_and_bytes);
  g_test_add_func ("/protocol/request/typed-arguments", test_typed_arguments);
  g_test_add_func ("/protocol/request/strict-json", test_request_strict_json);
  g_test_add_func ("/protocol/reply/always-valid-json", test_reply_always_valid_json);
  g_test_add_func ("/protocol/reply/round-trip", test_reply_round_trip);
  g_test_add_func ("/protocol/reply/error-and-event", test_error_reply_and_event);
  g_test_add_func ("/protocol/reply/payload-consistency", test_reply_payload_consistency);
  return g_test_run ();
}
