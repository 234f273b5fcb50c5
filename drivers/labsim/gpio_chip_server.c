#include "drivers/labsim/gpio_chip_server.h"

#include <errno.h>
#include <fcntl.h>
#include <poll.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <unistd.h>

#include "drivers/gpio/gpio_wire.h"

typedef struct {
  int fd;                  /* -1: free slot */
  guint id;                /* owner tag of its lines, never 0 */
  char buf[DS_GPIO_WIRE_MAX_LINE];
  gsize len;
  gboolean requested;
  guint n;
  guint offsets[DS_GPIO_CHIP_SERVER_MAX_LINES];
  char consumer[64];
} Client;

struct DsGpioChipServer {
  char *path, *label;
  guint n_lines;
  DsGpioChipEdgeFunc edge;
  gpointer edge_data;
  int listen_fd;
  int stop_pipe[2];
  GThread *thread;
  GMutex lock;             /* levels and stats: read from other threads */
  int level[DS_GPIO_CHIP_SERVER_MAX_LINES];
  guint owner[DS_GPIO_CHIP_SERVER_MAX_LINES]; /* client id, 0: free; chip thread only */
  DsGpioChipStats stats;
  Client clients[DS_GPIO_CHIP_SERVER_MAX_CLIENTS];
  guint next_id;
};

/* Drives a line; the edge is reported on a change only, as a wire would carry it. */
static void
drive (DsGpioChipServer *s, guint offset, int value)
{
  g_mutex_lock (&s->lock);
  gboolean changed = s->level[offset] != value;
  s->level[offset] = value;
  if (changed)
    s->stats.edges++;
  g_mutex_unlock (&s->lock);
  if (changed && s->edge)
    s->edge (s->edge_data, offset, value == 1);
}

static void
client_close (DsGpioChipServer *s, Client *c)
{
  /* Released lines keep their level (a released output is not driven anywhere else). */
  for (guint i = 0; i < s->n_lines; i++)
    if (s->owner[i] == c->id)
      s->owner[i] = 0;
  close (c->fd);
  c->fd = -1;
  c->requested = FALSE;
}

/* A client that does not read its replies is dropped rather than allowed to block the chip. */
static gboolean
reply (Client *c, const char *fmt, ...) G_GNUC_PRINTF (2, 3);
static gboolean
reply (Client *c, const char *fmt, ...)
{
  va_list ap;
  va_start (ap, fmt);
  g_autofree char *body = g_strdup_vprintf (fmt, ap);
  va_end (ap);
  g_autofree char *line = g_strdup_printf ("%s\n", body);
  gsize len = strlen (line);
  return send (c->fd, line, len, MSG_NOSIGNAL | MSG_DONTWAIT) == (gssize) len;
}

static gboolean
refuse (DsGpioChipServer *s, Client *c, const char *code, const char *fmt, ...) G_GNUC_PRINTF (4, 5);
static gboolean
refuse (DsGpioChipServer *s, Client *c, const char *code, const char *fmt, ...)
{
  va_list ap;
  va_start (ap, fmt);
  g_autofree char *msg = g_strdup_vprintf (fmt, ap);
  va_end (ap);
  g_mutex_lock (&s->lock);
  s->stats.refused++;
  g_mutex_unlock (&s->lock);
  return reply (c, "err %s %s", code, msg);
}

/* "1,0,1" or "3,4": n numbers each <= max. FALSE names nothing: the caller says which list. */
static gboolean
parse_list (const char *text, guint max, guint *out, guint *n)
{
  g_auto (GStrv) parts = g_strsplit (text, ",", -1);
  *n = 0;
  for (guint i = 0; parts[i]; i++) {
    guint64 v;
    if (*n == DS_GPIO_CHIP_SERVER_MAX_LINES || !g_ascii_string_to_unsigned (parts[i], 10, 0, max, &v, NULL))
      return FALSE;
    out[(*n)++] = (guint) v;
  }
  return *n > 0;
}

