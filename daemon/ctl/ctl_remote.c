/* descatterctl's commands that talk to the daemon (status: ctl_status.c). */
#include <errno.h>
#include <math.h>
#include <glib/gstdio.h>
#include <signal.h>
#include <string.h>
#include <unistd.h>

#include "daemon/ctl/ctl_commands.h"
#include "daemon/ctl/ctl_interrupt.h"
#include "daemon/ctl/ctl_output.h"
#include "daemon/output/result_meta.h"

/* Human output of the replies that carry a `message` (stop, release, acquire): that sentence,
 * which the daemon words for people. */
static void
print_message (JsonObject *body)
{
  printf ("%s\n", json_object_get_string_member_with_default (body, "message", "done"));
}

/* A command without arguments whose reply is printed by human (the JSON with --json). */
static int
simple_command (const DsCtlTarget *target, int argc, char **argv, const char *cmd, const char *summary,
                void (*human) (JsonObject *body))
{
  gboolean json = FALSE;
  GOptionEntry entries[] = { DS_CTL_JSON_ENTRY (json), { NULL } };
  if (!ds_ctl_parse_options (&argc, &argv, entries, summary))
    return 2;
  g_autoptr (DsClient) c = ds_ctl_connect (target, cmd);
  if (!c)
    return 1;
  g_autoptr (DsMessage) m = ds_ctl_call (c, cmd, NULL, NULL, NULL);
  if (!m)
    return 1;
  ds_ctl_print_reply (m->reply->body, json, human);
  return 0;
}

static void
print_hello (JsonObject *body)
{
  printf ("%s %s (%s), protocol %" G_GINT64_FORMAT "\n",
          json_object_get_string_member_with_default (body, "server", "?"),
          json_object_get_string_member_with_default (body, "version", "?"),
          json_object_get_string_member_with_default (body, "git", "?"),
          json_object_get_int_member_with_default (body, "protocol", 0));
}

int
ds_ctl_hello (const DsCtlTarget *target, int argc, char **argv)
{
  gboolean json = FALSE;
  GOptionEntry entries[] = { DS_CTL_JSON_ENTRY (json), { NULL } };
  if (!ds_ctl_parse_options (&argc, &argv, entries, "Prints the daemon's protocol version, version and build."))
    return 2;
  g_autoptr (DsClient) c = ds_ctl_connect (target, "hello");
  if (!c)
    return 1;
  /* A hello without the token would undo the authentication: the daemon closes the line. */
  g_autoptr (JsonObject) args = json_object_new ();
  if (target->token)
    json_object_set_string_member (args, "token", target->token);
  json_object_set_string_member (args, "client", "descatterctl");
  g_autoptr (DsMessage) m = ds_ctl_call (c, "hello", args, NULL, NULL);
  if (!m)
    return 1;
  ds_ctl_print_reply (m->reply->body, json, print_hello);
  return 0;
}

int
ds_ctl_stop (const DsCtlTarget *target, int argc, char **argv)
{
  return simple_command (target, argc, argv, "stop", "Stops continuous acquisition after the set in progress.",
                         print_message);
}

static void
print_cancelled (JsonObject *body)
{
  gint64 n = json_object_get_int_member_with_default (body, "cancelled", 0);
  gboolean stream = json_object_get_boolean_member_with_default (body, "stream_stopped", FALSE);
  printf ("%" G_GINT64_FORMAT " request%s cancelled%s; state %s\n", n, n == 1 ? "" : "s",
          stream ? ", continuous acquisition stopped" : "",
          json_object_get_string_member_with_default (body, "state", "?"));
}

int
ds_ctl_cancel (const DsCtlTarget *target, int argc, char **argv)
{
  return simple_command (target, argc, argv, "cancel",
                         "Stops what the daemon acquires, whoever asked: the set in progress, every capture, "
                         "calibrate and dark waiting (answered `cancelled`) and continuous acquisition.",
                         print_cancelled);
}

int
ds_ctl_release (const DsCtlTarget *target, int argc, char **argv)
{
  return simple_command (target, argc, argv, "release",
                         "Closes the camera and illuminator so that another program (arv-viewer) can open the "
                         "camera; captures are refused until `descatterctl acquire`.",
                         print_message);
}

