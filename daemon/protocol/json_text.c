#include "daemon/protocol/json_text.h"

#include <errno.h>
#include <math.h>
#include <string.h>

#include "daemon/protocol/protocol.h"

typedef struct {
  const char *start, *p, *end;
  guint depth, max_depth;
  GError **error;
} Parser;

static JsonNode *parse_value (Parser *ps);

static gsize
offset (const Parser *ps)
{
  return (gsize) (ps->p - ps->start);
}

static JsonNode *
fail (Parser *ps, const char *what)
{
  /* Only the first failure is reported: the innermost one, where the text went wrong. */
  if (ps->error && !*ps->error)
    g_set_error (ps->error, DS_PROTOCOL_ERROR, DS_PROTOCOL_ERROR_BAD_JSON, "not valid JSON at byte %zu: %s",
                 offset (ps), what);
  return NULL;
}

static void
skip_ws (Parser *ps)
{
  while (ps->p < ps->end && (*ps->p == ' ' || *ps->p == '\t' || *ps->p == '\n' || *ps->p == '\r'))
    ps->p++;
}

static gboolean
literal (Parser *ps, const char *word)
{
  gsize n = strlen (word);
  if ((gsize) (ps->end - ps->p) < n || memcmp (ps->p, word, n) != 0)
    return FALSE;
  ps->p += n;
  return TRUE;
}

static int
hex4 (const char *s)
{
  int v = 0;
  for (int i = 0; i < 4; i++) {
    int d = g_ascii_xdigit_value (s[i]);
    if (d < 0)
      return -1;
    v = v * 16 + d;
  }
  return v;
}

/* A string's contents after its opening quote; ps->p ends after the closing quote. */
static char *
parse_string (Parser *ps)
{
  GString *s = g_string_new (NULL);
  ps->p++; /* the opening quote */
  while (ps->p < ps->end) {
    guchar c = (guchar) *ps->p;
    if (c == '"') {
      ps->p++;
      return g_string_free (s, FALSE);
    }
    if (c < 0x20) {
      g_autofree char *what = g_strdup_printf ("control character U+%04X inside a string (it must be escaped)", c);
      fail (ps, what);
      break;
    }
    if (c != '\\') {
      g_string_append_c (s, (char) c);
      ps->p++;
      continue;
    }
    if (ps->end - ps->p < 2) {
      fail (ps, "unterminated escape");
      break;
    }
    char e = ps->p[1];
    const char *simple = strchr ("\"\\/bfnrt", e);
    if (e && simple) {
      static const char decoded[] = "\"\\/\b\f\n\r\t";
      g_string_append_c (s, decoded[simple - "\"\\/bfnrt"]);
      ps->p += 2;
      continue;
    }
    if (e != 'u') {
      fail (ps, "unknown escape (allowed: \\\" \\\\ \\/ \\b \\f \\n \\r \\t \\uXXXX)");
      break;
    }
    int cp = ps->end - ps->p >= 6 ? hex4 (ps->p + 2) : -1;
    if (cp < 0) {
      fail (ps, "\\u must be followed by four hexadecimal digits");
      break;
    }
    if (cp == 0) {
      fail (ps, "\\u0000 (NUL) inside a string is refused");
      break;
    }
    if (cp >= 0xDC00 && cp <= 0xDFFF) {
      fail (ps, "lone low surrogate (\\uDC00..\\uDFFF without a high surrogate before it)");
      break;
    }
    if (cp >= 0xD800 && cp <= 0xDBFF) {
      int lo = ps->end - ps->p >= 12 && ps->p[6] == '\\' && ps->p[7] == 'u' ? hex4 (ps->p + 8) : -1;
      if (lo < 0xDC00 || lo > 0xDFFF) {
        fail (ps, "lone high surrogate (\\uD800..\\uDBFF not followed by a low surrogate)");
        break;
      }
      cp = 0x10000 + ((cp - 0xD800) << 10) + (lo - 0xDC00);
      ps->p += 6;
    }
    g_string_append_unichar (s, (gunichar) cp);
    ps->p += 6;
  }
  if (ps->p >= ps->end)
    fail (ps, "unterminated string");
  g_string_free (s, TRUE);
  return NULL;
}