static gboolean
do_request (DsGpioChipServer *s, Client *c, char **tok, guint ntok)
{
  guint offsets[DS_GPIO_CHIP_SERVER_MAX_LINES], values[DS_GPIO_CHIP_SERVER_MAX_LINES], n, nv;
  if (c->requested)
    return refuse (s, c, DS_GPIO_WIRE_ERR_STATE, "this connection already holds lines: one request per connection");
  if (ntok != 4 || strlen (tok[1]) >= sizeof c->consumer)
    return refuse (s, c, DS_GPIO_WIRE_ERR_INVALID, "expected: request CONSUMER OFF[,OFF...] VAL[,VAL...] "
                   "(consumer below %zu characters)", sizeof c->consumer);
  if (!parse_list (tok[2], 100000, offsets, &n))
    return refuse (s, c, DS_GPIO_WIRE_ERR_INVALID, "offsets \"%.64s\": expected up to %d numbers separated by commas",
                   tok[2], DS_GPIO_CHIP_SERVER_MAX_LINES);
  if (!parse_list (tok[3], 1, values, &nv) || nv != n)
    return refuse (s, c, DS_GPIO_WIRE_ERR_INVALID, "values \"%.64s\": expected %u of 0 or 1", tok[3], n);
  for (guint i = 0; i < n; i++) {
    if (offsets[i] >= s->n_lines)
      return refuse (s, c, DS_GPIO_WIRE_ERR_RANGE, "line %u beyond the chip's %u lines", offsets[i], s->n_lines);
    for (guint j = 0; j < i; j++)
      if (offsets[j] == offsets[i])
        return refuse (s, c, DS_GPIO_WIRE_ERR_INVALID, "line %u requested twice", offsets[i]);
    if (s->owner[offsets[i]]) {
      const char *holder = "another consumer";
      for (guint k = 0; k < DS_GPIO_CHIP_SERVER_MAX_CLIENTS; k++)
        if (s->clients[k].fd >= 0 && s->clients[k].id == s->owner[offsets[i]])
          holder = s->clients[k].consumer;
      return refuse (s, c, DS_GPIO_WIRE_ERR_BUSY, "line %u is busy: held by \"%s\"", offsets[i], holder);
    }
  }
  g_strlcpy (c->consumer, tok[1], sizeof c->consumer);
  c->n = n;
  memcpy (c->offsets, offsets, n * sizeof *offsets);
  c->requested = TRUE;
  for (guint i = 0; i < n; i++)
    s->owner[offsets[i]] = c->id;
  for (guint i = 0; i < n; i++)
    drive (s, offsets[i], (int) values[i]);
  g_mutex_lock (&s->lock);
  s->stats.requests_ok++;
  g_mutex_unlock (&s->lock);
  return reply (c, "ok %u", s->n_lines);
}

static gboolean
do_set (DsGpioChipServer *s, Client *c, char **tok, guint ntok)
{
  guint values[DS_GPIO_CHIP_SERVER_MAX_LINES], nv;
  if (!c->requested)
    return refuse (s, c, DS_GPIO_WIRE_ERR_STATE, "set before request: no lines held");
  if (ntok != 2 || !parse_list (tok[1], 1, values, &nv) || nv != c->n)
    return refuse (s, c, DS_GPIO_WIRE_ERR_INVALID, "expected: set VAL[,VAL...] with %u values of 0 or 1", c->n);
  for (guint i = 0; i < c->n; i++)
    drive (s, c->offsets[i], (int) values[i]);
  return reply (c, "ok");
}

static gboolean
do_get (DsGpioChipServer *s, Client *c, guint ntok)
{
  if (!c->requested)
    return refuse (s, c, DS_GPIO_WIRE_ERR_STATE, "get before request: no lines held");
  if (ntok != 1)
    return refuse (s, c, DS_GPIO_WIRE_ERR_INVALID, "expected: get");
  g_autoptr (GString) out = g_string_new ("ok ");
  for (guint i = 0; i < c->n; i++)
    g_string_append_printf (out, "%s%d", i ? "," : "", ds_gpio_chip_server_level (s, c->offsets[i]));
  return reply (c, "%s", out->str);
}

