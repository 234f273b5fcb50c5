/* Accepting on a GSocketListener without spinning when the process is out of descriptors.
 * GSocketService retries a failed accept at once, and EMFILE leaves the pending connection
 * readable, so it logs and retries in a busy loop; this loop pauses for a while instead and
 * says so at most every 10 s. Main thread (the context current at start); nothing blocks. */
#pragma once
#include <gio/gio.h>

G_BEGIN_DECLS

typedef struct DsAcceptLoop DsAcceptLoop;

/* A new connection (the callee takes a reference if it keeps it). */
typedef void (*DsAcceptFunc) (GSocketConnection *connection, gpointer user_data);

DsAcceptLoop *ds_accept_loop_new (GSocketListener *listener, DsAcceptFunc on_accept, gpointer user_data);
/* Starts accepting (again); does nothing if it is. */
void ds_accept_loop_start (DsAcceptLoop *loop);
/* Stops: no callback after this. */
void ds_accept_loop_stop (DsAcceptLoop *loop);
void ds_accept_loop_free (DsAcceptLoop *loop);
/* Times accepting paused after an error. */
guint64 ds_accept_loop_paused (const DsAcceptLoop *loop);

G_END_DECLS