static JsonNode *
parse_number (Parser *ps)
{
  const char *q = ps->p;
  gboolean integral = TRUE;
  if (q < ps->end && *q == '-')
    q++;
  if (q >= ps->end || !g_ascii_isdigit (*q))
    return fail (ps, "expected a value (a number needs a digit)");
  if (*q == '0' && q + 1 < ps->end && g_ascii_isdigit (q[1]))
    return fail (ps, "numbers do not start with 0");
  while (q < ps->end && g_ascii_isdigit (*q))
    q++;
  if (q < ps->end && *q == '.') {
    integral = FALSE;
    q++;
    if (q >= ps->end || !g_ascii_isdigit (*q))
      return fail (ps, "a fraction needs a digit after the point");
    while (q < ps->end && g_ascii_isdigit (*q))
      q++;
  }
  if (q < ps->end && (*q == 'e' || *q == 'E')) {
    integral = FALSE;
    q++;
    if (q < ps->end && (*q == '+' || *q == '-'))
      q++;
    if (q >= ps->end || !g_ascii_isdigit (*q))
      return fail (ps, "an exponent needs a digit");
    while (q < ps->end && g_ascii_isdigit (*q))
      q++;
  }
  /* The line is not NUL-terminated where the number ends: convert a copy. */
  g_autofree char *text = g_strndup (ps->p, (gsize) (q - ps->p));
  JsonNode *node = json_node_new (JSON_NODE_VALUE);
  errno = 0;
  if (integral) {
    gint64 v = g_ascii_strtoll (text, NULL, 10);
    if (errno == ERANGE) {
      json_node_unref (node);
      return fail (ps, "integer outside the 64-bit range");
    }
    json_node_set_int (node, v);
  } else {
    double v = g_ascii_strtod (text, NULL);
    if (!isfinite (v)) {
      json_node_unref (node);
      return fail (ps, "number too large for a double");
    }
    json_node_set_double (node, v);
  }
  ps->p = q;
  return node;
}

static gboolean
enter (Parser *ps)
{
  if (++ps->depth <= ps->max_depth)
    return TRUE;
  if (ps->error && !*ps->error)
    g_set_error (ps->error, DS_PROTOCOL_ERROR, DS_PROTOCOL_ERROR_TOO_DEEP,
                 "JSON nested deeper than %u levels (at byte %zu)", ps->max_depth, offset (ps));
  return FALSE;
}

static JsonNode *
parse_array (Parser *ps)
{
  if (!enter (ps))
    return NULL;
  ps->p++;
  g_autoptr (JsonArray) arr = json_array_new ();
  skip_ws (ps);
  if (ps->p < ps->end && *ps->p == ']') {
    ps->p++;
  } else {
    for (;;) {
      JsonNode *el = parse_value (ps);
      if (!el)
        return NULL;
      json_array_add_element (arr, el);
      skip_ws (ps);
      if (ps->p < ps->end && *ps->p == ',') {
        ps->p++;
        continue;
      }
      if (ps->p < ps->end && *ps->p == ']') {
        ps->p++;
        break;
      }
      return fail (ps, "expected ',' or ']' in an array");
    }
  }
  ps->depth--;
  JsonNode *node = json_node_new (JSON_NODE_ARRAY);
  json_node_set_array (node, arr);
  return node;
}

static JsonNode *
parse_object (Parser *ps)
{
  if (!enter (ps))
    return NULL;
  ps->p++;
  g_autoptr (JsonObject) obj = json_object_new ();
  skip_ws (ps);
  if (ps->p < ps->end && *ps->p == '}') {
    ps->p++;
  } else {
    for (;;) {
      skip_ws (ps);
      if (ps->p >= ps->end || *ps->p != '"')
        return fail (ps, "expected a member name in double quotes");
      const char *name_at = ps->p;
      g_autofree char *name = parse_string (ps);
      if (!name)
        return NULL;
      if (json_object_has_member (obj, name)) {
        ps->p = name_at;
        g_autofree char *what = g_strdup_printf ("duplicate member \"%s\"", name);
        return fail (ps, what);
      }
      skip_ws (ps);
      if (ps->p >= ps->end || *ps->p != ':')
        return fail (ps, "expected ':' after a member name");
      ps->p++;
      JsonNode *value = parse_value (ps);
      if (!value)
        return NULL;
      json_object_set_member (obj, name, value);
      skip_ws (ps);
      if (ps->p < ps->end && *ps->p == ',') {
        ps->p++;
        continue;
      }
      if (ps->p < ps->end && *ps->p == '}') {
        ps->p++;
        break;
      }
      return fail (ps, "expected ',' or '}' in an object");
    }
  }
  ps->depth--;
  JsonNode *node = json_node_new (JSON_NODE_OBJECT);
  json_node_set_object (node, obj);
  return node;
}