/* FALSE: the connection is to be closed. */
static gboolean
handle_line (DsGpioChipServer *s, Client *c, char *line)
{
  g_auto (GStrv) tok = g_strsplit (line, " ", 8);
  guint ntok = g_strv_length (tok);
  if (ntok == 0 || !*tok[0])
    return refuse (s, c, DS_GPIO_WIRE_ERR_INVALID, "empty request: expected request, set, get or info");
  for (const char *p = line; *p; p++)
    if (!g_ascii_isprint (*p))
      return refuse (s, c, DS_GPIO_WIRE_ERR_INVALID, "byte 0x%02x at %td: requests are printable ASCII",
                     (guchar) *p, p - line);
  if (strcmp (tok[0], "request") == 0)
    return do_request (s, c, tok, ntok);
  if (strcmp (tok[0], "set") == 0)
    return do_set (s, c, tok, ntok);
  if (strcmp (tok[0], "get") == 0)
    return do_get (s, c, ntok);
  if (strcmp (tok[0], "info") == 0 && ntok == 1)
    return reply (c, "ok lines=%u label=%s", s->n_lines, s->label);
  return refuse (s, c, DS_GPIO_WIRE_ERR_INVALID, "unknown request \"%.32s\": expected request, set, get or info",
                 tok[0]);
}

static void
client_readable (DsGpioChipServer *s, Client *c)
{
  gssize r = recv (c->fd, c->buf + c->len, sizeof c->buf - c->len, 0);
  if (r <= 0) {
    client_close (s, c);
    return;
  }
  c->len += (gsize) r;
  char *nl;
  while (c->fd >= 0 && (nl = memchr (c->buf, '\n', c->len))) {
    *nl = '\0';
    gsize used = (gsize) (nl - c->buf) + 1;
    /* A NUL inside the line ends the C string early: refuse it rather than act on a prefix. */
    gboolean ok = strlen (c->buf) + 1 == used
                      ? handle_line (s, c, c->buf)
                      : refuse (s, c, DS_GPIO_WIRE_ERR_INVALID, "NUL byte in a request");
    memmove (c->buf, c->buf + used, c->len - used);
    c->len -= used;
    if (!ok)
      client_close (s, c);
  }
  if (c->fd >= 0 && c->len == sizeof c->buf) {
    refuse (s, c, DS_GPIO_WIRE_ERR_INVALID, "request longer than %d bytes: closing", DS_GPIO_WIRE_MAX_LINE);
    client_close (s, c);
  }
}

static void
accept_client (DsGpioChipServer *s)
{
  int fd = accept4 (s->listen_fd, NULL, NULL, SOCK_CLOEXEC);
  if (fd < 0)
    return;
  for (guint k = 0; k < DS_GPIO_CHIP_SERVER_MAX_CLIENTS; k++)
    if (s->clients[k].fd < 0) {
      Client *c = &s->clients[k];
      memset (c, 0, sizeof *c);
      c->fd = fd;
      c->id = ++s->next_id ? s->next_id : ++s->next_id;
      return;
    }
  Client full = { .fd = fd };
  refuse (s, &full, DS_GPIO_WIRE_ERR_BUSY, "the chip serves %d connections at most", DS_GPIO_CHIP_SERVER_MAX_CLIENTS);
  close (fd);
}

static gpointer
serve (gpointer data)
{
  DsGpioChipServer *s = data;
  for (;;) {
    struct pollfd pfd[2 + DS_GPIO_CHIP_SERVER_MAX_CLIENTS];
    Client *who[2 + DS_GPIO_CHIP_SERVER_MAX_CLIENTS];
    guint n = 0;
    pfd[n] = (struct pollfd) { .fd = s->stop_pipe[0], .events = POLLIN };
    who[n++] = NULL;
    pfd[n] = (struct pollfd) { .fd = s->listen_fd, .events = POLLIN };
    who[n++] = NULL;
    for (guint k = 0; k < DS_GPIO_CHIP_SERVER_MAX_CLIENTS; k++)
      if (s->clients[k].fd >= 0) {
        pfd[n] = (struct pollfd) { .fd = s->clients[k].fd, .events = POLLIN };
        who[n++] = &s->clients[k];
      }
    if (poll (pfd, n, -1) < 0) {
      if (errno == EINTR)
        continue;
      g_warning ("GPIO chip %s: poll: %s", s->path, g_strerror (errno));
      return NULL;
    }
    if (pfd[0].revents)
      return NULL;
    if (pfd[1].revents & POLLIN)
      accept_client (s);
    for (guint i = 2; i < n; i++)
      if (pfd[i].revents)
        client_readable (s, who[i]);
  }
}