int
ds_ctl_acquire (const DsCtlTarget *target, int argc, char **argv)
{
  return simple_command (target, argc, argv, "acquire", "Opens the devices again after `descatterctl release`.",
                         print_message);
}

int
ds_ctl_config (const DsCtlTarget *target, int argc, char **argv)
{
  GOptionEntry entries[] = { { NULL } };
  if (!ds_ctl_parse_options (&argc, &argv, entries,
                             "Prints the daemon's effective configuration (the file with the "
                             "daemon's command-line overrides applied)."))
    return 2;
  g_autoptr (DsClient) c = ds_ctl_connect (target, "config");
  if (!c)
    return 1;
  g_autoptr (DsMessage) m = ds_ctl_call (c, "config", NULL, NULL, NULL);
  if (!m)
    return 1;
  JsonObject *o = json_node_get_object (m->reply->body);
  printf ("%s", json_object_get_string_member_with_default (o, "text", ""));
  return 0;
}

/* Acquisition options shared by capture and start. Numbers stay text until sent
 * (ds_ctl_args_int): NULL is "not given", every typed value goes to the daemon. */
typedef struct {
  char *phases, *averages, *exposure_us, *gain_db, *target_error, *time_budget_ms, *speed_px_s, *estimator;
  gboolean dark_frame, no_dark_frame, no_verify, single_frame;
} AcqOptions;

static void
acq_options_clear (AcqOptions *o)
{
  g_free (o->phases);
  g_free (o->averages);
  g_free (o->exposure_us);
  g_free (o->gain_db);
  g_free (o->target_error);
  g_free (o->time_budget_ms);
  g_free (o->speed_px_s);
  g_free (o->estimator);
}
G_DEFINE_AUTO_CLEANUP_CLEAR_FUNC (AcqOptions, acq_options_clear)

/* NULL (message printed) when an option is malformed or contradicts another. */
static JsonObject *
acq_args (const AcqOptions *o, const char *cmd)
{
  g_autoptr (JsonObject) args = json_object_new ();
  if (!ds_ctl_args_int (args, cmd, "phases", "phases", o->phases) ||
      !ds_ctl_args_int (args, cmd, "averages", "averages", o->averages) ||
      !ds_ctl_args_double (args, cmd, "exposure-us", "exposure_us", o->exposure_us) ||
      !ds_ctl_args_double (args, cmd, "gain-db", "gain_db", o->gain_db) ||
      !ds_ctl_args_double (args, cmd, "target-error", "target_error", o->target_error) ||
      !ds_ctl_args_double (args, cmd, "time-budget-ms", "time_budget_ms", o->time_budget_ms) ||
      !ds_ctl_args_double (args, cmd, "speed-px-s", "speed_px_s", o->speed_px_s))
    return NULL;
  if (o->dark_frame && o->no_dark_frame) {
    fprintf (stderr, "descatterctl %s: --dark-frame and --no-dark-frame exclude each other\n", cmd);
    return NULL;
  }
  if (o->estimator)
    json_object_set_string_member (args, "estimator", o->estimator);
  if (o->dark_frame || o->no_dark_frame)
    json_object_set_boolean_member (args, "dark_frame", o->dark_frame);
  if (o->no_verify)
    json_object_set_boolean_member (args, "verify_phase", FALSE);
  if (o->single_frame)
    json_object_set_boolean_member (args, "single_frame", TRUE);
  return g_steal_pointer (&args);
}

