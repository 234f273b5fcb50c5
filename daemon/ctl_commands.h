/* descatterctl subcommands. Each is a file of its own (daemon/ctl_<name>.c) with one entry point
 * taking the arguments after the subcommand name (argv[0] is the subcommand) and returning the
 * process exit status: 0 success, 1 the operation failed (message on stderr), 2 bad usage. */
#pragma once

int ds_ctl_separate (int argc, char **argv);
