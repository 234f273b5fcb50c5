/* The values of the configuration that are more than one number (config.h): a region of the
 * sensor, a host and port, the pixel format the camera delivers. Pure functions, any thread. */
#include "daemon/config/config.h"

#include <string.h>

gboolean
ds_config_parse_roi (const char *roi, guint v[4], GError **error)
{
  g_auto (GStrv) parts = roi ? g_strsplit (roi, ",", -1) : NULL;
  gboolean ok = parts && g_strv_length (parts) == 4;
  for (guint i = 0; ok && i < 4; i++) {
    guint64 n = 0;
    ok = g_ascii_string_to_unsigned (g_strstrip (parts[i]), 10, 0, 65535, &n, NULL) && (i < 2 || n > 0);
    v[i] = (guint) n;
  }
  if (!ok)
    g_set_error (error, DS_CONFIG_ERROR, DS_CONFIG_ERROR_BAD_VALUE,
                 "[camera] roi = \"%s\": expected x,y,width,height (four integers 0..65535, width and "
                 "height above 0), or empty for the full sensor", roi ? roi : "");
  return ok;
}

gboolean
ds_config_parse_host_port (const char *text, char **host, guint16 *port)
{
  const char *colon = text ? strrchr (text, ':') : NULL;
  guint64 p = 0;
  if (!colon || colon == text || !g_ascii_string_to_unsigned (colon + 1, 10, 0, 65535, &p, NULL))
    return FALSE;
  g_autofree char *h = g_strndup (text, (gsize) (colon - text));
  /* [::1]:7420 as well as 127.0.0.1:7420 */
  if (h[0] == '[' && h[strlen (h) - 1] == ']') {
    char *inner = g_strndup (h + 1, strlen (h) - 2);
    g_free (h);
    h = inner;
  }
  if (!g_hostname_is_ip_address (h))
    return FALSE;
  if (port)
    *port = (guint16) p;
  if (host)
    *host = g_steal_pointer (&h);
  return TRUE;
}

const char *
ds_config_camera_pixel_format (const DsConfig *config)
{
  return strcmp (config->camera_backend, "sim") == 0 ? "simulated" : config->pixel_format;
}
