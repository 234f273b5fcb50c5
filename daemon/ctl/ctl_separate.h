/* `descatterctl separate`: a phase folder separated offline, no daemon (ds_ctl_separate, its own
 * library). Declared apart from the remote commands (ctl_commands.h) so that it and its tests
 * need nothing of the protocol client. Same contract as every subcommand: argv[0] is
 * "separate"; returns 0 on success, 1 when the operation failed (message on stderr), 2 on bad
 * usage. */
#pragma once

int ds_ctl_separate (int argc, char **argv);
