/* descatterctl: the command-line client of descatterd, and offline tools (separate). */
#include <locale.h>
#include <stdio.h>
#include <string.h>

#include "daemon/ctl/ctl_commands.h"

static const struct {
  const char *name;
  int (*run) (int argc, char **argv);
  const char *help;
} commands[] = {
  { "hello", ds_ctl_hello, "protocol version and daemon identity" },
  { "status", ds_ctl_status, "devices, counters, timings, clients" },
  { "capture", ds_ctl_capture, "acquire one phase set; write TIFF + PNG previews" },
  { "stream", ds_ctl_stream, "subscribe and write/print results as they come" },
  { "start", ds_ctl_start, "start continuous acquisition" },
  { "stop", ds_ctl_stop, "stop continuous acquisition" },
  { "dark", ds_ctl_dark, "calibrate the dark frame (illuminator off)" },
  { "config", ds_ctl_config, "print the daemon's effective configuration" },
  { "separate", ds_ctl_separate, "separate a folder of phase images offline (no daemon)" },
  { "study", ds_ctl_study, "accuracy against acquisition time on simulated scenes (no daemon)" },
};

static void
usage (FILE *f)
{
  fprintf (f, "usage: descatterctl [--address ADDR] COMMAND [OPTIONS]\n\ncommands:\n");
  for (size_t i = 0; i < sizeof commands / sizeof commands[0]; i++)
    fprintf (f, "  %-10s %s\n", commands[i].name, commands[i].help);
  fprintf (f, "\nADDR: a UNIX socket path (default %s), unix:PATH or tcp:HOST:PORT;\n"
              "also from $DESCATTER_ADDRESS. `descatterctl COMMAND --help` for options.\n",
           DS_CTL_DEFAULT_ADDRESS);
}

int
main (int argc, char **argv)
{
  setlocale (LC_ALL, "");
  int i = 1;
  while (i < argc && argv[i][0] == '-') {
    if ((strcmp (argv[i], "--address") == 0 || strcmp (argv[i], "-a") == 0) && i + 1 < argc) {
      ds_ctl_set_address (argv[i + 1]);
      i += 2;
    } else if (g_str_has_prefix (argv[i], "--address=")) {
      ds_ctl_set_address (argv[i] + strlen ("--address="));
      i++;
    } else if (strcmp (argv[i], "--help") == 0 || strcmp (argv[i], "-h") == 0) {
      usage (stdout);
      return 0;
    } else {
      fprintf (stderr, "descatterctl: unknown option %s\n", argv[i]);
      usage (stderr);
      return 2;
    }
  }
  if (i >= argc) {
    usage (stderr);
    return 2;
  }
  for (size_t c = 0; c < sizeof commands / sizeof commands[0]; c++)
    if (strcmp (argv[i], commands[c].name) == 0)
      return commands[c].run (argc - i, argv + i);
  fprintf (stderr, "descatterctl: unknown command \"%s\"\n", argv[i]);
  usage (stderr);
  return 2;
}
