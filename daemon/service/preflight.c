#include "daemon/service/preflight.h"

#include <errno.h>
#include <gio/gio.h>
#include <glib/gstdio.h>
#include <string.h>
#include <sys/stat.h>

#include "daemon/operating/data_dir.h"
#include "drivers/gpio/gpio_lines.h"
#include "drivers/modbus/modbus_illuminator.h"
#include "drivers/sim/render_cost.h"
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

/* What start's spool does (spool.c: g_mkdir_with_parents, then files written inside), tried
 * and undone: the missing folders are created and removed again, and a folder that exists
 * gets a folder created and removed inside it. Permissions, a read-only file system or a
 * regular file on the way all refuse here as they would at start. */
static gboolean
check_spool_dir (const char *dir, GError **error)
{
  if (g_file_test (dir, G_FILE_TEST_EXISTS)) {
    if (!g_file_test (dir, G_FILE_TEST_IS_DIR))
      return refuse (error, "[daemon] spool-dir = \"%s\" exists and is not a directory", dir);
    g_autofree char *probe = g_build_filename (dir, ".descatterd-check-XXXXXX", NULL);
    if (!g_mkdtemp (probe)) {
      int e = errno;
      return refuse (error, "[daemon] spool-dir = \"%s\": cannot write in it: %s", dir, g_strerror (e));
    }
    g_rmdir (probe);
    return TRUE;
  }
  g_autoptr (GPtrArray) missing = g_ptr_array_new_with_free_func (g_free);
  g_autofree char *p = g_strdup (dir);
  while (!g_file_test (p, G_FILE_TEST_EXISTS)) {
    g_ptr_array_add (missing, g_strdup (p));
    char *parent = g_path_get_dirname (p);
    gboolean top = strcmp (parent, p) == 0;
    g_free (p);
    p = parent;
    if (top)
      break;
  }
  g_autoptr (GPtrArray) made = g_ptr_array_new ();
  int e = 0;
  const char *failed = NULL;
  for (guint i = missing->len; !failed && i-- > 0;) {
    if (g_mkdir (missing->pdata[i], 0750) == 0)
      g_ptr_array_add (made, missing->pdata[i]);
    else {
      e = errno;
      failed = missing->pdata[i];
    }
  }
  for (guint k = made->len; k-- > 0;) /* undone deepest first */
    g_rmdir (made->pdata[k]);
  if (failed)
    return refuse (error, "[daemon] spool-dir = \"%s\" cannot be created: %s: %s", dir, failed, g_strerror (e));
  return TRUE;
}

typedef struct {
  const char *where, *text;
  const char *host;
  guint16 port;
} Listener;

/* Two listeners on one port collide when their hosts are equal or either is the wildcard; a
 * port of 0 is the kernel's choice and never collides. */
static gboolean
listeners_collide (const Listener *a, const Listener *b)
{
  if (a->port == 0 || a->port != b->port)
    return FALSE;
  g_autoptr (GInetAddress) ia = g_inet_address_new_from_string (a->host);
  g_autoptr (GInetAddress) ib = g_inet_address_new_from_string (b->host);
  return g_inet_address_equal (ia, ib) || g_inet_address_get_is_any (ia) || g_inet_address_get_is_any (ib);
}

/* Binds the address as the server will (GSocketListener: SO_REUSEADDR) and closes it again,
 * so that a port held by another program refuses here and not after the socket file exists. */
static gboolean
test_bind (const Listener *l, GError **error)
{
  if (l->port == 0)
    return TRUE;
  g_autoptr (GInetAddress) ia = g_inet_address_new_from_string (l->host);
  g_autoptr (GSocketAddress) sa = g_inet_socket_address_new (ia, l->port);
  g_autoptr (GError) e = NULL;
  g_autoptr (GSocket) sock = g_socket_new (g_inet_address_get_family (ia), G_SOCKET_TYPE_STREAM,
                                           G_SOCKET_PROTOCOL_TCP, &e);
  if (!sock || !g_socket_bind (sock, sa, TRUE, &e) || !g_socket_listen (sock, &e))
    return refuse (error, "%s \"%s\": cannot listen there: %s", l->where, l->text, e->message);
  g_socket_close (sock, NULL);
  return TRUE;
}

static gboolean
check_listeners (const DsPreflight *pf, const char *tcp_where, const char *tcp, const char *http_where,
                 const char *http, gboolean running, GError **error)
{
  Listener ls[2];
  guint n = 0;
  if (pf->tcp_host)
    ls[n++] = (Listener) { tcp_where, tcp, pf->tcp_host, pf->tcp_port };
  if (pf->http_host)
    ls[n++] = (Listener) { http_where, http, pf->http_host, pf->http_port };
  if (n == 2 && listeners_collide (&ls[0], &ls[1]))
    return refuse (error, "%s \"%s\" and %s \"%s\" are the same address; give each its own port", ls[0].where,
                   ls[0].text, ls[1].where, ls[1].text);
  for (guint i = 0; !running && i < n; i++)
    if (!test_bind (&ls[i], error))
      return FALSE;
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
  if (!check_listeners (pf, ov && ov->tcp_listen ? "--tcp" : "[daemon] tcp-listen", tcp,
                        ov && ov->http_listen ? "--http" : "[http] listen", http, ov && ov->running, error))
    return FALSE;
  if (c->spool_dir && *c->spool_dir && !check_spool_dir (c->spool_dir, error))
    return FALSE;
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
      if (!scene || !ds_scene_check_files (scene, &e) || !ds_render_cost_check (scene, &e)) {
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
