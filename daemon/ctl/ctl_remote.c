/* descatterctl's commands that talk to the daemon. */
#include <stdio.h>
#include <string.h>
#include <unistd.h>

#include "daemon/protocol/client.h"
#include "daemon/ctl/ctl_commands.h"
#include "daemon/ctl/ctl_output.h"

/* The one process-wide option of the CLI, set once by main before any command runs. */
static char *ctl_address;

void
ds_ctl_set_address (const char *address)
{
  g_free (ctl_address);
  ctl_address = g_strdup (address);
}

const char *
ds_ctl_address (void)
{
  if (ctl_address)
    return ctl_address;
  const char *env = g_getenv ("DESCATTER_ADDRESS");
  return env && *env ? env : DS_CTL_DEFAULT_ADDRESS;
}

static gboolean
parse_options (int *argc, char ***argv, GOptionEntry *entries, const char *summary)
{
  g_autoptr (GOptionContext) ctx = g_option_context_new (NULL);
  g_option_context_set_summary (ctx, summary);
  g_option_context_add_main_entries (ctx, entries, NULL);
  g_autoptr (GError) error = NULL;
  if (!g_option_context_parse (ctx, argc, argv, &error)) {
    fprintf (stderr, "descatterctl %s: %s\n", (*argv)[0], error->message);
    return FALSE;
  }
  if (*argc > 1) {
    fprintf (stderr, "descatterctl %s: unexpected argument \"%s\"\n", (*argv)[0], (*argv)[1]);
    return FALSE;
  }
  return TRUE;
}

static void
print_json (JsonNode *node)
{
  if (!node) {
    printf ("{}\n");
    return;
  }
  g_autofree char *text = json_to_string (node, TRUE);
  printf ("%s\n", text);
}

/* Calls cmd; prints a failed reply's error. Returns the message only when ok. */
static DsMessage *
call (DsClient *client, const char *cmd, JsonObject *args, DsClientEventFunc on_event, gpointer data)
{
  g_autoptr (GError) error = NULL;
  DsMessage *m = ds_client_call (client, cmd, args, on_event, data, &error);
  if (!m) {
    fprintf (stderr, "descatterctl %s: %s\n", cmd, error->message);
    return NULL;
  }
  if (!m->reply->ok) {
    fprintf (stderr, "descatterctl %s: %s: %s\n", cmd, ds_protocol_error_name (m->reply->error_code),
             m->reply->error_message);
    ds_message_free (m);
    return NULL;
  }
  return m;
}

static DsClient *
connect_or_complain (const char *cmd)
{
  g_autoptr (GError) error = NULL;
  DsClient *c = ds_client_connect (ds_ctl_address (), &error);
  if (!c)
    fprintf (stderr, "descatterctl %s: %s (is descatterd running? --address)\n", cmd, error->message);
  return c;
}

static int
simple_command (int argc, char **argv, const char *cmd, const char *summary)
{
  GOptionEntry entries[] = { { NULL } };
  if (!parse_options (&argc, &argv, entries, summary))
    return 2;
  g_autoptr (DsClient) c = connect_or_complain (cmd);
  if (!c)
    return 1;
  g_autoptr (DsMessage) m = call (c, cmd, NULL, NULL, NULL);
  if (!m)
    return 1;
  print_json (m->reply->body);
  return 0;
}

int
ds_ctl_hello (int argc, char **argv)
{
  return simple_command (argc, argv, "hello", "Prints the daemon's protocol version and identity.");
}

int
ds_ctl_status (int argc, char **argv)
{
  return simple_command (argc, argv, "status", "Prints devices, frame counters, timings and clients.");
}

int
ds_ctl_stop (int argc, char **argv)
{
  return simple_command (argc, argv, "stop", "Stops continuous acquisition.");
}

int
ds_ctl_config (int argc, char **argv)
{
  GOptionEntry entries[] = { { NULL } };
  if (!parse_options (&argc, &argv, entries, "Prints the daemon's effective configuration."))
    return 2;
  g_autoptr (DsClient) c = connect_or_complain ("config");
  if (!c)
    return 1;
  g_autoptr (DsMessage) m = call (c, "config", NULL, NULL, NULL);
  if (!m)
    return 1;
  JsonObject *o = json_node_get_object (m->reply->body);
  printf ("%s", json_object_get_string_member_with_default (o, "text", ""));
  return 0;
}

/* Acquisition options shared by capture, start and dark. */
typedef struct {
  int phases, averages;
  double exposure_us, gain_db;
  char *estimator;
  gboolean dark_frame, no_verify;
} AcqOptions;

static void
acq_options_free (AcqOptions *o)
{
  g_free (o->estimator);
}

