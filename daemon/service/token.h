/* A listener's token: comparing one (TCP's hello, HTTP's ?token= or Bearer) without leaking
 * where it differs, and the HTTP token descatterd makes for itself when none is configured.
 * Reading configured token files is preflight's (preflight.c). Any thread. */
#pragma once
#include <glib.h>

G_BEGIN_DECLS

/* Constant time in the length of the expected token: no early exit on the first mismatch. */
gboolean ds_token_equal (const char *expected, const char *given);

/* A new random token (256 bits from the kernel's generator, as 64 hex digits). */
char *ds_token_generate (GError **error);

/* Writes `token` to `path` (a temporary name, fsynced, renamed) readable by whom may use the
 * socket at `socket_path`: its group when the socket is group-accessible (mode 0640), else its
 * owner only (0600). So HTTP lets in exactly who the socket lets in. */
gboolean ds_token_write_for_socket (const char *path, const char *token, const char *socket_path, GError **error);

G_END_DECLS
