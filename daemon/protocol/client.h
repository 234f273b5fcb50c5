/* A blocking client of descatterd's protocol (docs/protocol.md), for descatterctl and tests.
 * One thread at a time per client. */
#pragma once
#include <gio/gio.h>

#include "daemon/protocol/protocol.h"

G_BEGIN_DECLS

typedef struct DsClient DsClient;

/* address: a UNIX socket path, "unix:PATH" or "tcp:HOST:PORT". */
DsClient *ds_client_connect (const char *address, GError **error);
void ds_client_free (DsClient *client);
G_DEFINE_AUTOPTR_CLEANUP_FUNC (DsClient, ds_client_free)

/* A message (reply or event) with its payloads, in the order announced. */
typedef struct {
  DsReply *reply;
  GBytes **payloads;  /* reply->n_payloads entries */
} DsMessage;

void ds_message_free (DsMessage *message);
G_DEFINE_AUTOPTR_CLEANUP_FUNC (DsMessage, ds_message_free)

/* Reads the next message (reply or event). timeout_ms 0 waits forever. */
DsMessage *ds_client_read (DsClient *client, guint timeout_ms, GError **error);

/* Events that arrive while waiting for a reply (progress, subscribed results). */
typedef void (*DsClientEventFunc) (const DsMessage *event, gpointer user_data);

/* Sends {"id": n, "cmd": cmd, "args": args} and waits for the reply with that id. args may be
 * NULL; it is not consumed. A reply with ok=false is returned as is (not as an error). */
DsMessage *ds_client_call (DsClient *client, const char *cmd, JsonObject *args,
                           DsClientEventFunc on_event, gpointer user_data, GError **error);

G_END_DECLS
