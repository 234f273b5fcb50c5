/* The input side of one HTTP connection, between the socket and libsoup: it counts what libsoup
 * reads and stops reads at a limit the connection's owner sets (http_listener.c), so that a
 * request's headers are refused at their size limit before libsoup buffers more of them. It
 * closes the socket when libsoup closes the stream (libsoup sees a GSimpleIOStream, whose
 * closing alone would leave the descriptor open). Main thread; never blocks on its own (the
 * blocking read is the socket's, used by nobody here). */
#pragma once
#include <gio/gio.h>

G_BEGIN_DECLS

#define DS_TYPE_HTTP_INPUT (ds_http_input_get_type ())
G_DECLARE_FINAL_TYPE (DsHttpInput, ds_http_input, DS, HTTP_INPUT, GInputStream)

/* Called once, when the stream is closed (by libsoup, or at its finalization). */
typedef void (*DsHttpInputClosedFunc) (gpointer user_data);

/* Reads from `conn`'s input; closes `conn` when closed itself. */
DsHttpInput *ds_http_input_new (GSocketConnection *conn, DsHttpInputClosedFunc closed, gpointer user_data);
/* Forget the closed callback (its owner is going away first). */
void ds_http_input_forget (DsHttpInput *in);

/* Bytes read so far, and when the last read returned data (monotonic µs; 0: never). */
guint64 ds_http_input_bytes (const DsHttpInput *in);
gint64 ds_http_input_last_read_us (const DsHttpInput *in);
/* Reads stop with G_IO_ERROR_MESSAGE_TOO_LARGE once `limit` bytes in all were read
 * (G_MAXUINT64: no limit); `what` names the limit in the error ("request headers over 16384
 * bytes"). */
void ds_http_input_set_limit (DsHttpInput *in, guint64 limit, const char *what);

G_END_DECLS
