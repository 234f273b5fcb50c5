/* descatterctl set: the open camera's exposure, gain and region, live (docs/protocol.md, `set`). */
#include <string.h>

#include "daemon/ctl/ctl_commands.h"
#include "daemon/ctl/ctl_output.h"

/* "x,y,width,height" into the request's "roi"; FALSE with a message naming the option. */
static gboolean
roi_arg (JsonObject *args, const char *text)
{
  if (!text)
    return TRUE;
  g_auto (GStrv) parts = g_strsplit (text, ",", -1);
  static const char *const keys[] = { "x", "y", "width", "height" };
  if (g_strv_length (parts) != G_N_ELEMENTS (keys)) {
    fprintf (stderr, "descatterctl set: --roi \"%s\": give x,y,width,height (pixels on the sensor)\n", text);
    return FALSE;
  }
  g_autoptr (JsonObject) roi = json_object_new ();
  for (guint i = 0; i < G_N_ELEMENTS (keys); i++) {
    char *end = NULL;
    const char *p = g_strstrip (parts[i]);
    guint64 v = g_ascii_strtoull (p, &end, 10);
    if (!*p || *end || *p == '-' || v > 65535) {
      fprintf (stderr, "descatterctl set: --roi \"%s\": %s \"%s\" is not a whole number 0..65535\n", text, keys[i],
               p);
      return FALSE;
    }
    json_object_set_int_member (roi, keys[i], (gint64) v);
  }
  json_object_set_object_member (args, "roi", json_object_ref (roi));
  return TRUE;
}

static void
print_camera (JsonObject *body)
{
  JsonObject *cam = json_object_get_object_member (body, "camera");
  JsonObject *roi = cam ? json_object_get_object_member (cam, "roi") : NULL;
  if (!cam || !roi)
    return;
  printf ("camera: exposure %g µs, gain %g dB, region %" G_GINT64_FORMAT ",%" G_GINT64_FORMAT " %" G_GINT64_FORMAT
          "x%" G_GINT64_FORMAT "; captures without their own exposure and gain use these\n",
          json_object_get_double_member_with_default (cam, "exposure_us", 0),
          json_object_get_double_member_with_default (cam, "gain_db", 0),
          json_object_get_int_member_with_default (roi, "x", 0), json_object_get_int_member_with_default (roi, "y", 0),
          json_object_get_int_member_with_default (roi, "width", 0),
          json_object_get_int_member_with_default (roi, "height", 0));
}

int
ds_ctl_set (const DsCtlTarget *target, int argc, char **argv)
{
  g_autofree char *exposure = NULL, *gain = NULL, *roi = NULL;
  gboolean json = FALSE;
  GOptionEntry entries[] = {
    DS_CTL_JSON_ENTRY (json),
    { "exposure-us", 'e', 0, G_OPTION_ARG_STRING, &exposure, "Exposure (µs, within the camera's range)", "E" },
    { "gain-db", 'g', 0, G_OPTION_ARG_STRING, &gain, "Gain (dB, within the camera's range)", "G" },
    { "roi", 0, 0, G_OPTION_ARG_STRING, &roi, "Region of the sensor: x,y,width,height (pixels)", "X,Y,W,H" },
    { NULL },
  };
  if (!ds_ctl_parse_options (&argc, &argv, entries,
                             "Changes the open camera's exposure, gain or region between two sets; they stay the "
                             "defaults of later captures (a capture's own exposure and gain still win) until "
                             "the daemon restarts. `descatterctl status` shows them and the camera's ranges."))
    return 2;
  g_autoptr (JsonObject) args = json_object_new ();
  if (!ds_ctl_args_double (args, "set", "exposure-us", "exposure_us", exposure) ||
      !ds_ctl_args_double (args, "set", "gain-db", "gain_db", gain) || !roi_arg (args, roi))
    return 2;
  if (json_object_get_size (args) == 0) {
    fprintf (stderr, "descatterctl set: nothing to set: give --exposure-us, --gain-db or --roi\n");
    return 2;
  }
  g_autoptr (DsClient) c = ds_ctl_connect (target, "set");
  if (!c)
    return 1;
  g_autoptr (DsMessage) m = ds_ctl_call (c, "set", args, NULL, NULL);
  if (!m)
    return 1;
  ds_ctl_print_reply (m->reply->body, json, print_camera);
  return 0;
}
