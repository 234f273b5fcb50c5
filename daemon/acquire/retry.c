/* The one retry rule of the frames the sequencer acquires: a phase set's (pipeline.c),
 * a dark frame's (dark.c) and the automatic operating point's pilot frames
 * (auto_point.c). A frame lost in transport, a device that timed out or a frame that failed
 * verification is re-acquired, counted in `retries`, up to [acquisition] phase-retries times per
 * phase (or per dark frame, per pilot frame); an error the policy calls fatal
 * (ds_seq_fatal_device_error: invalid, unsupported, disconnected) ends it at once. */
#include <stdarg.h>

#include "daemon/acquire/acquisition.h"

gboolean
ds_seq_retry_or_fail (DsAcquisition *acq, guint *retries_left, DsFrameCounters *c, GError **why, GError **error,
                      const char *what_format, ...)
{
  gboolean fatal = ds_seq_fatal_device_error (acq, *why);
  if (fatal || *retries_left == 0) {
    va_list ap;
    va_start (ap, what_format);
    g_autofree char *what = g_strdup_vprintf (what_format, ap);
    va_end (ap);
    g_propagate_prefixed_error (error, g_steal_pointer (why), "%s: %s", what, fatal ? "" : "retries exhausted: ");
    return FALSE;
  }
  (*retries_left)--;
  c->retries++;
  g_clear_error (why);
  return TRUE;
}