#define ACQ_ENTRIES(o)                                                                                     \
  { "phases", 'n', 0, G_OPTION_ARG_STRING, &(o).phases, "Phases N (2..64)", "N" },                         \
  { "averages", 'm', 0, G_OPTION_ARG_STRING, &(o).averages, "Frames averaged per phase (1..64)", "M" },    \
  { "exposure-us", 'e', 0, G_OPTION_ARG_STRING, &(o).exposure_us, "Exposure (µs, 1..1e7)", "E" },          \
  { "gain-db", 'g', 0, G_OPTION_ARG_STRING, &(o).gain_db, "Gain (dB, 0..48)", "G" },                       \
  { "estimator", 0, 0, G_OPTION_ARG_STRING, &(o).estimator, "maxmin, sine or robust", "NAME" },            \
  { "dark-frame", 0, 0, G_OPTION_ARG_NONE, &(o).dark_frame, "Take a dark frame with each set", NULL },     \
  { "no-dark-frame", 0, 0, G_OPTION_ARG_NONE, &(o).no_dark_frame, "Take no dark frame (overrides the configuration)", NULL }, \
  { "no-verify", 0, 0, G_OPTION_ARG_NONE, &(o).no_verify, "Do not verify the stripe phase of each frame", NULL }, \
  { "single-frame", 0, 0, G_OPTION_ARG_NONE, &(o).single_frame,                                             \
    "One frame per result, separated from one stripe period around each pixel (maxmin or sine; for moving "  \
    "scenes, at one period's resolution along x)", NULL },                                                   \
  { "target-error", 0, 0, G_OPTION_ARG_STRING, &(o).target_error,                                           \
    "Automatic operating point: the relative error to reach (0..1; docs/accuracy.md)", "ERR" },              \
  { "time-budget-ms", 0, 0, G_OPTION_ARG_STRING, &(o).time_budget_ms,                                       \
    "Automatic operating point: the acquisition time allowed per set (ms)", "MS" },                         \
  { "speed-px-s", 0, 0, G_OPTION_ARG_STRING, &(o).speed_px_s,                                               \
    "Automatic operating point: the moving objects' speed across the stripes (px/s along x); predictions "  \
    "then include the motion error (docs/accuracy.md, \"Moving objects\")", "V" }

static void
on_progress (const DsMessage *ev, gpointer data)
{
  gboolean *tty = data;
  if (g_strcmp0 (ev->reply->event, "progress") != 0 || !ev->reply->body)
    return;
  JsonObject *o = json_node_get_object (ev->reply->body);
  gint64 k = json_object_get_int_member_with_default (o, "phase", 0);
  gint64 n = json_object_get_int_member_with_default (o, "phases", 0);
  fprintf (stderr, "%sphase %" G_GINT64_FORMAT "/%" G_GINT64_FORMAT " acquired%s", *tty ? "\r" : "",
           k + 1, n, *tty ? "" : "\n");
  fflush (stderr);
}

/* TRUE when dir does not exist, or is an empty folder. */
static gboolean
dir_is_free (const char *dir, gboolean *exists, GError **error)
{
  *exists = g_file_test (dir, G_FILE_TEST_EXISTS);
  if (!*exists)
    return TRUE;
  if (!g_file_test (dir, G_FILE_TEST_IS_DIR)) {
    g_set_error (error, G_FILE_ERROR, G_FILE_ERROR_NOTDIR, "%s exists and is not a folder", dir);
    return FALSE;
  }
  g_autoptr (GDir) d = g_dir_open (dir, 0, error);
  if (!d)
    return FALSE;
  const char *first = g_dir_read_name (d);
  if (first) {
    g_set_error (error, G_FILE_ERROR, G_FILE_ERROR_EXIST,
                 "%s already holds files (%s...): its results would be overwritten; "
                 "--force to write into it anyway, or choose another folder", dir, first);
    return FALSE;
  }
  return TRUE;
}

/* The folder results go to, created before anything is acquired so that a refusal wastes no
 * acquisition. --out: refused when it holds files, unless --force. No --out (capture): a new
 * folder capture-YYYYmmdd-HHMMSS in the current directory, which the final line names. */
