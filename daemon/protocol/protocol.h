/* The wire protocol of descatterd (docs/protocol.md is the reference): one line of JSON per
 * message, bounded in size and nesting, followed by the binary payloads its `payloads` array
 * announces. This file parses and builds lines; it does no I/O, so the server, the client and
 * the fuzzer share it. Every function is pure: any thread, never blocks. */
#pragma once
#include <glib.h>
#include <json-glib/json-glib.h>

G_BEGIN_DECLS

#define DS_PROTOCOL_VERSION 1
#define DS_PROTOCOL_MAX_LINE (64 * 1024) /* bytes, newline excluded */
/* The live view's token, when descatterd made it, is in the file named by the socket's path with
 * this appended (readable by whom may use the socket; descatterctl live-url). */
#define DS_HTTP_TOKEN_SUFFIX ".http-token"
#define DS_PROTOCOL_MAX_DEPTH 8          /* nesting of objects and arrays */

#define DS_PROTOCOL_ERROR (ds_protocol_error_quark ())
GQuark ds_protocol_error_quark (void);

/* Stable: the wire carries the names (ds_protocol_error_name), clients match on them. */
typedef enum {
  DS_PROTOCOL_ERROR_LINE_TOO_LONG = 1,
  DS_PROTOCOL_ERROR_BAD_JSON = 2,
  DS_PROTOCOL_ERROR_TOO_DEEP = 3,
  DS_PROTOCOL_ERROR_BAD_REQUEST = 4,
  DS_PROTOCOL_ERROR_UNKNOWN_COMMAND = 5,
  DS_PROTOCOL_ERROR_BAD_ARGUMENT = 6,
  DS_PROTOCOL_ERROR_BUSY = 7,
  DS_PROTOCOL_ERROR_DEVICE = 8,
  DS_PROTOCOL_ERROR_UNAUTHORIZED = 9,
  DS_PROTOCOL_ERROR_LIMIT = 10,
  DS_PROTOCOL_ERROR_FAILED = 11,
  DS_PROTOCOL_ERROR_CANCELLED = 12,
  DS_PROTOCOL_ERROR_BAD_REPLY = 13, /* client side: the daemon's answer does not parse */
} DsProtocolError;

const char *ds_protocol_error_name (DsProtocolError code);
/* Reverse of ds_protocol_error_name; unknown names map to DS_PROTOCOL_ERROR_FAILED. */
DsProtocolError ds_protocol_error_from_name (const char *name);

/* A request as the server sees it. `id` is whatever JSON scalar the client sent (or NULL)
 * and is echoed verbatim; `args` is never NULL. */
typedef struct {
  JsonNode *id;
  char *cmd;
  JsonObject *args;
} DsRequest;

void ds_request_free (DsRequest *request);
G_DEFINE_AUTOPTR_CLEANUP_FUNC (DsRequest, ds_request_free)

/* Parses one line (without its newline). On failure returns NULL and, when the line was
 * JSON enough to carry one, sets *id_out to the request's id so the error reply can echo it. */
DsRequest *ds_request_parse (const char *line, gsize len, JsonNode **id_out, GError **error);

/* Fails with BAD_ARGUMENT naming the first key of args not in the NULL-terminated list. */
gboolean ds_request_check_keys (const DsRequest *request, const char *const *allowed, GError **error);

/* Typed, bounded getters: absent key -> default; wrong type or out of range -> BAD_ARGUMENT
 * naming the key, the value and the range. */
gboolean ds_request_get_uint (const DsRequest *request, const char *key, guint64 min, guint64 max,
                              guint64 def, guint64 *out, GError **error);
gboolean ds_request_get_double (const DsRequest *request, const char *key, double min, double max,
                                double def, double *out, GError **error);
gboolean ds_request_get_bool (const DsRequest *request, const char *key, gboolean def,
                              gboolean *out, GError **error);
/* out points into `allowed` (static strings), never into the request. */
gboolean ds_request_get_choice (const DsRequest *request, const char *key, const char *const *allowed,
                                const char *def, const char **out, GError **error);

typedef struct {
  const char *name;  /* "transmissive", "scattered", "mask", ... */
  const char *dtype; /* "f32", "u16", "u8" */
  guint width, height;
  guint64 bytes;     /* exactly width * height * sizeof dtype: rows are packed on the wire */
} DsPayloadInfo;

/* Builds a reply line ending in '\n'. `result` may be NULL (an empty object is sent); it is
 * not consumed. */
char *ds_reply_build_ok (JsonNode *id, JsonNode *result, const DsPayloadInfo *payloads,
                         guint n_payloads, gsize *len);
char *ds_reply_build_error (JsonNode *id, const GError *error, gsize *len);
/* An unsolicited message on a subscribed connection. */
char *ds_event_build (const char *event, guint64 seq, JsonNode *body, const DsPayloadInfo *payloads,
                      guint n_payloads, gsize *len);
/* A `result` event: `skipped` follows `seq`, the results published since the previous result
 * this connection was sent that it was not sent (docs/protocol.md, "Events"). */
char *ds_result_event_build (guint64 seq, guint64 skipped, JsonNode *body, const DsPayloadInfo *payloads,
                             guint n_payloads, gsize *len);

/* A reply or event as the client sees it. */
typedef struct {
  gboolean ok;
  char *event;            /* NULL for replies */
  JsonNode *id;           /* replies */
  guint64 seq;            /* events */
  guint64 skipped;        /* `result` events: results not sent to this client just before it */
  JsonNode *body;         /* "result" of a reply or "body" of an event; NULL if absent */
  DsProtocolError error_code; /* when !ok */
  char *error_message;
  DsPayloadInfo *payloads; /* names/dtypes owned by the struct */
  guint n_payloads;
} DsReply;

void ds_reply_free (DsReply *reply);
G_DEFINE_AUTOPTR_CLEANUP_FUNC (DsReply, ds_reply_free)

/* Parses a reply or event line; checks each payload's byte count against its shape so that
 * a client never reads a stream out of sync. */
DsReply *ds_reply_parse (const char *line, gsize len, GError **error);

gsize ds_dtype_size (const char *dtype); /* 0 for an unknown dtype */

G_END_DECLS
