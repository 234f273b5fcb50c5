#include "daemon/service/preflight.h"

#include <errno.h>
#include <gio/gio.h>
#include <glib/gstdio.h>
#include <string.h>
#include <sys/stat.h>

#include "daemon/operating/data_dir.h"
#include "drivers/gpio/gpio_lines.h"
#include "drivers/modbus/modbus_illuminator.h"
#include "drivers/sim/scene.h"
#include "drivers/simdev/sim_lab.h"

#define MAX_TOKEN_BYTES 1024

static gboolean
refuse (GError **error, const char *fmt, ...) G_GNUC_PRINTF (2, 3);

static gboolean
refuse (GError **error, const char *fmt, ...)
{
  va_list ap;
  va_start (ap, fmt);
  g_autofree char *msg = g_strdup_vprintf (fmt, ap);
  va_end (ap);
  g_set_error_literal (error, DS_CONFIG_ERROR, DS_CONFIG_ERROR_BAD_VALUE, msg);
  return FALSE;
}

/* Wraps a driver's own parse error (its message names the part that is wrong). */
static gboolean
refuse_with (GError **error, GError *cause, const char *where)
{
  g_set_error (error, DS_CONFIG_ERROR, DS_CONFIG_ERROR_BAD_VALUE, "%s: %s", where, cause->message);
  g_error_free (cause);
  return FALSE;
}

static gboolean
read_token (const char *path, const char *key, char **token, GError **error)
{
  g_autofree char *text = NULL;
  gsize len = 0;
  GError *e = NULL;
  GStatBuf st;
  if (g_stat (path, &st) == 0 && (!S_ISREG (st.st_mode) || st.st_size > MAX_TOKEN_BYTES))
    return refuse (error, "%s = \"%s\": not a regular file of at most %d bytes", key, path, MAX_TOKEN_BYTES);
  if (!g_file_get_contents (path, &text, &len, &e))
    return refuse_with (error, e, key);
  if (memchr (text, '\0', len) || !g_utf8_validate (text, (gssize) len, NULL))
    return refuse (error, "%s = \"%s\": the token must be UTF-8 text", key, path);
  g_strstrip (text);
  if (g_utf8_strlen (text, -1) < 16)
    return refuse (error, "%s = \"%s\": the token must be at least 16 characters (has %ld)", key, path,
                   g_utf8_strlen (text, -1));
  *token = g_steal_pointer (&text);
  return TRUE;
}

static gboolean
check_socket_path (const char *path, const char *where, GError **error)
{
  if (strlen (path) >= DS_CONFIG_MAX_SOCKET_PATH)
    return refuse (error, "%s \"%s\": %zu bytes, a UNIX socket path has at most %d", where, path, strlen (path),
                   DS_CONFIG_MAX_SOCKET_PATH - 1);
  GStatBuf st;
  if (g_lstat (path, &st) == 0 && !S_ISSOCK (st.st_mode))
    return refuse (error, "%s \"%s\" exists and is not a socket; it is never replaced", where, path);
  return TRUE;
}

/* An IP:PORT to listen on (TCP clients, the live view and /metrics); a non-loopback address
 * needs a token (token_key: where it is configured). *host and *port are set only when the
 * address is accepted. */
static gboolean
check_listen (const char *listen, const char *where, gboolean has_token, const char *token_key, char **host,
              guint16 *port, GError **error)
{
  g_autofree char *h = NULL;
  guint16 p = 0;
  if (!ds_config_parse_host_port (listen, &h, &p))
    return refuse (error, "%s \"%s\": expected IP:PORT (a numeric address, port 0..65535)", where, listen);
  g_autoptr (GInetAddress) ia = g_inet_address_new_from_string (h);
  if (!ia)
    return refuse (error, "%s \"%s\": %s is not an IP address", where, listen, h);
  if (!g_inet_address_get_is_loopback (ia) && !has_token)
    return refuse (error, "%s \"%s\" is not loopback: it requires %s", where, listen, token_key);
  *host = g_steal_pointer (&h);
  *port = p;
  return TRUE;
}

static gboolean
check_gpio (const DsConfig *c, GError **error)
{
  guint offsets[DS_GPIO_MAX_LINES];
  guint n = 0;
  GError *e = NULL;
  if (!ds_gpio_parse_offsets (c->gpio_lines, offsets, &n, &e))
    return refuse_with (error, e, "[illuminator] gpio-lines");
  for (guint i = 0; i < n; i++) {
    for (guint j = 0; j < i; j++)
      if (offsets[i] == offsets[j])
        return refuse (error, "[illuminator] gpio-lines = \"%s\": line %u is listed twice", c->gpio_lines,
                       offsets[i]);
    if (c->gpio_enable_line >= 0 && offsets[i] == (guint) c->gpio_enable_line)
      return refuse (error, "[illuminator] gpio-enable-line = %d is also one of gpio-lines", c->gpio_enable_line);
    if (strcmp (c->trigger_backend, "gpio") == 0 && offsets[i] == (guint) c->trigger_gpio_line)
      return refuse (error, "[trigger] gpio-line = %d is also one of [illuminator] gpio-lines", c->trigger_gpio_line);
  }
  return TRUE;
}