static char *
prepare_out_dir (const char *cmd, const char *out, gboolean force)
{
  g_autoptr (GError) error = NULL;
  if (out) {
    gboolean exists;
    if (!force && !dir_is_free (out, &exists, &error)) {
      fprintf (stderr, "descatterctl %s: --out %s\n", cmd, error->message);
      return NULL;
    }
    if (g_mkdir_with_parents (out, 0755) != 0) {
      fprintf (stderr, "descatterctl %s: cannot create %s: %s\n", cmd, out, g_strerror (errno));
      return NULL;
    }
    return g_strdup (out);
  }
  g_autoptr (GDateTime) now = g_date_time_new_now_local ();
  g_autofree char *base = g_date_time_format (now, "capture-%Y%m%d-%H%M%S");
  for (guint k = 1; k < 100; k++) {
    g_autofree char *dir = k == 1 ? g_strdup (base) : g_strdup_printf ("%s-%u", base, k);
    if (g_mkdir (dir, 0755) == 0)
      return g_steal_pointer (&dir);
    if (errno != EEXIST) {
      fprintf (stderr, "descatterctl %s: cannot create ./%s: %s (--out DIR)\n", cmd, dir, g_strerror (errno));
      return NULL;
    }
  }
  fprintf (stderr, "descatterctl %s: cannot find a free folder name %s-N (--out DIR)\n", cmd, base);
  return NULL;
}

/* --files: the kinds of result files (daemon/output/result_files.h). */
static gboolean
parse_files (const char *cmd, const char *list, const char *fallback, guint *kinds)
{
  g_autoptr (GError) error = NULL;
  if (!ds_file_kinds_parse (list ? list : fallback, kinds, &error)) {
    fprintf (stderr, "descatterctl %s: --files: %s\n", cmd, error->message);
    return FALSE;
  }
  return TRUE;
}

/* An automatic capture's prediction where it is a lower bound (docs/accuracy.md): its upper end,
 * or that the pilot bounds none, so that the user does not read the prediction as the error. */
static void
print_lower_bound (JsonNode *body)
{
  JsonNode *lower = ds_json_path (body, "settings.operating_point.lower_bound");
  if (!lower || !JSON_NODE_HOLDS_VALUE (lower) || json_node_get_value_type (lower) != G_TYPE_BOOLEAN ||
      !json_node_get_boolean (lower))
    return;
  double predicted = ds_json_path_double (body, "settings.operating_point.predicted_error", NAN);
  double upper = ds_json_path_double (body, "settings.operating_point.predicted_error_upper", NAN);
  if (isfinite (upper))
    fprintf (stderr, "descatterctl capture: predicted error %.4g is a lower bound; its upper end is %.4g\n", predicted,
             upper);
  else
    fprintf (stderr, "descatterctl capture: predicted error %.4g is a lower bound with no upper end\n", predicted);
}

