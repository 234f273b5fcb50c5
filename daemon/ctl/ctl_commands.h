/* descatterctl subcommands. Each takes the arguments after the global options (argv[0] is the
 * subcommand) and returns the process exit status: 0 success, 1 the operation failed (message
 * on stderr), 2 bad usage. Remote commands also get the daemon to talk to. */
#pragma once
#include <glib.h>

#include "daemon/ctl/ctl_separate.h"
#include "daemon/ctl/ctl_session.h"

int ds_ctl_hello (const DsCtlTarget *target, int argc, char **argv);
int ds_ctl_status (const DsCtlTarget *target, int argc, char **argv);
int ds_ctl_live_url (const DsCtlTarget *target, int argc, char **argv);
int ds_ctl_capture (const DsCtlTarget *target, int argc, char **argv);
int ds_ctl_stream (const DsCtlTarget *target, int argc, char **argv);
int ds_ctl_start (const DsCtlTarget *target, int argc, char **argv);
int ds_ctl_stop (const DsCtlTarget *target, int argc, char **argv);
int ds_ctl_cancel (const DsCtlTarget *target, int argc, char **argv);
int ds_ctl_preview (const DsCtlTarget *target, int argc, char **argv);
int ds_ctl_release (const DsCtlTarget *target, int argc, char **argv);
int ds_ctl_acquire (const DsCtlTarget *target, int argc, char **argv);
int ds_ctl_dark (const DsCtlTarget *target, int argc, char **argv);
int ds_ctl_config (const DsCtlTarget *target, int argc, char **argv);
int ds_ctl_set (const DsCtlTarget *target, int argc, char **argv);
/* A folder given: offline; none: the daemon calibrates on the rig. */
int ds_ctl_calibrate (const DsCtlTarget *target, int argc, char **argv);

/* Offline: no daemon (and ds_ctl_separate, ctl_separate.h). */
int ds_ctl_study (int argc, char **argv);
int ds_ctl_validate (int argc, char **argv);
int ds_ctl_generate_scenes (int argc, char **argv);
