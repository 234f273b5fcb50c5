/* Ctrl-C during a request that makes the daemon acquire (capture, calibrate): the daemon is asked
 * to stop too, instead of acquiring on for a client that is gone. The first SIGINT (or SIGTERM)
 * sends `cancel` on a second connection (the first one waits for its reply, and the protocol
 * answers one request at a time per connection); the request is then answered `cancelled` and
 * the command exits 130. A second signal exits 130 at once. Main thread; one guarded request at
 * a time per process. */
#pragma once
#include <glib.h>

#include "daemon/ctl/ctl_session.h"

G_BEGIN_DECLS

/* From now on the signals are taken by a watcher thread (blocked in every thread). cmd names
 * the command in messages. */
void ds_ctl_interrupt_begin (const DsCtlTarget *target, const char *cmd);
/* After the guarded call returned: TRUE when a signal came (the cancel was sent and answered,
 * or failed with its message printed): the caller exits 130 (128 + SIGINT) without writing
 * anything. From now on a signal exits 130 at once. */
gboolean ds_ctl_interrupt_end (void);

#define DS_CTL_EXIT_INTERRUPTED 130

G_END_DECLS
