/* What every remote command of descatterctl shares: where the daemon is (address and TCP
 * token, from the global options or the environment), option parsing with "unset" told apart
 * from every value a user can type, and calls that print a failed reply's error. Main thread
 * only; nothing here keeps state between calls. */
#pragma once
#include <stdio.h>

#include "daemon/ctl/ctl_globals.h"
#include "daemon/protocol/client.h"

G_BEGIN_DECLS


/* The daemon a remote command talks to. */
typedef struct {
  const char *address; /* never NULL: --address, $DESCATTER_ADDRESS or the default */
  const char *token;   /* NULL: none; --token, --token-file or $DESCATTER_TOKEN */
} DsCtlTarget;

/* --json for the commands whose reply is printed for people by default. */
#define DS_CTL_JSON_ENTRY(var)                                                                            \
  { "json", 'j', 0, G_OPTION_ARG_NONE, &(var), "Print the daemon's reply as JSON (for scripts)", NULL }

/* Parses a subcommand's options; refuses positional arguments. FALSE: the message is printed. */
gboolean ds_ctl_parse_options (int *argc, char ***argv, const GOptionEntry *entries, const char *summary);

/* Connects and, when a token is set, authenticates with hello. NULL: the reason and a hint
 * are printed, prefixed with "descatterctl CMD". */
DsClient *ds_ctl_connect (const DsCtlTarget *target, const char *cmd);

/* Calls cmd; a transport failure or a reply with ok=false is printed (with a hint for
 * `unauthorized`) and gives NULL. */
DsMessage *ds_ctl_call (DsClient *client, const char *cmd, JsonObject *args,
                        DsClientEventFunc on_event, gpointer user_data);

/* Numeric options are taken as text (G_OPTION_ARG_STRING) so that "not given" (NULL) is told
 * apart from every value a user can type: a given value is sent as it is, and the daemon
 * refuses what is out of range, naming the range (docs/protocol.md); nothing falls back to a
 * default silently. These set args[key] from --OPTION's text when it was given; FALSE (message
 * printed) when the text is not an integer, or not a finite number (JSON cannot carry nan/inf). */
gboolean ds_ctl_args_int (JsonObject *args, const char *cmd, const char *option, const char *key,
                          const char *text);
gboolean ds_ctl_args_double (JsonObject *args, const char *cmd, const char *option, const char *key,
                             const char *text);
/* The same parse, for options a command uses itself. */
gboolean ds_ctl_parse_int (const char *cmd, const char *option, const char *text, gint64 *out);
gboolean ds_ctl_parse_double (const char *cmd, const char *option, const char *text, double *out);

void ds_ctl_print_json (JsonNode *node);
/* A reply's body: as JSON when json is set (or the body is not an object), else through human. */
void ds_ctl_print_reply (JsonNode *body, gboolean json, void (*human) (JsonObject *body));

G_END_DECLS