static JsonObject *
acq_args (const AcqOptions *o)
{
  JsonObject *args = json_object_new ();
  if (o->phases)
    json_object_set_int_member (args, "phases", o->phases);
  if (o->averages)
    json_object_set_int_member (args, "averages", o->averages);
  if (o->exposure_us > 0)
    json_object_set_double_member (args, "exposure_us", o->exposure_us);
  if (o->gain_db >= 0)
    json_object_set_double_member (args, "gain_db", o->gain_db);
  if (o->estimator)
    json_object_set_string_member (args, "estimator", o->estimator);
  if (o->dark_frame)
    json_object_set_boolean_member (args, "dark_frame", TRUE);
  if (o->no_verify)
    json_object_set_boolean_member (args, "verify_phase", FALSE);
  return args;
}

#define ACQ_ENTRIES(o)                                                                             \
  { "phases", 'n', 0, G_OPTION_ARG_INT, &(o).phases, "Phases N (2..64)", "N" },                   \
  { "averages", 'm', 0, G_OPTION_ARG_INT, &(o).averages, "Frames averaged per phase (1..64)", "M" }, \
  { "exposure-us", 'e', 0, G_OPTION_ARG_DOUBLE, &(o).exposure_us, "Exposure (µs)", "E" },          \
  { "gain-db", 'g', 0, G_OPTION_ARG_DOUBLE, &(o).gain_db, "Gain (dB)", "G" },                      \
  { "estimator", 0, 0, G_OPTION_ARG_STRING, &(o).estimator, "maxmin, sine or robust", "NAME" },     \
  { "dark-frame", 0, 0, G_OPTION_ARG_NONE, &(o).dark_frame, "Take a dark frame with this set", NULL }, \
  { "no-verify", 0, 0, G_OPTION_ARG_NONE, &(o).no_verify, "Do not verify the stripe phase of each frame", NULL }

static void
on_progress (const DsMessage *ev, gpointer data)
{
  gboolean *tty = data;
  if (g_strcmp0 (ev->reply->event, "progress") != 0 || !ev->reply->body)
    return;
  JsonObject *o = json_node_get_object (ev->reply->body);
  gint64 k = json_object_get_int_member_with_default (o, "phase", 0);
  gint64 n = json_object_get_int_member_with_default (o, "phases", 0);
  fprintf (stderr, *tty ? "\rphase %" G_GINT64_FORMAT "/%" G_GINT64_FORMAT " acquired" : "phase %" G_GINT64_FORMAT "/%" G_GINT64_FORMAT " acquired\n",
           k + 1, n);
  fflush (stderr);
}

int
ds_ctl_capture (int argc, char **argv)
{
  AcqOptions o = { .gain_db = -1 };
  g_autofree char *out = NULL, *format = NULL;
  gboolean extrema = FALSE, quiet = FALSE;
  GOptionEntry entries[] = {
    ACQ_ENTRIES (o),
    { "format", 'f', 0, G_OPTION_ARG_STRING, &format, "f32 (default) or u16", "FMT" },
    { "extrema", 0, 0, G_OPTION_ARG_NONE, &extrema, "Also fetch max, min and mean", NULL },
    { "out", 'o', 0, G_OPTION_ARG_FILENAME, &out, "Output folder (default .)", "DIR" },
    { "quiet", 'q', 0, G_OPTION_ARG_NONE, &quiet, "No progress line", NULL },
    { NULL },
  };
  if (!parse_options (&argc, &argv, entries,
                      "Acquires one phase set and writes transmissive/scattered (TIFF), the mask, "
                      "PNG previews and result.json.")) {
    acq_options_free (&o);
    return 2;
  }
  g_autoptr (JsonObject) args = acq_args (&o);
  acq_options_free (&o);
  if (format)
    json_object_set_string_member (args, "format", format);
  if (extrema) {
    JsonArray *outs = json_array_new ();
    const char *names[] = { "transmissive", "scattered", "mask", "max", "min", "mean" };
    for (guint i = 0; i < G_N_ELEMENTS (names); i++)
      json_array_add_string_element (outs, names[i]);
    json_object_set_array_member (args, "outputs", outs);
  }
  json_object_set_boolean_member (args, "progress", !quiet);
  g_autoptr (DsClient) c = connect_or_complain ("capture");
  if (!c)
    return 1;
  gboolean tty = isatty (2);
  g_autoptr (DsMessage) m = call (c, "capture", args, on_progress, &tty);
  if (tty && !quiet)
    fprintf (stderr, "\n");
  if (!m)
    return 1;
  g_autoptr (GError) error = NULL;
  const char *dir = out ? out : ".";
  if (!ds_ctl_write_result (m, dir, "", &error)) {
    fprintf (stderr, "descatterctl capture: writing %s: %s\n", dir, error->message);
    return 1;
  }
  JsonObject *body = json_node_get_object (m->reply->body);
  printf ("set %" G_GINT64_FORMAT " written to %s\n", json_object_get_int_member_with_default (body, "set_id", 0), dir);
  return 0;
}