int
ds_ctl_capture (const DsCtlTarget *target, int argc, char **argv)
{
  g_auto (AcqOptions) o = { 0 };
  g_autofree char *out = NULL, *format = NULL, *files = NULL;
  gboolean extrema = FALSE, quiet = FALSE, force = FALSE, save_phases = FALSE;
  GOptionEntry entries[] = {
    ACQ_ENTRIES (o),
    { "format", 'f', 0, G_OPTION_ARG_STRING, &format, "Wire format: f32 (default) or u16", "FMT" },
    { "extrema", 0, 0, G_OPTION_ARG_NONE, &extrema, "Also fetch max, min and mean", NULL },
    { "files", 0, 0, G_OPTION_ARG_STRING, &files,
      "Files to write: any of " DS_FILES_ALL_NAMES " (default tiff,png16,preview)", "LIST" },
    { "save-phases", 0, 0, G_OPTION_ARG_NONE, &save_phases,
      "Also fetch the raw phase and dark frames and write them as a phase folder (descatterctl separate reads it)",
      NULL },
    { "out", 'o', 0, G_OPTION_ARG_FILENAME, &out,
      "Output folder (default: a new capture-DATE-TIME folder here)", "DIR" },
    { "force", 0, 0, G_OPTION_ARG_NONE, &force, "Write into --out even when it holds files", NULL },
    { "quiet", 'q', 0, G_OPTION_ARG_NONE, &quiet, "No progress line", NULL },
    { NULL },
  };
  guint kinds = 0;
  if (!ds_ctl_parse_options (&argc, &argv, entries,
                             "Acquires one phase set and writes set-<UTC>-<id>-transmissive.tiff, "
                             "-scattered.tiff (float32 with tags), -mask.png, -direct.png/-global.png "
                             "(16-bit), previews and the sidecar set-<UTC>-<id>.json (docs/operations.md, "
                             "\"Result files\").") ||
      !parse_files ("capture", files, "tiff,png16,preview", &kinds))
    return 2;
  g_autoptr (JsonObject) args = acq_args (&o, "capture");
  if (!args)
    return 2;
  if (save_phases) {
    json_object_set_boolean_member (args, "save_phases", TRUE);
    kinds |= DS_FILES_PHASES;
  }
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
  g_autoptr (DsClient) c = ds_ctl_connect (target, "capture");
  if (!c)
    return 1;
  g_autofree char *dir = prepare_out_dir ("capture", out, force);
  if (!dir)
    return 1;
  gboolean tty = isatty (2);
  /* Ctrl-C cancels the capture in the daemon as well (ctl_interrupt.h): nothing is written. */
  ds_ctl_interrupt_begin (target, "capture");
  g_autoptr (DsMessage) m = ds_ctl_call (c, "capture", args, on_progress, &tty);
  gboolean interrupted = ds_ctl_interrupt_end ();
  if (tty && !quiet)
    fprintf (stderr, "\n");
  if (!m || interrupted) {
    if (!out)
      g_rmdir (dir); /* the folder we made is still empty */
    return interrupted ? DS_CTL_EXIT_INTERRUPTED : 1;
  }
  g_autoptr (GError) error = NULL;
  if (save_phases && !ds_json_path (m->reply->body, "raw_frames")) {
    fprintf (stderr, "descatterctl capture: the daemon sent no raw frames (too old for --save-phases?)\n");
    return 1;
  }
  g_autoptr (GPtrArray) written = g_ptr_array_new_with_free_func (g_free);
  if (!ds_ctl_write_result (m, dir, kinds, written, &error)) {
    fprintf (stderr, "descatterctl capture: writing %s: %s\n", dir, error->message);
    return 1;
  }
  /* Chosen on the margin (docs/protocol.md): the user asked for a target no point is predicted to
   * meet, and should not learn it from the metadata only. */
  JsonNode *margin = ds_json_path (m->reply->body, "settings.operating_point.target_may_be_missed");
  if (margin && JSON_NODE_HOLDS_VALUE (margin) && json_node_get_value_type (margin) == G_TYPE_BOOLEAN &&
      json_node_get_boolean (margin))
    fprintf (stderr, "descatterctl capture: the target may be missed: %s\n",
             ds_json_path_string (m->reply->body, "settings.operating_point.target_note", ""));
  print_lower_bound (m->reply->body);
  JsonObject *body = json_node_get_object (m->reply->body);
  printf ("set %" G_GINT64_FORMAT " written to %s/%s: %s\n", json_object_get_int_member_with_default (body, "set_id", 0),
          dir, out ? "" : " (a new folder here: no --out given)",
          written->len ? (const char *) written->pdata[written->len - 1] : "");
  return 0;
}

/* start's reply is the settings the sets run with (docs/protocol.md, "Result settings"). */
static void
print_started (JsonObject *s)
{
  /* Not ready: the stream's sets fail until the devices are (the daemon's words, and why). */
  const char *why = json_object_get_string_member_with_default (s, "not_ready_reason", NULL);
  if (why)
    fprintf (stderr, "descatterctl start: %s (%s)\n", json_object_get_string_member_with_default (s, "message", ""),
             why);
  gint64 m = json_object_get_int_member_with_default (s, "averages", 1);
  printf ("continuous acquisition started: %" G_GINT64_FORMAT " phases x %" G_GINT64_FORMAT " frame%s, %s, "
          "exposure %g µs, gain %g dB, dark frame %s; results go to subscribers (descatterctl stream)\n",
          json_object_get_int_member_with_default (s, "phases", 0), m, m == 1 ? "" : "s",
          json_object_get_string_member_with_default (s, "estimator", "?"),
          json_object_get_double_member_with_default (s, "exposure_us", 0),
          json_object_get_double_member_with_default (s, "gain_db", 0),
          json_object_get_boolean_member_with_default (s, "dark_frame", FALSE) ? "on" : "off");
}

