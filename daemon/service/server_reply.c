/* Replies to requests, and the error replies' count by code (status, /metrics). */
#include "daemon/service/server_private.h"
#include "daemon/service/json_build.h"

/* Replies are never dropped: a client that asked waits for its answer. */
static void
send_line (DsConnection *conn, char *line, gsize len, GBytes *const *payloads, guint n)
{
  g_autoptr (GBytes) b = g_bytes_new_take (line, len);
  ds_connection_send (conn, b, payloads, n, FALSE);
}

void
ds_server_reply_ok (DsServer *server, DsConnection *conn, JsonNode *id, JsonNode *result,
                    const DsPayloadInfo *infos, GBytes *const *payloads, guint n_payloads)
{
  (void) server;
  gsize len = 0;
  char *line = ds_reply_build_ok (id, result, infos, n_payloads, &len);
  send_line (conn, line, len, payloads, n_payloads);
}

/* The client's fault: what it sent cannot be taken whatever the rig's state. */
static gboolean
is_bad_request (DsProtocolError code)
{
  switch (code) {
  case DS_PROTOCOL_ERROR_LINE_TOO_LONG:
  case DS_PROTOCOL_ERROR_BAD_JSON:
  case DS_PROTOCOL_ERROR_TOO_DEEP:
  case DS_PROTOCOL_ERROR_BAD_REQUEST:
  case DS_PROTOCOL_ERROR_UNKNOWN_COMMAND:
  case DS_PROTOCOL_ERROR_BAD_ARGUMENT:
  case DS_PROTOCOL_ERROR_UNAUTHORIZED:
    return TRUE;
  default:
    return FALSE;
  }
}

void
ds_server_reply_error (DsServer *server, DsConnection *conn, JsonNode *id, const GError *error)
{
  if (server) {
    /* The same code the reply carries (ds_reply_build_error). */
    DsProtocolError code = error && error->domain == DS_PROTOCOL_ERROR ? (DsProtocolError) error->code
                                                                       : DS_PROTOCOL_ERROR_FAILED;
    if ((guint) code >= G_N_ELEMENTS (server->stats.error_replies))
      code = DS_PROTOCOL_ERROR_FAILED;
    server->stats.error_replies[code]++;
    if (is_bad_request (code))
      server->stats.bad_requests++;
  }
  gsize len = 0;
  char *line = ds_reply_build_error (id, error, &len);
  send_line (conn, line, len, NULL, 0);
}