static int
listen_on (const char *path, GError **error)
{
  struct sockaddr_un addr = { .sun_family = AF_UNIX };
  if (strlen (path) >= sizeof addr.sun_path) {
    g_set_error (error, G_IO_ERROR, G_IO_ERROR_INVALID_ARGUMENT, "GPIO chip socket \"%s\": longer than %zu bytes",
                 path, sizeof addr.sun_path - 1);
    return -1;
  }
  struct stat st;
  if (lstat (path, &st) == 0) {
    if (!S_ISSOCK (st.st_mode)) {
      g_set_error (error, G_IO_ERROR, G_IO_ERROR_EXISTS, "GPIO chip socket \"%s\": exists and is not a socket", path);
      return -1;
    }
    unlink (path); /* a socket left by a labsim that was killed */
  }
  strcpy (addr.sun_path, path);
  int fd = socket (AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
  if (fd < 0 || bind (fd, (struct sockaddr *) &addr, sizeof addr) < 0 || listen (fd, 16) < 0) {
    int e = errno;
    g_set_error (error, G_IO_ERROR, g_io_error_from_errno (e), "GPIO chip socket \"%s\": %s", path, g_strerror (e));
    if (fd >= 0)
      close (fd);
    return -1;
  }
  return fd;
}

DsGpioChipServer *
ds_gpio_chip_server_new (const char *path, guint n_lines, const char *label, DsGpioChipEdgeFunc edge,
                         gpointer user_data, GError **error)
{
  if (n_lines == 0 || n_lines > DS_GPIO_CHIP_SERVER_MAX_LINES) {
    g_set_error (error, G_IO_ERROR, G_IO_ERROR_INVALID_ARGUMENT, "GPIO chip: %u lines (1..%d)", n_lines,
                 DS_GPIO_CHIP_SERVER_MAX_LINES);
    return NULL;
  }
  int stop_pipe[2];
  if (pipe2 (stop_pipe, O_CLOEXEC) < 0) {
    int e = errno;
    g_set_error (error, G_IO_ERROR, g_io_error_from_errno (e), "GPIO chip \"%s\": %s", path, g_strerror (e));
    return NULL;
  }
  int fd = listen_on (path, error);
  if (fd < 0) {
    close (stop_pipe[0]);
    close (stop_pipe[1]);
    return NULL;
  }
  DsGpioChipServer *s = g_new0 (DsGpioChipServer, 1);
  s->stop_pipe[0] = stop_pipe[0];
  s->stop_pipe[1] = stop_pipe[1];
  s->path = g_strdup (path);
  s->label = g_strdup (label ? label : "descatter-labsim");
  s->n_lines = n_lines;
  s->edge = edge;
  s->edge_data = user_data;
  s->listen_fd = fd;
  g_mutex_init (&s->lock);
  for (guint k = 0; k < DS_GPIO_CHIP_SERVER_MAX_CLIENTS; k++)
    s->clients[k].fd = -1;
  s->thread = g_thread_new ("labsim-gpio", serve, s);
  return s;
}

int
ds_gpio_chip_server_level (DsGpioChipServer *s, guint offset)
{
  if (offset >= s->n_lines)
    return -1;
  g_mutex_lock (&s->lock);
  int v = s->level[offset];
  g_mutex_unlock (&s->lock);
  return v;
}

void
ds_gpio_chip_server_stats (DsGpioChipServer *s, DsGpioChipStats *stats)
{
  g_mutex_lock (&s->lock);
  *stats = s->stats;
  g_mutex_unlock (&s->lock);
}

void
ds_gpio_chip_server_free (DsGpioChipServer *s)
{
  if (!s)
    return;
  char b = 1;
  if (write (s->stop_pipe[1], &b, 1) != 1)
    g_warning ("GPIO chip %s: cannot wake the chip thread", s->path);
  g_thread_join (s->thread);
  for (guint k = 0; k < DS_GPIO_CHIP_SERVER_MAX_CLIENTS; k++)
    if (s->clients[k].fd >= 0)
      client_close (s, &s->clients[k]);
  close (s->listen_fd);
  close (s->stop_pipe[0]);
  close (s->stop_pipe[1]);
  unlink (s->path);
  g_mutex_clear (&s->lock);
  g_free (s->path);
  g_free (s->label);
  g_free (s);
}