int
ds_ctl_start (const DsCtlTarget *target, int argc, char **argv)
{
  g_auto (AcqOptions) o = { 0 };
  gboolean json = FALSE;
  g_autofree char *results = NULL;
  GOptionEntry entries[] = { ACQ_ENTRIES (o),
                             { "results", 0, 0, G_OPTION_ARG_STRING, &results,
                               "per-set (a result per phase set) or per-frame (a result per frame from the "
                               "latest N phases; needs averages 1)", "MODE" },
                             DS_CTL_JSON_ENTRY (json), { NULL } };
  if (!ds_ctl_parse_options (&argc, &argv, entries,
                             "Starts continuous acquisition (results go to subscribers: "
                             "descatterctl stream). Without options the configuration's settings "
                             "apply, and follow its reloads."))
    return 2;
  g_autoptr (JsonObject) args = acq_args (&o, "start");
  if (!args)
    return 2;
  if (results)
    json_object_set_string_member (args, "results", results);
  g_autoptr (DsClient) c = ds_ctl_connect (target, "start");
  if (!c)
    return 1;
  g_autoptr (DsMessage) m = ds_ctl_call (c, "start", args, NULL, NULL);
  if (!m)
    return 1;
  ds_ctl_print_reply (m->reply->body, json, print_started);
  return 0;
}

static void
print_dark (JsonObject *body)
{
  printf ("dark frame stored: mean %.2f DN; later sets with the same exposure and gain subtract it\n",
          json_object_get_double_member_with_default (body, "dark_mean_dn", 0));
}

int
ds_ctl_dark (const DsCtlTarget *target, int argc, char **argv)
{
  g_autofree char *averages = NULL, *exposure = NULL, *gain = NULL;
  gboolean json = FALSE;
  GOptionEntry entries[] = {
    DS_CTL_JSON_ENTRY (json),
    { "averages", 'm', 0, G_OPTION_ARG_STRING, &averages, "Frames averaged (1..64)", "M" },
    { "exposure-us", 'e', 0, G_OPTION_ARG_STRING, &exposure, "Exposure (µs, 1..1e7)", "E" },
    { "gain-db", 'g', 0, G_OPTION_ARG_STRING, &gain, "Gain (dB, 0..48)", "G" },
    { NULL },
  };
  if (!ds_ctl_parse_options (&argc, &argv, entries, "Measures the dark frame (illuminator off) used by later sets."))
    return 2;
  g_autoptr (JsonObject) args = json_object_new ();
  if (!ds_ctl_args_int (args, "dark", "averages", "averages", averages) ||
      !ds_ctl_args_double (args, "dark", "exposure-us", "exposure_us", exposure) ||
      !ds_ctl_args_double (args, "dark", "gain-db", "gain_db", gain))
    return 2;
  g_autoptr (DsClient) c = ds_ctl_connect (target, "dark");
  if (!c)
    return 1;
  g_autoptr (DsMessage) m = ds_ctl_call (c, "dark", args, NULL, NULL);
  if (!m)
    return 1;
  ds_ctl_print_reply (m->reply->body, json, print_dark);
  return 0;
}

/* A subscriber of an idle daemon would wait with no output: say why, and how to start. */
static void
note_when_idle (DsClient *c)
{
  g_autoptr (GError) error = NULL;
  g_autoptr (DsMessage) m = ds_client_call (c, "status", NULL, NULL, NULL, &error);
  if (!m || !m->reply->ok || !m->reply->body || !JSON_NODE_HOLDS_OBJECT (m->reply->body))
    return;
  JsonObject *st = json_node_get_object (m->reply->body);
  if (json_object_get_boolean_member_with_default (st, "continuous", FALSE) ||
      json_object_get_int_member_with_default (st, "pending", 0) > 0)
    return;
  const char *state = json_object_get_string_member_with_default (st, "state", "?");
  const char *last_error = json_object_get_string_member_with_default (st, "last_error", "");
  if (strcmp (state, "failed") == 0)
    fprintf (stderr, "descatterctl stream: the daemon's devices failed (%s); no results will come "
                     "until it is restarted\n", *last_error ? last_error : "see descatterctl status");
  else
    fprintf (stderr, "descatterctl stream: descatterd is not acquiring (state %s): results come "
                     "while continuous acquisition runs (`descatterctl start`, `descatterctl stop`) "
                     "or other clients capture; waiting (Ctrl-C to end)\n", state);
}

