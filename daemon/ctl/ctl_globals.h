/* What every descatterctl command's --help says of the global options, and the letters they
 * take. Any thread; no state. */
#pragma once
#include <glib.h>

G_BEGIN_DECLS

#define DS_CTL_DEFAULT_ADDRESS "/run/descatterd/descatterd.sock"

/* Short option letters have one meaning across descatterctl (tests/daemon/test_ctl_options.py
 * checks every command's --help): the global ones (-a --address, -V --version, -h --help) are
 * taken nowhere else, and a letter a command uses means what it means everywhere (-n phases,
 * -m averages, -e exposure-us, -g gain-db, -o out, -q quiet, -s scene, -j json, ...). An
 * option whose natural letter is taken by another meaning is long-only. */

/* The global options' lines (address, token, token file) as descatterctl --help prints them:
 * the one text for the program's usage and the end of every command's --help. In a header of
 * its own because `separate` is also a library (ds_ctl_separate) that needs no protocol client. */
#define DS_CTL_GLOBAL_OPTIONS_HELP                                                                        \
  "  -a, --address ADDR   the daemon: a UNIX socket path (default " DS_CTL_DEFAULT_ADDRESS "),\n"           \
  "                       unix:PATH or tcp:HOST:PORT; also $DESCATTER_ADDRESS\n"                           \
  "  --token TOKEN        the daemon's TCP token (also $DESCATTER_TOKEN)\n"                                \
  "  --token-file FILE    read the token from FILE (keeps it out of the process list)\n"

/* Ends a command's --help with the global options (given before the command). */
static inline void
ds_ctl_describe_globals (GOptionContext *ctx)
{
  g_option_context_set_description (ctx, "Global options (before the command: descatterctl [OPTIONS] "
                                          "COMMAND ...):\n" DS_CTL_GLOBAL_OPTIONS_HELP);
}

G_END_DECLS
