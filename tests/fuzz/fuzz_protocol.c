/* Fuzz target: the request parser (what any client can send) and the reply parser (what
 * descatterctl accepts from the daemon). Neither may crash, leak or accept a payload whose
 * byte count disagrees with its shape, and every reply the daemon would send back (echoing
 * whatever id the request carried) must itself parse as strict JSON. */
#include <stdint.h>

#include "daemon/protocol/protocol.h"

int LLVMFuzzerTestOneInput (const uint8_t *data, size_t size);

int
LLVMFuzzerTestOneInput (const uint8_t *data, size_t size)
{
  JsonNode *id = NULL;
  GError *error = NULL;
  DsRequest *req = ds_request_parse ((const char *) data, size, &id, &error);
  if (req) {
    static const char *const keys[] = { "phases", "averages", NULL };
    guint64 u;
    double d;
    ds_request_check_keys (req, keys, NULL);
    ds_request_get_uint (req, "phases", 2, 64, 8, &u, NULL);
    ds_request_get_double (req, "exposure_us", 1, 1e7, 1000, &d, NULL);
    gsize len;
    g_autofree char *line = ds_reply_build_ok (req->id, NULL, NULL, 0, &len);
    DsReply *echo = ds_reply_parse (line, len - 1, NULL);
    g_assert (echo && echo->id);
    g_assert (req->id ? json_node_equal (echo->id, req->id) : JSON_NODE_HOLDS_NULL (echo->id));
    ds_reply_free (echo);
    ds_request_free (req);
  } else {
    gsize len;
    g_autofree char *line = ds_reply_build_error (id, error, &len);
    g_assert (line[len - 1] == '\n');
    DsReply *echo = ds_reply_parse (line, len - 1, NULL);
    g_assert (echo && !echo->ok);
    ds_reply_free (echo);
  }
  if (id)
    json_node_unref (id);
  g_clear_error (&error);
  DsReply *reply = ds_reply_parse ((const char *) data, size, NULL);
  if (reply) {
    for (guint i = 0; i < reply->n_payloads; i++)
      g_assert (reply->payloads[i].bytes ==
                (guint64) reply->payloads[i].width * reply->payloads[i].height *
                    ds_dtype_size (reply->payloads[i].dtype));
    ds_reply_free (reply);
  }
  return 0;
}
