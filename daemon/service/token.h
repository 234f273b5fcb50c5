/* Comparing a listener's token (TCP's hello, HTTP's ?token= or Bearer) without leaking where it
 * differs. Reading the token files is preflight's (preflight.c). Any thread. */
#pragma once
#include <glib.h>

G_BEGIN_DECLS

/* Constant time in the length of the expected token: no early exit on the first mismatch. */
gboolean ds_token_equal (const char *expected, const char *given);

G_END_DECLS