/* SIGINT/SIGTERM end `stream` between two messages, so that a growing HDF5 file is closed and
 * renamed. A signal handler can only set a flag: this one is the process's. */
static volatile sig_atomic_t stream_stop;

static void
on_stop_signal (int sig)
{
  (void) sig;
  stream_stop = 1;
}

/* Appends a streamed result to the stream's growing HDF5 file (opened at the first one). */
static gboolean
append_to_run (DsHdf5Run **run, const DsMessage *m, const char *dir, GError **error)
{
  g_autoptr (DsCtlResult) r = ds_ctl_result_new (m, error);
  if (!r)
    return FALSE;
  const DsOutputResult *planes = ds_ctl_result_planes (r);
  if (!*run) {
    g_autofree char *stem = ds_result_stem (planes->meta);
    g_autofree char *name = g_strdup_printf ("run-%s.h5", stem + strlen ("set-"));
    g_autofree char *path = g_build_filename (dir, name, NULL);
    *run = ds_hdf5_run_open (path, planes, error);
    if (!*run)
      return FALSE;
  }
  return ds_hdf5_run_append (*run, planes, error);
}

static int
close_run (DsHdf5Run *run, int status)
{
  if (!run)
    return status;
  g_autoptr (GError) error = NULL;
  g_autofree char *path = g_strdup (ds_hdf5_run_path (run));
  if (!ds_hdf5_run_close (run, &error)) {
    fprintf (stderr, "descatterctl stream: %s\n", error->message);
    return 1;
  }
  fprintf (stderr, "descatterctl stream: run written to %s\n", path);
  return status;
}