static JsonNode *
parse_value (Parser *ps)
{
  skip_ws (ps);
  if (ps->p >= ps->end)
    return fail (ps, "expected a value, found the end of the line");
  switch (*ps->p) {
  case '{':
    return parse_object (ps);
  case '[':
    return parse_array (ps);
  case '"': {
    char *s = parse_string (ps);
    if (!s)
      return NULL;
    JsonNode *node = json_node_new (JSON_NODE_VALUE);
    json_node_set_string (node, s);
    g_free (s);
    return node;
  }
  case 't':
  case 'f':
    if (literal (ps, "true") || literal (ps, "false")) {
      JsonNode *node = json_node_new (JSON_NODE_VALUE);
      json_node_set_boolean (node, ps->p[-4] == 't');
      return node;
    }
    return fail (ps, "expected a value");
  case 'n':
    if (literal (ps, "null"))
      return json_node_new (JSON_NODE_NULL);
    return fail (ps, "expected a value");
  case '\'':
    return fail (ps, "strings are in double quotes, not single quotes");
  default:
    return parse_number (ps);
  }
}

JsonNode *
ds_json_parse_strict (const char *text, gsize len, guint max_depth, GError **error)
{
  Parser ps = { .start = text, .p = text, .end = text + len, .max_depth = max_depth, .error = error };
  JsonNode *node = parse_value (&ps);
  if (!node)
    return NULL;
  skip_ws (&ps);
  if (ps.p != ps.end) {
    json_node_unref (node);
    return fail (&ps, "more text after the JSON value (one request per line)");
  }
  return node;
}

/* ---- writing ---- */

static void
write_string (GString *out, const char *s)
{
  g_autofree char *valid = g_utf8_make_valid (s, -1);
  g_string_append_c (out, '"');
  for (const guchar *p = (const guchar *) valid; *p; p++) {
    switch (*p) {
    case '"': g_string_append (out, "\\\""); break;
    case '\\': g_string_append (out, "\\\\"); break;
    case '\b': g_string_append (out, "\\b"); break;
    case '\f': g_string_append (out, "\\f"); break;
    case '\n': g_string_append (out, "\\n"); break;
    case '\r': g_string_append (out, "\\r"); break;
    case '\t': g_string_append (out, "\\t"); break;
    default:
      if (*p < 0x20 || *p == 0x7f)
        g_string_append_printf (out, "\\u%04x", *p);
      else
        g_string_append_c (out, (char) *p);
    }
  }
  g_string_append_c (out, '"');
}

static void
write_double (GString *out, double v)
{
  if (!isfinite (v)) {
    g_string_append (out, "null");
    return;
  }
  /* The shortest of %.15g/%.17g that reads back as the same double. */
  char buf[G_ASCII_DTOSTR_BUF_SIZE];
  g_ascii_formatd (buf, sizeof buf, "%.15g", v);
  if (g_ascii_strtod (buf, NULL) != v)
    g_ascii_formatd (buf, sizeof buf, "%.17g", v);
  g_string_append (out, buf);
  if (!strpbrk (buf, ".eE"))
    g_string_append (out, ".0");
}

void
ds_json_write (GString *out, JsonNode *node)
{
  if (!node) {
    g_string_append (out, "null");
    return;
  }
  switch (json_node_get_node_type (node)) {
  case JSON_NODE_OBJECT: {
    JsonObject *obj = json_node_get_object (node);
    GList *members = json_object_get_members (obj);
    g_string_append_c (out, '{');
    for (GList *l = members; l; l = l->next) {
      if (l != members)
        g_string_append_c (out, ',');
      write_string (out, l->data);
      g_string_append_c (out, ':');
      ds_json_write (out, json_object_get_member (obj, l->data));
    }
    g_string_append_c (out, '}');
    g_list_free (members);
    return;
  }
  case JSON_NODE_ARRAY: {
    JsonArray *arr = json_node_get_array (node);
    g_string_append_c (out, '[');
    for (guint i = 0; i < json_array_get_length (arr); i++) {
      if (i)
        g_string_append_c (out, ',');
      ds_json_write (out, json_array_get_element (arr, i));
    }
    g_string_append_c (out, ']');
    return;
  }
  case JSON_NODE_NULL:
    g_string_append (out, "null");
    return;
  case JSON_NODE_VALUE:
    break;
  }
  GType t = json_node_get_value_type (node);
  if (t == G_TYPE_INT64)
    g_string_append_printf (out, "%" G_GINT64_FORMAT, json_node_get_int (node));
  else if (t == G_TYPE_DOUBLE)
    write_double (out, json_node_get_double (node));
  else if (t == G_TYPE_BOOLEAN)
    g_string_append (out, json_node_get_boolean (node) ? "true" : "false");
  else if (t == G_TYPE_STRING)
    write_string (out, json_node_get_string (node) ? json_node_get_string (node) : "");
  else
    g_string_append (out, "null");
}

char *
ds_json_to_text (JsonNode *node, gsize *len)
{
  GString *out = g_string_new (NULL);
  ds_json_write (out, node);
  if (len)
    *len = out->len;
  return g_string_free (out, FALSE);
}
