#include "daemon/ctl/ctl_session.h"

#include <errno.h>
#include <math.h>
#include <string.h>

gboolean
ds_ctl_parse_options (int *argc, char ***argv, const GOptionEntry *entries, const char *summary)
{
  g_autoptr (GOptionContext) ctx = g_option_context_new (NULL);
  g_option_context_set_summary (ctx, summary);
  g_option_context_add_main_entries (ctx, entries, NULL);
  ds_ctl_describe_globals (ctx);
  g_autoptr (GError) error = NULL;
  if (!g_option_context_parse (ctx, argc, argv, &error)) {
    fprintf (stderr, "descatterctl %s: %s\n", (*argv)[0], error->message);
    return FALSE;
  }
  if (*argc > 1) {
    fprintf (stderr, "descatterctl %s: unexpected argument \"%s\"\n", (*argv)[0], (*argv)[1]);
    return FALSE;
  }
  return TRUE;
}

static const char *
unauthorized_hint (DsProtocolError code)
{
  return code == DS_PROTOCOL_ERROR_UNAUTHORIZED
             ? " (a TCP address needs the daemon's token: --token, --token-file or $DESCATTER_TOKEN)"
             : "";
}

DsMessage *
ds_ctl_call (DsClient *client, const char *cmd, JsonObject *args, DsClientEventFunc on_event,
             gpointer user_data)
{
  g_autoptr (GError) error = NULL;
  DsMessage *m = ds_client_call (client, cmd, args, on_event, user_data, &error);
  if (!m) {
    fprintf (stderr, "descatterctl %s: %s\n", cmd, error->message);
    return NULL;
  }
  if (!m->reply->ok) {
    fprintf (stderr, "descatterctl %s: %s: %s%s\n", cmd, ds_protocol_error_name (m->reply->error_code),
             m->reply->error_message, unauthorized_hint (m->reply->error_code));
    ds_message_free (m);
    return NULL;
  }
  return m;
}

DsClient *
ds_ctl_connect (const DsCtlTarget *target, const char *cmd)
{
  g_autoptr (GError) error = NULL;
  g_autoptr (DsClient) c = ds_client_connect (target->address, &error);
  if (!c) {
    fprintf (stderr, "descatterctl %s: %s (is descatterd running? --address or $DESCATTER_ADDRESS)\n",
             cmd, error->message);
    return NULL;
  }
  if (target->token) {
    g_autoptr (JsonObject) args = json_object_new ();
    json_object_set_string_member (args, "token", target->token);
    json_object_set_string_member (args, "client", "descatterctl");
    g_autoptr (DsMessage) m = ds_client_call (c, "hello", args, NULL, NULL, &error);
    if (!m) {
      fprintf (stderr, "descatterctl %s: hello: %s\n", cmd, error->message);
      return NULL;
    }
    if (!m->reply->ok) {
      fprintf (stderr, "descatterctl %s: the daemon refused the token: %s\n", cmd, m->reply->error_message);
      return NULL;
    }
  }
  return g_steal_pointer (&c);
}

gboolean
ds_ctl_parse_int (const char *cmd, const char *option, const char *text, gint64 *out)
{
  char *end = NULL;
  errno = 0;
  gint64 v = g_ascii_strtoll (text, &end, 10);
  if (!*text || !end || *end || errno) {
    fprintf (stderr, "descatterctl %s: --%s \"%s\" is not an integer\n", cmd, option, text);
    return FALSE;
  }
  *out = v;
  return TRUE;
}

gboolean
ds_ctl_parse_double (const char *cmd, const char *option, const char *text, double *out)
{
  char *end = NULL;
  errno = 0;
  double v = g_ascii_strtod (text, &end);
  if (!*text || !end || *end || errno || !isfinite (v)) {
    fprintf (stderr, "descatterctl %s: --%s \"%s\" is not a finite number\n", cmd, option, text);
    return FALSE;
  }
  *out = v;
  return TRUE;
}

gboolean
ds_ctl_args_int (JsonObject *args, const char *cmd, const char *option, const char *key, const char *text)
{
  gint64 v;
  if (!text)
    return TRUE;
  if (!ds_ctl_parse_int (cmd, option, text, &v))
    return FALSE;
  json_object_set_int_member (args, key, v);
  return TRUE;
}

gboolean
ds_ctl_args_double (JsonObject *args, const char *cmd, const char *option, const char *key, const char *text)
{
  double v;
  if (!text)
    return TRUE;
  if (!ds_ctl_parse_double (cmd, option, text, &v))
    return FALSE;
  json_object_set_double_member (args, key, v);
  return TRUE;
}

void
ds_ctl_print_json (JsonNode *node)
{
  if (!node) {
    printf ("{}\n");
    return;
  }
  g_autofree char *text = json_to_string (node, TRUE);
  printf ("%s\n", text);
}

void
ds_ctl_print_reply (JsonNode *body, gboolean json, void (*human) (JsonObject *body))
{
  if (json || !body || !JSON_NODE_HOLDS_OBJECT (body))
    ds_ctl_print_json (body);
  else
    human (json_node_get_object (body));
}