static gboolean
check_model (DsPreflight *pf, const DsConfig *c, GError **error)
{
  gboolean configured = c->operating_model && *c->operating_model;
  pf->model_path = configured ? g_strdup (c->operating_model) : ds_data_path ("operating-model.conf");
  GError *e = NULL;
  pf->model = ds_operating_model_load (pf->model_path, &e);
  if (pf->model)
    return TRUE;
  /* A model named in the file must be usable; the built-in one missing only turns automatic
   * captures off (a build tree without its data, say). */
  if (configured)
    return refuse_with (error, e, "[acquisition] operating-model");
  pf->model_note = g_strdup (e->message);
  g_error_free (e);
  return TRUE;
}

static gboolean
run_checks (DsPreflight *pf, const DsConfig *config, const DsPreflightOverrides *ov, GError **error)
{
  DsConfig *c = pf->config = ds_config_copy (config);
  if (ov && ov->scene_path) {
    g_free (c->sim_scene);
    c->sim_scene = g_canonicalize_filename (ov->scene_path, NULL);
  }
  if (ov && ov->socket_path) {
    g_free (c->socket_path);
    c->socket_path = g_canonicalize_filename (ov->socket_path, NULL);
  }
  if (!check_socket_path (c->socket_path, ov && ov->socket_path ? "--socket" : "[daemon] socket", error))
    return FALSE;
  if (c->tcp_token_file && !read_token (c->tcp_token_file, "[daemon] tcp-token-file", &pf->token, error))
    return FALSE;
  const char *tcp = ov && ov->tcp_listen ? ov->tcp_listen : c->tcp_listen;
  if (tcp && *tcp &&
      !check_listen (tcp, ov && ov->tcp_listen ? "--tcp" : "[daemon] tcp-listen", pf->token != NULL,
                     "[daemon] tcp-token-file", &pf->tcp_host, &pf->tcp_port, error))
    return FALSE;
  if (c->http_token_file && !read_token (c->http_token_file, "[http] token-file", &pf->http_token, error))
    return FALSE;
  const char *http = ov && ov->http_listen ? ov->http_listen : c->http_listen;
  if (http && *http &&
      !check_listen (http, ov && ov->http_listen ? "--http" : "[http] listen", pf->http_token != NULL,
                     "[http] token-file", &pf->http_host, &pf->http_port, error))
    return FALSE;
  if (c->spool_dir && g_file_test (c->spool_dir, G_FILE_TEST_EXISTS) &&
      !g_file_test (c->spool_dir, G_FILE_TEST_IS_DIR)) {
    refuse (error, "[daemon] spool-dir = \"%s\" exists and is not a directory", c->spool_dir);
    return FALSE;
  }
  GError *e = NULL;
  if (strcmp (c->illuminator_backend, "modbus") == 0) {
    DsModbusUri uri;
    if (!ds_modbus_uri_parse (c->modbus_uri, &uri, &e)) {
      refuse_with (error, e, "[illuminator] modbus-uri");
      return FALSE;
    }
  }
  if ((strcmp (c->illuminator_backend, "gpio") == 0 || strcmp (c->trigger_backend, "gpio") == 0) &&
      c->gpio_lines && !check_gpio (c, error))
    return FALSE;
  if (strcmp (c->camera_backend, "sim") == 0) {
    DsSimFaults faults;
    if (!ds_sim_faults_parse (c->sim_faults, &faults, &e)) {
      refuse_with (error, e, "[sim] faults");
      return FALSE;
    }
    if (c->sim_scene) {
      g_autoptr (DsScene) scene = ds_scene_load (c->sim_scene, &e);
      if (!scene) {
        refuse_with (error, e, ov && ov->scene_path ? "--scene" : "[sim] scene");
        return FALSE;
      }
    }
  }
  return check_model (pf, c, error);
}

DsPreflight *
ds_preflight_run (const DsConfig *config, const DsPreflightOverrides *ov, GError **error)
{
  g_autoptr (DsPreflight) pf = g_new0 (DsPreflight, 1);
  if (!run_checks (pf, config, ov, error)) {
    if (ov && ov->config_name)
      g_prefix_error (error, "%s: ", ov->config_name);
    return NULL;
  }
  return g_steal_pointer (&pf);
}

void
ds_preflight_free (DsPreflight *pf)
{
  if (!pf)
    return;
  ds_config_free (pf->config);
  g_free (pf->token);
  g_free (pf->http_token);
  g_free (pf->http_host);
  g_free (pf->tcp_host);
  g_clear_pointer (&pf->model, ds_operating_model_free);
  g_free (pf->model_path);
  g_free (pf->model_note);
  g_free (pf);
}
