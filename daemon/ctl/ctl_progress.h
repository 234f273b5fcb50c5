/* A progress report on stderr for long commands (study, capture): done/total, percent and the
 * time left, estimated from the work done so far. On a terminal it is one line rewritten with
 * \r; otherwise (a log, CI) plain lines, at most one every `interval` seconds and a last one,
 * so that a log never fills with carriage returns. Main thread only. */
#pragma once
#include <glib.h>

G_BEGIN_DECLS

typedef struct DsCtlProgress DsCtlProgress;

/* label: "study"; unit: what is counted ("sets"). total_weight: the work in arbitrary units
 * (e.g. frames), used for the time left; total_items: what is shown. quiet: report nothing. */
DsCtlProgress *ds_ctl_progress_new (const char *label, const char *unit, guint total_items,
                                    double total_weight, gboolean quiet);
/* One more item of `weight` is done; extra: appended to the line (may be NULL). */
void ds_ctl_progress_advance (DsCtlProgress *p, double weight, const char *extra);
/* Ends the line (a terminal) and frees. */
void ds_ctl_progress_free (DsCtlProgress *p);
G_DEFINE_AUTOPTR_CLEANUP_FUNC (DsCtlProgress, ds_ctl_progress_free)

/* "1 h 02 min", "3 min 20 s", "12 s": for the time left. Newly allocated. */
char *ds_ctl_format_duration (double seconds);

G_END_DECLS
