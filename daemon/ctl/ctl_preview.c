/* descatterctl preview: free-running frames for aligning the rig (docs/protocol.md, `preview`),
 * shown in the live view and sent to `stream --frames`-style subscribers; on or off. */
#include <string.h>

#include "daemon/ctl/ctl_commands.h"
#include "daemon/ctl/ctl_output.h"

static void
print_preview (JsonObject *body)
{
  printf ("%s; state %s\n", json_object_get_string_member_with_default (body, "message", "done"),
          json_object_get_string_member_with_default (body, "state", "?"));
}

int
ds_ctl_preview (const DsCtlTarget *target, int argc, char **argv)
{
  gboolean json = FALSE;
  g_autofree char *light = NULL, *phase = NULL;
  GOptionEntry entries[] = {
    { "light", 'l', 0, G_OPTION_ARG_STRING, &light,
      "with on: all (every stripe lit, the default), off (illuminator dark) or phase (one phase: --phase)", "LIGHT" },
    { "phase", 'p', 0, G_OPTION_ARG_STRING, &phase, "with --light phase: the phase lit, 0..N-1 of the configured N",
      "K" },
    DS_CTL_JSON_ENTRY (json),
    { NULL },
  };
  g_autoptr (GOptionContext) ctx = g_option_context_new ("on|off - free-running frames for aligning the rig");
  g_option_context_set_summary (ctx, "on: the camera runs free at its own rate with the illuminator all on, off or "
                                     "showing one phase; the frames go to the live view and to socket subscribers "
                                     "that ask for them; no phase set is taken, nothing is recorded. off, stop, "
                                     "cancel, release, or a capture, dark or start end it. Refused (busy) while "
                                     "a capture or continuous acquisition runs.");
  g_option_context_add_main_entries (ctx, entries, NULL);
  ds_ctl_describe_globals (ctx);
  g_autoptr (GError) error = NULL;
  if (!g_option_context_parse (ctx, &argc, &argv, &error)) {
    fprintf (stderr, "descatterctl preview: %s\n", error->message);
    return 2;
  }
  if (argc != 2 || (strcmp (argv[1], "on") != 0 && strcmp (argv[1], "off") != 0)) {
    fprintf (stderr, "descatterctl preview: say on or off (descatterctl preview on [--light all|off|phase "
                     "[--phase K]], descatterctl preview off)\n");
    return 2;
  }
  g_autoptr (JsonObject) args = json_object_new ();
  json_object_set_string_member (args, "state", argv[1]);
  /* Sent as given: the daemon checks them against the configured phases and names what is wrong. */
  if (light)
    json_object_set_string_member (args, "light", light);
  if (phase && !ds_ctl_args_int (args, "preview", "--phase", "phase", phase))
    return 2;
  g_autoptr (DsClient) c = ds_ctl_connect (target, "preview");
  if (!c)
    return 1;
  g_autoptr (DsMessage) m = ds_ctl_call (c, "preview", args, NULL, NULL);
  if (!m)
    return 1;
  ds_ctl_print_reply (m->reply->body, json, print_preview);
  return 0;
}