int
ds_ctl_stream (const DsCtlTarget *target, int argc, char **argv)
{
  g_autofree char *count_text = NULL, *delay_text = NULL, *out = NULL, *files = NULL;
  gboolean force = FALSE;
  GOptionEntry entries[] = {
    { "count", 'c', 0, G_OPTION_ARG_STRING, &count_text,
      "Stop after this many sets, each a result or a failure (default: until interrupted); exit status 1 "
      "when one of them failed", "N" },
    { "out", 'o', 0, G_OPTION_ARG_FILENAME, &out, "Write each result to DIR (set-<UTC>-<id>-*)", "DIR" },
    { "files", 0, 0, G_OPTION_ARG_STRING, &files,
      "Files to write with --out: any of " DS_FILES_ALL_NAMES " (default tiff); hdf5-run: one growing file for "
      "the whole stream", "LIST" },
    { "force", 0, 0, G_OPTION_ARG_NONE, &force, "Write into --out even when it holds files", NULL },
    { "delay-ms", 0, 0, G_OPTION_ARG_STRING, &delay_text, "Wait this long before reading each message (simulates a slow client)", "MS" },
    { NULL },
  };
  if (!ds_ctl_parse_options (&argc, &argv, entries,
                             "Subscribes to results and prints (or writes) each one; `failed` and "
                             "`device` events are printed as they come."))
    return 2;
  guint kinds = 0;
  if (!parse_files ("stream", files, "tiff", &kinds))
    return 2;
  gint64 count = 0, delay_ms = 0;
  if ((count_text && !ds_ctl_parse_int ("stream", "count", count_text, &count)) ||
      (delay_text && !ds_ctl_parse_int ("stream", "delay-ms", delay_text, &delay_ms)))
    return 2;
  if (count_text && count < 1) {
    fprintf (stderr, "descatterctl stream: --count must be at least 1 (leave it out to stream forever)\n");
    return 2;
  }
  if (delay_ms < 0 || delay_ms > 3600 * 1000) {
    fprintf (stderr, "descatterctl stream: --delay-ms must be in 0..3600000\n");
    return 2;
  }
  g_autoptr (DsClient) c = ds_ctl_connect (target, "stream");
  if (!c)
    return 1;
  g_autofree char *dir = out ? prepare_out_dir ("stream", out, force) : NULL;
  if (out && !dir)
    return 1;
  /* Before subscribing: a status reply waited for later would drop the events before it. */
  note_when_idle (c);
  g_autoptr (DsMessage) sub = ds_ctl_call (c, "subscribe", NULL, NULL, NULL);
  if (!sub)
    return 1;
  /* seq counts every result the daemon publishes: a gap is results this client lost. */
  guint64 last_seq = 0;
  if (sub->reply->body && JSON_NODE_HOLDS_OBJECT (sub->reply->body)) {
    gint64 next = json_object_get_int_member_with_default (json_node_get_object (sub->reply->body), "next_seq", 0);
    last_seq = next > 0 ? (guint64) next - 1 : 0;
  }
  struct sigaction sa = { .sa_handler = on_stop_signal };
  sigaction (SIGINT, &sa, NULL);
  sigaction (SIGTERM, &sa, NULL);
  DsHdf5Run *run = NULL;
  /* A failed set counts towards --count: with every set failing (the illuminator showing the
   * wrong phase, say) a scripted `stream --count N` would otherwise never end. */
  gint64 failed = 0;
  for (gint64 got = 0; (count == 0 || got < count) && !stream_stop;) {
    if (delay_ms > 0)
      g_usleep ((gulong) delay_ms * 1000);
    g_autoptr (GError) error = NULL;
    /* Wake up now and then to notice a stop signal. */
    g_autoptr (DsMessage) m = ds_client_read (c, 500, &error);
    if (!m && g_error_matches (error, G_IO_ERROR, G_IO_ERROR_TIMED_OUT))
      continue;
    if (!m) {
      fprintf (stderr, "descatterctl stream: %s\n", error->message);
      return close_run (run, 1);
    }
    if (!m->reply->event)
      continue;
    if (strcmp (m->reply->event, "result") != 0) {
      g_autofree char *body = m->reply->body ? json_to_string (m->reply->body, FALSE) : g_strdup ("");
      printf ("%s %s\n", m->reply->event, body);
      fflush (stdout);
      if (strcmp (m->reply->event, "failed") == 0) {
        failed++;
        got++;
      }
      continue;
    }
    JsonObject *body = json_node_get_object (m->reply->body);
    gint64 set_id = json_object_get_int_member_with_default (body, "set_id", 0);
    guint64 lost = m->reply->seq > last_seq + 1 ? m->reply->seq - last_seq - 1 : 0;
    last_seq = m->reply->seq;
    /* skipped: the results the daemon did not send this client before this one (a slow reader of
     * per-frame results gets the newest); their seq numbers are in `lost` too. */
    printf ("result seq=%" G_GUINT64_FORMAT " set=%" G_GINT64_FORMAT " lost=%" G_GUINT64_FORMAT
            " skipped=%" G_GUINT64_FORMAT "\n",
            m->reply->seq, set_id, lost, m->reply->skipped);
    fflush (stdout);
    if (dir && (kinds & ~DS_FILES_HDF5_RUN) && !ds_ctl_write_result (m, dir, kinds, NULL, &error)) {
      fprintf (stderr, "descatterctl stream: writing %s: %s\n", dir, error->message);
      return close_run (run, 1);
    }
    if (dir && (kinds & DS_FILES_HDF5_RUN) && !append_to_run (&run, m, dir, &error)) {
      fprintf (stderr, "descatterctl stream: writing %s: %s\n", dir, error->message);
      return close_run (run, 1);
    }
    got++;
  }
  if (failed > 0) {
    if (count > 0)
      fprintf (stderr, "descatterctl stream: %" G_GINT64_FORMAT " of the %" G_GINT64_FORMAT " sets failed (the `failed` lines say why)\n",
               failed, count);
    else
      fprintf (stderr, "descatterctl stream: %" G_GINT64_FORMAT " sets failed (the `failed` lines say why)\n", failed);
  }
  return close_run (run, failed > 0 ? 1 : 0);
}
