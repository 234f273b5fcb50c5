/* `descatterctl status`: the daemon's status document as a summary a person reads at a glance
 * (--json: the document as the daemon sent it, for scripts). Members a daemon of another
 * version does not send are left out, never printed as zeros. */
#include <math.h>
#include <string.h>

#include "daemon/ctl/ctl_commands.h"
#include "daemon/ctl/ctl_progress.h"

static JsonObject *
member_object (JsonObject *o, const char *name)
{
  JsonNode *n = o ? json_object_get_member (o, name) : NULL;
  return n && JSON_NODE_HOLDS_OBJECT (n) ? json_node_get_object (n) : NULL;
}

static gboolean
has_number (JsonObject *o, const char *name)
{
  JsonNode *n = o ? json_object_get_member (o, name) : NULL;
  return n && JSON_NODE_HOLDS_VALUE (n) &&
         (json_node_get_value_type (n) == G_TYPE_INT64 || json_node_get_value_type (n) == G_TYPE_DOUBLE);
}

static gint64
int_of (JsonObject *o, const char *name)
{
  return o ? json_object_get_int_member_with_default (o, name, 0) : 0;
}

static const char *
str_of (JsonObject *o, const char *name)
{
  JsonNode *n = o ? json_object_get_member (o, name) : NULL;
  return n && JSON_NODE_HOLDS_VALUE (n) && json_node_get_value_type (n) == G_TYPE_STRING
             ? json_node_get_string (n)
             : NULL;
}

static gboolean
bool_of (JsonObject *o, const char *name)
{
  return o ? json_object_get_boolean_member_with_default (o, name, FALSE) : FALSE;
}

/* "by a set at 07:51:02 UTC (4 s ago), mean 12.3 DN over 1 frame at 5000 µs, 0 dB" */
static char *
describe_dark_frame (JsonObject *d)
{
  const char *taken = str_of (d, "taken_utc");
  g_autoptr (GDateTime) t = taken ? g_date_time_new_from_iso8601 (taken, NULL) : NULL;
  g_autofree char *when = t ? g_date_time_format (t, "%Y-%m-%d %H:%M:%S UTC") : g_strdup ("?");
  g_autofree char *mean = has_number (d, "mean_dn")
                              ? g_strdup_printf ("%.1f DN", json_object_get_double_member (d, "mean_dn"))
                              : g_strdup ("no finite level");
  gint64 frames = int_of (d, "frames");
  return g_strdup_printf ("%s at %s (%.0f s ago), mean %s over %" G_GINT64_FORMAT " frame%s at %g µs, %g dB",
                          g_strcmp0 (str_of (d, "source"), "set") == 0 ? "by a set" : "by the dark command", when,
                          has_number (d, "age_s") ? json_object_get_double_member (d, "age_s") : NAN, mean,
                          frames, frames == 1 ? "" : "s",
                          has_number (d, "exposure_us") ? json_object_get_double_member (d, "exposure_us") : NAN,
                          has_number (d, "gain_db") ? json_object_get_double_member (d, "gain_db") : NAN);
}

/* Which dark frame the next set subtracts, and the last one measured. A daemon without the
 * "dark" member says only whether it stores one. */
static void
print_dark (JsonObject *st)
{
  JsonObject *dark = member_object (st, "dark");
  if (!dark) {
    printf ("dark frame:   %s", bool_of (st, "has_dark") ? "stored (the dark command's)" : "none stored");
    return;
  }
  const char *mode = str_of (dark, "mode");
  JsonObject *last = member_object (dark, "last"), *stored = member_object (dark, "stored");
  if (g_strcmp0 (mode, "per-set") == 0)
    printf ("dark frame:   taken by every set (dark-frame on)");
  else if (g_strcmp0 (mode, "stored") == 0)
    printf ("dark frame:   the dark command's, subtracted from every set (dark-frame off)");
  else if (stored)
    printf ("dark frame:   NONE subtracted (dark-frame off; the stored one is for other exposure or gain)");
  else
    printf ("dark frame:   NONE subtracted (dark-frame off, no dark command run)");
  if (last) {
    g_autofree char *text = describe_dark_frame (last);
    printf ("\n              last %s", text);
  } else
    printf ("; none taken yet");
  if (stored && g_strcmp0 (str_of (last, "source"), "dark-command") != 0) {
    g_autofree char *text = describe_dark_frame (stored);
    printf ("\n              stored %s", text);
  }
}

static char *
format_bytes (double b)
{
  const char *units[] = { "B", "KiB", "MiB", "GiB", "TiB" };
  guint u = 0;
  while (b >= 1024 && u + 1 < G_N_ELEMENTS (units)) {
    b /= 1024;
    u++;
  }
  return u == 0 ? g_strdup_printf ("%.0f B", b) : g_strdup_printf ("%.1f %s", b, units[u]);
}