int
ds_ctl_start (int argc, char **argv)
{
  AcqOptions o = { .gain_db = -1 };
  GOptionEntry entries[] = { ACQ_ENTRIES (o), { NULL } };
  if (!parse_options (&argc, &argv, entries, "Starts continuous acquisition (results go to subscribers).")) {
    acq_options_free (&o);
    return 2;
  }
  g_autoptr (JsonObject) args = acq_args (&o);
  acq_options_free (&o);
  g_autoptr (DsClient) c = connect_or_complain ("start");
  if (!c)
    return 1;
  g_autoptr (DsMessage) m = call (c, "start", args, NULL, NULL);
  if (!m)
    return 1;
  print_json (m->reply->body);
  return 0;
}

int
ds_ctl_dark (int argc, char **argv)
{
  int averages = 0;
  double exposure = 0, gain = -1;
  GOptionEntry entries[] = {
    { "averages", 'm', 0, G_OPTION_ARG_INT, &averages, "Frames averaged (1..64)", "M" },
    { "exposure-us", 'e', 0, G_OPTION_ARG_DOUBLE, &exposure, "Exposure (µs)", "E" },
    { "gain-db", 'g', 0, G_OPTION_ARG_DOUBLE, &gain, "Gain (dB)", "G" },
    { NULL },
  };
  if (!parse_options (&argc, &argv, entries, "Measures the dark frame (illuminator off) used by later sets."))
    return 2;
  g_autoptr (JsonObject) args = json_object_new ();
  if (averages)
    json_object_set_int_member (args, "averages", averages);
  if (exposure > 0)
    json_object_set_double_member (args, "exposure_us", exposure);
  if (gain >= 0)
    json_object_set_double_member (args, "gain_db", gain);
  g_autoptr (DsClient) c = connect_or_complain ("dark");
  if (!c)
    return 1;
  g_autoptr (DsMessage) m = call (c, "dark", args, NULL, NULL);
  if (!m)
    return 1;
  print_json (m->reply->body);
  return 0;
}

int
ds_ctl_stream (int argc, char **argv)
{
  int count = 0, delay_ms = 0;
  g_autofree char *out = NULL;
  GOptionEntry entries[] = {
    { "count", 'c', 0, G_OPTION_ARG_INT, &count, "Stop after this many results (default: forever)", "N" },
    { "out", 'o', 0, G_OPTION_ARG_FILENAME, &out, "Write each result to DIR/set-NNNNNN-*", "DIR" },
    { "delay-ms", 0, 0, G_OPTION_ARG_INT, &delay_ms, "Wait this long before reading each message (simulates a slow client)", "MS" },
    { NULL },
  };
  if (!parse_options (&argc, &argv, entries, "Subscribes to results and prints (or writes) each one."))
    return 2;
  g_autoptr (DsClient) c = connect_or_complain ("stream");
  if (!c)
    return 1;
  g_autoptr (DsMessage) sub = call (c, "subscribe", NULL, NULL, NULL);
  if (!sub)
    return 1;
  guint64 last_seq = 0;
  for (int got = 0; count == 0 || got < count;) {
    if (delay_ms > 0)
      g_usleep ((gulong) delay_ms * 1000);
    g_autoptr (GError) error = NULL;
    g_autoptr (DsMessage) m = ds_client_read (c, 0, &error);
    if (!m) {
      fprintf (stderr, "descatterctl stream: %s\n", error->message);
      return 1;
    }
    if (!m->reply->event)
      continue;
    if (strcmp (m->reply->event, "result") != 0) {
      g_autofree char *body = m->reply->body ? json_to_string (m->reply->body, FALSE) : g_strdup ("");
      printf ("%s %s\n", m->reply->event, body);
      fflush (stdout);
      continue;
    }
    JsonObject *body = json_node_get_object (m->reply->body);
    gint64 set_id = json_object_get_int_member_with_default (body, "set_id", 0);
    guint64 lost = last_seq && m->reply->seq > last_seq + 1 ? m->reply->seq - last_seq - 1 : 0;
    last_seq = m->reply->seq;
    printf ("result seq=%" G_GUINT64_FORMAT " set=%" G_GINT64_FORMAT " lost=%" G_GUINT64_FORMAT "\n",
            m->reply->seq, set_id, lost);
    fflush (stdout);
    if (out) {
      g_autofree char *prefix = g_strdup_printf ("set-%06" G_GINT64_FORMAT "-", set_id);
      if (!ds_ctl_write_result (m, out, prefix, &error)) {
        fprintf (stderr, "descatterctl stream: writing %s: %s\n", out, error->message);
        return 1;
      }
    }
    got++;
  }
  return 0;
}
