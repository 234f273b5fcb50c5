/* descatterctl live-url: the live view's address with its token, for a browser. The token
 * descatterd made for itself is in a file beside the socket that only those who may use the
 * socket can read, so the address reaches exactly them. */
#include <string.h>

#include "daemon/ctl/ctl_commands.h"
#include "daemon/ctl/ctl_session.h"
#include "daemon/protocol/protocol.h"

int
ds_ctl_live_url (const DsCtlTarget *target, int argc, char **argv)
{
  GOptionEntry entries[] = { { NULL } };
  if (!ds_ctl_parse_options (&argc, &argv, entries,
                             "Prints the live view's address with its token (open it in a browser)."))
    return 2;
  g_autoptr (DsClient) c = ds_ctl_connect (target, "live-url");
  if (!c)
    return 1;
  g_autoptr (DsMessage) m = ds_ctl_call (c, "status", NULL, NULL, NULL);
  if (!m)
    return 1;
  JsonObject *st = m->reply->body && JSON_NODE_HOLDS_OBJECT (m->reply->body) ? json_node_get_object (m->reply->body)
                                                                              : NULL;
  JsonNode *http_node = st ? json_object_get_member (st, "http") : NULL;
  JsonObject *http = http_node && JSON_NODE_HOLDS_OBJECT (http_node) ? json_node_get_object (http_node) : NULL;
  const char *url = http ? json_object_get_string_member_with_default (http, "url", NULL) : NULL;
  if (!url) {
    fprintf (stderr, "descatterctl live-url: the live view is off (set [http] listen)\n");
    return 1;
  }
  if (strchr (target->address, ':') && target->address[0] != '/') {
    fprintf (stderr, "descatterctl live-url: %s is a TCP address; the token file is beside the daemon's UNIX socket\n",
             target->address);
    return 1;
  }
  g_autofree char *path = g_strconcat (target->address, DS_HTTP_TOKEN_SUFFIX, NULL);
  g_autofree char *token = NULL;
  g_autoptr (GError) error = NULL;
  if (!g_file_get_contents (path, &token, NULL, &error)) {
    fprintf (stderr, "descatterctl live-url: %s (with [http] token-file, add ?token= and that file's token to %s)\n",
             error->message, url);
    return 1;
  }
  g_strstrip (token);
  g_autofree char *escaped = g_uri_escape_string (token, NULL, FALSE);
  printf ("%s?token=%s\n", url, escaped);
  return 0;
}
