/* descatterctl: the command-line client of descatterd, and offline tools (separate, study). */
#include <locale.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "build_info.h"
#include "daemon/ctl/ctl_commands.h"

static const struct {
  const char *name;
  int (*remote) (const DsCtlTarget *target, int argc, char **argv);
  int (*offline) (int argc, char **argv);
  const char *help;
} commands[] = {
  { "hello", ds_ctl_hello, NULL, "protocol version and daemon identity" },
  { "status", ds_ctl_status, NULL, "state, devices, counters, timings, clients" },
  { "live-url", ds_ctl_live_url, NULL, "the live view's address with its token, for a browser" },
  { "capture", ds_ctl_capture, NULL, "acquire one phase set; write TIFF + PNG previews" },
  { "stream", ds_ctl_stream, NULL, "subscribe and write/print results as they come" },
  { "start", ds_ctl_start, NULL, "start continuous acquisition" },
  { "stop", ds_ctl_stop, NULL, "stop continuous acquisition" },
  { "cancel", ds_ctl_cancel, NULL, "stop the running capture, calibrate or stream now, and what waits" },
  { "preview", ds_ctl_preview, NULL, "free-running frames for aligning (on/off), no sets" },
  { "release", ds_ctl_release, NULL, "close the devices so that arv-viewer can take the camera" },
  { "acquire", ds_ctl_acquire, NULL, "open the devices again after release" },
  { "dark", ds_ctl_dark, NULL, "calibrate the dark frame (illuminator off)" },
  { "config", ds_ctl_config, NULL, "print the daemon's effective configuration" },
  { "set", ds_ctl_set, NULL, "change the open camera's exposure, gain or region, live" },
  { "separate", NULL, ds_ctl_separate, "separate a folder of phase images offline (no daemon)" },
  { "calibrate", ds_ctl_calibrate, NULL, "measure the stripe pattern on a reference: a phase folder, or the rig" },
  { "study", NULL, ds_ctl_study, "accuracy against acquisition time on simulated scenes (no daemon)" },
  { "validate", NULL, ds_ctl_validate, "the automatic operating point against the simulator's truth (no daemon)" },
  { "generate-scenes", NULL, ds_ctl_generate_scenes, "random scene files for validation (no daemon)" },
};

static void
usage (FILE *f)
{
  fprintf (f, "usage: descatterctl [OPTIONS] COMMAND [COMMAND OPTIONS]\n\ncommands:\n");
  for (size_t i = 0; i < G_N_ELEMENTS (commands); i++)
    fprintf (f, "  %-16s %s\n", commands[i].name, commands[i].help);
  fprintf (f, "\noptions:\n%s"
              "  -V, --version        print the version and exit\n"
              "  -h, --help           print this help and exit\n"
              "\n`descatterctl COMMAND --help` lists a command's options.\n",
           DS_CTL_GLOBAL_OPTIONS_HELP);
}

/* "--name VALUE" or "--name=VALUE" at argv[*i]; advances *i past what it used. */
static gboolean
take_value (int argc, char **argv, int *i, const char *lng, const char *shrt, const char **value)
{
  const char *a = argv[*i];
  size_t n = strlen (lng);
  if (strncmp (a, lng, n) == 0 && a[n] == '=') {
    *value = a + n + 1;
    (*i)++;
    return TRUE;
  }
  if ((strcmp (a, lng) == 0 || (shrt && strcmp (a, shrt) == 0))) {
    if (*i + 1 >= argc) {
      fprintf (stderr, "descatterctl: %s needs a value\n", lng);
      exit (2);
    }
    *value = argv[*i + 1];
    *i += 2;
    return TRUE;
  }
  return FALSE;
}

static char *
read_token_file (const char *path)
{
  g_autofree char *text = NULL;
  g_autoptr (GError) error = NULL;
  if (!g_file_get_contents (path, &text, NULL, &error)) {
    fprintf (stderr, "descatterctl: --token-file: %s\n", error->message);
    return NULL;
  }
  g_strstrip (text);
  if (!*text) {
    fprintf (stderr, "descatterctl: --token-file %s is empty\n", path);
    return NULL;
  }
  return g_steal_pointer (&text);
}

int
main (int argc, char **argv)
{
  setlocale (LC_ALL, "");
  const char *address = NULL, *token = NULL, *token_file = NULL;
  int i = 1;
  while (i < argc && argv[i][0] == '-') {
    if (take_value (argc, argv, &i, "--address", "-a", &address) ||
        take_value (argc, argv, &i, "--token", NULL, &token) ||
        take_value (argc, argv, &i, "--token-file", NULL, &token_file))
      continue;
    if (strcmp (argv[i], "--help") == 0 || strcmp (argv[i], "-h") == 0) {
      usage (stdout);
      return 0;
    }
    if (strcmp (argv[i], "--version") == 0 || strcmp (argv[i], "-V") == 0) {
      printf ("descatterctl %s (%s)\n", DS_VERSION, DS_GIT_DESCRIBE);
      return 0;
    }
    fprintf (stderr, "descatterctl: unknown option %s\n", argv[i]);
    usage (stderr);
    return 2;
  }
  if (i >= argc) {
    usage (stderr);
    return 2;
  }
  if (token && token_file) {
    fprintf (stderr, "descatterctl: --token and --token-file exclude each other\n");
    return 2;
  }
  g_autofree char *file_token = token_file ? read_token_file (token_file) : NULL;
  if (token_file && !file_token)
    return 2;
  const char *env_address = g_getenv ("DESCATTER_ADDRESS");
  const char *env_token = g_getenv ("DESCATTER_TOKEN");
  DsCtlTarget target = {
    .address = address ? address : env_address && *env_address ? env_address : DS_CTL_DEFAULT_ADDRESS,
    .token = token ? token : file_token ? file_token : env_token && *env_token ? env_token : NULL,
  };
  for (size_t c = 0; c < G_N_ELEMENTS (commands); c++)
    if (strcmp (argv[i], commands[c].name) == 0)
      return commands[c].remote ? commands[c].remote (&target, argc - i, argv + i)
                                : commands[c].offline (argc - i, argv + i);
  fprintf (stderr, "descatterctl: unknown command \"%s\"\n", argv[i]);
  usage (stderr);
  return 2;
}
