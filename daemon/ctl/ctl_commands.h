/* descatterctl subcommands. Each takes the arguments after the global options (argv[0] is the
 * subcommand) and returns the process exit status: 0 success, 1 the operation failed (message
 * on stderr), 2 bad usage. */
#pragma once
#include <glib.h>

#define DS_CTL_DEFAULT_ADDRESS "/run/descatterd/descatterd.sock"

/* The daemon's address for the remote commands (--address, else $DESCATTER_ADDRESS, else the
 * default). */
void ds_ctl_set_address (const char *address);
const char *ds_ctl_address (void);

int ds_ctl_hello (int argc, char **argv);
int ds_ctl_status (int argc, char **argv);
int ds_ctl_capture (int argc, char **argv);
int ds_ctl_stream (int argc, char **argv);
int ds_ctl_start (int argc, char **argv);
int ds_ctl_stop (int argc, char **argv);
int ds_ctl_dark (int argc, char **argv);
int ds_ctl_config (int argc, char **argv);
int ds_ctl_separate (int argc, char **argv);
int ds_ctl_study (int argc, char **argv);