/* "stale 3, incomplete 1" for the non-zero members of an object of counts; "" for none. */
static char *
nonzero_counts (JsonObject *o)
{
  GString *s = g_string_new (NULL);
  if (o) {
    g_autoptr (GList) names = json_object_get_members (o);
    for (GList *l = names; l; l = l->next)
      if (int_of (o, l->data) > 0)
        g_string_append_printf (s, "%s%s %" G_GINT64_FORMAT, s->len ? ", " : "", (char *) l->data,
                                int_of (o, l->data));
  }
  return g_string_free (s, FALSE);
}

static void
print_summary (JsonObject *st)
{
  const char *version = str_of (st, "version"), *build = str_of (st, "git");
  printf ("descatterd %s", version ? version : "(version unknown)");
  if (build)
    printf (" (%s)", build);
  if (has_number (st, "uptime_s")) {
    g_autofree char *up = ds_ctl_format_duration (json_object_get_double_member (st, "uptime_s"));
    printf (", up %s", up);
  }
  printf ("\n");
  const char *state = str_of (st, "state");
  printf ("state:        %s, %s%s\n", state ? state : "?", bool_of (st, "ready") ? "ready" : "NOT ready",
          bool_of (st, "continuous") ? ", continuous acquisition on" : "");
  const char *why = str_of (st, "not_ready_reason");
  if (why && *why)
    printf ("              %s\n", why);
  JsonObject *pv = member_object (st, "preview");
  if (pv && bool_of (pv, "on")) {
    const char *light = str_of (pv, "light");
    printf ("preview:      light %s", light ? light : "?");
    if (has_number (pv, "phase"))
      printf (" (phase %" G_GINT64_FORMAT " of %" G_GINT64_FORMAT ")", int_of (pv, "phase"), int_of (pv, "phases"));
    printf (", %" G_GINT64_FORMAT " frames, %.1f fps\n", int_of (pv, "frames"),
            has_number (pv, "fps") ? json_object_get_double_member (pv, "fps") : 0.0);
  }
  printf ("sets:         %" G_GINT64_FORMAT " done, %" G_GINT64_FORMAT " failed, %" G_GINT64_FORMAT
          " cancelled, %" G_GINT64_FORMAT " waiting\n",
          int_of (st, "sets_done"), int_of (st, "sets_failed"), int_of (st, "sets_cancelled"), int_of (st, "pending"));
  const char *last_error = str_of (st, "last_error");
  if (last_error && *last_error)
    printf ("last error:   %s\n", last_error);

  JsonObject *dev = member_object (st, "devices");
  const char *backends = str_of (dev, "backends");
  if (backends)
    printf ("devices:      %s\n", backends);
  JsonObject *cam = member_object (dev, "camera");
  if (cam) {
    printf ("camera:       %s %s, serial %s, at %s, %" G_GINT64_FORMAT "x%" G_GINT64_FORMAT ", %s\n",
            str_of (cam, "vendor") ? str_of (cam, "vendor") : "?", str_of (cam, "model") ? str_of (cam, "model") : "?",
            str_of (cam, "serial") ? str_of (cam, "serial") : "?", str_of (cam, "address") ? str_of (cam, "address") : "?",
            int_of (cam, "width"), int_of (cam, "height"), bool_of (cam, "connected") ? "connected" : "DISCONNECTED");
    printf ("              %" G_GINT64_FORMAT " frames, %" G_GINT64_FORMAT " failures, %" G_GINT64_FORMAT
            " missing packets, %" G_GINT64_FORMAT " timeouts, %" G_GINT64_FORMAT " reconnects\n",
            int_of (cam, "completed"), int_of (cam, "failures"), int_of (cam, "missing_packets"),
            int_of (cam, "timeouts"), int_of (cam, "reconnects"));
  }
  /* What captures without their own exposure and gain take (`descatterctl set` changes it). */
  JsonObject *live = member_object (st, "camera");
  JsonObject *roi = member_object (live, "roi");
  if (live && roi)
    printf ("settings:     exposure %g µs, gain %g dB, region %" G_GINT64_FORMAT ",%" G_GINT64_FORMAT " %" G_GINT64_FORMAT
            "x%" G_GINT64_FORMAT "\n",
            json_object_get_double_member_with_default (live, "exposure_us", 0),
            json_object_get_double_member_with_default (live, "gain_db", 0), int_of (roi, "x"), int_of (roi, "y"),
            int_of (roi, "width"), int_of (roi, "height"));
  JsonObject *ill = member_object (dev, "illuminator");
  if (ill) {
    printf ("illuminator:  %s%s%s, ", bool_of (ill, "ready") ? "ready" : "NOT ready",
            bool_of (ill, "fault") ? ", FAULT" : "", bool_of (ill, "over_temperature") ? ", OVER TEMPERATURE" : "");
    if (int_of (ill, "applied_phase") >= 0)
      printf ("phase %" G_GINT64_FORMAT " lit", int_of (ill, "applied_phase"));
    else
      printf ("no phase lit");
    printf (", %" G_GINT64_FORMAT " phase changes", int_of (ill, "apply_count"));
    if (has_number (ill, "temperature_c"))
      printf (", %.1f °C", json_object_get_double_member (ill, "temperature_c"));
    printf ("\n");
    if (int_of (ill, "failed_attempts") > 0)
      printf ("              link: %" G_GINT64_FORMAT " failed attempts, %" G_GINT64_FORMAT
              " accesses failed after retries; last: %s\n",
              int_of (ill, "failed_attempts"), int_of (ill, "failed_accesses"),
              str_of (ill, "last_link_problem") ? str_of (ill, "last_link_problem") : "?");
  }

  JsonObject *fr = member_object (st, "frames");
  if (fr) {
    g_autofree char *drops = nonzero_counts (member_object (fr, "dropped_by_reason"));
    printf ("frames:       %" G_GINT64_FORMAT " acquired, %" G_GINT64_FORMAT " folded, %" G_GINT64_FORMAT
            " dropped%s%s%s, %" G_GINT64_FORMAT " retries\n",
            int_of (fr, "acquired"), int_of (fr, "folded"), int_of (fr, "dropped"), *drops ? " (" : "",
            drops, *drops ? ")" : "", int_of (fr, "retries"));
  }
  JsonObject *stages = member_object (st, "stage_mean_ms");
  if (stages && has_number (stages, "set")) {
    printf ("mean times:   set %.1f ms", json_object_get_double_member (stages, "set"));
    g_autoptr (GList) names = json_object_get_members (stages);
    const char *sep = " (";
    for (GList *l = names; l; l = l->next)
      if (strcmp (l->data, "set") != 0 && has_number (stages, l->data)) {
        printf ("%s%s %.2f", sep, (char *) l->data, json_object_get_double_member (stages, l->data));
        sep = ", ";
      }
    printf ("%s\n", strcmp (sep, ", ") == 0 ? ")" : "");
  }
  print_dark (st);
  if (has_number (st, "phase_offset_cycles"))
    printf ("; stripe phase offset %.3f cycles", json_object_get_double_member (st, "phase_offset_cycles"));
  printf ("\n");

  JsonObject *model = member_object (st, "operating_model");
  if (model) {
    if (bool_of (model, "loaded"))
      printf ("auto point:   operating model %s\n", str_of (model, "path") ? str_of (model, "path") : "loaded");
    else
      printf ("auto point:   UNAVAILABLE (--target-error/--time-budget-ms are refused): %s\n",
              str_of (model, "error") ? str_of (model, "error") : "no operating model");
  }
  JsonObject *cl = member_object (st, "clients");
  if (cl)
    printf ("clients:      %" G_GINT64_FORMAT " connected, %" G_GINT64_FORMAT " subscribed; %" G_GINT64_FORMAT
            " requests (%" G_GINT64_FORMAT " answered with an error); %" G_GINT64_FORMAT " results published, %" G_GINT64_FORMAT
            " dropped for slow readers\n",
            int_of (cl, "connected"), int_of (cl, "subscribers"), int_of (cl, "requests"),
            int_of (cl, "bad_requests"), int_of (cl, "results_published"), int_of (cl, "results_dropped"));
  JsonObject *spool = member_object (st, "spool");
  if (spool) {
    g_autofree char *bytes = format_bytes ((double) int_of (spool, "bytes"));
    printf ("spool:        %s, %" G_GINT64_FORMAT " sets removed for space, %" G_GINT64_FORMAT " errors\n", bytes,
            int_of (spool, "sets_removed"), int_of (spool, "errors"));
  }
}

int
ds_ctl_status (const DsCtlTarget *target, int argc, char **argv)
{
  gboolean json = FALSE;
  GOptionEntry entries[] = {
    { "json", 'j', 0, G_OPTION_ARG_NONE, &json, "Print the status document as the daemon sends it", NULL },
    { NULL },
  };
  if (!ds_ctl_parse_options (&argc, &argv, entries,
                             "Prints the daemon's state, devices, frame counters, timings and clients."))
    return 2;
  g_autoptr (DsClient) c = ds_ctl_connect (target, "status");
  if (!c)
    return 1;
  g_autoptr (DsMessage) m = ds_ctl_call (c, "status", NULL, NULL, NULL);
  if (!m)
    return 1;
  if (json)
    ds_ctl_print_json (m->reply->body);
  else if (m->reply->body && JSON_NODE_HOLDS_OBJECT (m->reply->body))
    print_summary (json_node_get_object (m->reply->body));
  else {
    fprintf (stderr, "descatterctl status: the daemon's status is not an object\n");
    return 1;
  }
  return 0;
}
