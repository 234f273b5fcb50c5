#include "drivers/gpio/gpio_lines_socket.h"

#include <errno.h>
#include <poll.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include "drivers/gpio/gpio_wire.h"

typedef struct {
  int fd;                  /* -1: not connected (never, or dropped after a failure) */
  char *chip, *path, *consumer;
  guint n;
  guint offsets[DS_GPIO_MAX_LINES];
  int last[DS_GPIO_MAX_LINES];
} SocketLines;

static void
drop (SocketLines *s)
{
  if (s->fd >= 0)
    close (s->fd);
  s->fd = -1;
}

static void
append_values (GString *out, const int *values, guint n)
{
  for (guint i = 0; i < n; i++)
    g_string_append_printf (out, "%s%d", i ? "," : "", values[i] ? 1 : 0);
}

/* The chip's "err CODE MESSAGE" as the kernel's errno would have said it. */
static void
chip_refused (SocketLines *s, const char *what, const char *answer, GError **error)
{
  struct { const char *code; GIOErrorEnum io; } map[] = {
    { DS_GPIO_WIRE_ERR_BUSY, G_IO_ERROR_BUSY },
    { DS_GPIO_WIRE_ERR_RANGE, G_IO_ERROR_NOT_FOUND },
    { DS_GPIO_WIRE_ERR_INVALID, G_IO_ERROR_INVALID_ARGUMENT },
    { DS_GPIO_WIRE_ERR_STATE, G_IO_ERROR_INVALID_ARGUMENT },
  };
  GIOErrorEnum code = G_IO_ERROR_FAILED;
  const char *msg = answer;
  for (guint i = 0; i < G_N_ELEMENTS (map); i++) {
    gsize len = strlen (map[i].code);
    if (strncmp (answer, map[i].code, len) == 0 && answer[len] == ' ') {
      code = map[i].io;
      msg = answer + len + 1;
    }
  }
  g_set_error (error, G_IO_ERROR, code, "GPIO %s: %s: %s", s->chip, what, msg);
}

/* Reads one reply line within the deadline. FALSE (connection dropped) on silence or EOF. */
static gboolean
read_reply (SocketLines *s, const char *what, char *line, GError **error)
{
  gint64 deadline = g_get_monotonic_time () + DS_GPIO_SOCKET_TIMEOUT_MS * 1000;
  gsize len = 0;
  for (;;) {
    gint64 left_ms = (deadline - g_get_monotonic_time () + 999) / 1000;
    struct pollfd p = { .fd = s->fd, .events = POLLIN };
    int r = left_ms > 0 ? poll (&p, 1, (int) left_ms) : 0;
    if (r < 0 && errno == EINTR)
      continue;
    if (r == 0) {
      drop (s);
      g_set_error (error, G_IO_ERROR, G_IO_ERROR_TIMED_OUT, "GPIO %s: %s: no answer within %d ms", s->chip, what,
                   DS_GPIO_SOCKET_TIMEOUT_MS);
      return FALSE;
    }
    gssize n = r > 0 ? recv (s->fd, line + len, DS_GPIO_WIRE_MAX_LINE - 1 - len, 0) : -1;
    if (n <= 0) {
      drop (s);
      g_set_error (error, G_IO_ERROR, G_IO_ERROR_CLOSED, "GPIO %s: %s: the chip went away (%s)", s->chip, what,
                   n == 0 ? "connection closed" : g_strerror (errno));
      return FALSE;
    }
    len += (gsize) n;
    line[len] = '\0';
    char *nl = memchr (line, '\n', len);
    if (nl && nl == line + len - 1) {
      *nl = '\0';
      return TRUE;
    }
    if (nl || len == DS_GPIO_WIRE_MAX_LINE - 1) {
      drop (s); /* more than one reply, or no end: out of step with the chip */
      g_set_error (error, G_IO_ERROR, G_IO_ERROR_INVALID_DATA, "GPIO %s: %s: malformed answer from the chip",
                   s->chip, what);
      return FALSE;
    }
  }
}

/* One request, one reply. On "ok", *rest is what followed it (borrowed from `line`). */
static gboolean
transact (SocketLines *s, const char *what, const char *request, char *line, const char **rest, GError **error)
{
  if (s->fd < 0) {
    g_set_error (error, G_IO_ERROR, G_IO_ERROR_CLOSED,
                 "GPIO %s: %s: not connected (the chip went away; the lines are requested again on reopen)",
                 s->chip, what);
    return FALSE;
  }
  g_autofree char *msg = g_strdup_printf ("%s\n", request);
  gsize len = strlen (msg);
  /* A reply-sized request never fills a socket buffer the chip drains: not blocking is safe. */
  if (send (s->fd, msg, len, MSG_NOSIGNAL | MSG_DONTWAIT) != (gssize) len) {
    int e = errno;
    drop (s);
    g_set_error (error, G_IO_ERROR, G_IO_ERROR_CLOSED, "GPIO %s: %s: the chip went away (%s)", s->chip, what,
                 g_strerror (e));
    return FALSE;
  }
  if (!read_reply (s, what, line, error))
    return FALSE;
  if (strcmp (line, "ok") == 0 || strncmp (line, "ok ", 3) == 0) {
    *rest = line[2] ? line + 3 : line + 2;
    return TRUE;
  }
  if (strncmp (line, "err ", 4) == 0) {
    chip_refused (s, what, line + 4, error);
    return FALSE;
  }
  drop (s);
  g_set_error (error, G_IO_ERROR, G_IO_ERROR_INVALID_DATA, "GPIO %s: %s: unexpected answer \"%.64s\"", s->chip,
               what, line);
  return FALSE;
}

static gboolean
connect_and_request (SocketLines *s, GError **error)
{
  drop (s);
  struct sockaddr_un addr = { .sun_family = AF_UNIX };
  if (strlen (s->path) >= sizeof addr.sun_path) {
    g_set_error (error, G_IO_ERROR, G_IO_ERROR_INVALID_ARGUMENT, "GPIO %s: socket path longer than %zu bytes",
                 s->chip, sizeof addr.sun_path - 1);
    return FALSE;
  }
  strcpy (addr.sun_path, s->path);
  int fd = socket (AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
  if (fd < 0 || connect (fd, (struct sockaddr *) &addr, sizeof addr) < 0) {
    int e = errno;
    if (fd >= 0)
      close (fd);
    /* No socket file, or one nobody listens on: the chip is not there (ENODEV for the kernel). */
    g_set_error (error, G_IO_ERROR, G_IO_ERROR_NOT_FOUND,
                 "GPIO %s: cannot open the chip: %s (is descatter-labsim running with --gpio-chip %s?)", s->chip,
                 g_strerror (e), s->path);
    return FALSE;
  }
  s->fd = fd;
  g_autoptr (GString) req = g_string_new ("request ");
  g_string_append (req, s->consumer);
  for (guint i = 0; i < s->n; i++)
    g_string_append_printf (req, "%s%u", i ? "," : " ", s->offsets[i]);
  g_string_append_c (req, ' ');
  append_values (req, s->last, s->n);
  char line[DS_GPIO_WIRE_MAX_LINE];
  const char *rest;
  if (!transact (s, "requesting the lines", req->str, line, &rest, error)) {
    drop (s);
    return FALSE;
  }
  return TRUE;
}

static gboolean
socket_set (gpointer impl, const int *values, GError **error)
{
  SocketLines *s = impl;
  g_autoptr (GString) req = g_string_new ("set ");
  append_values (req, values, s->n);
  char line[DS_GPIO_WIRE_MAX_LINE];
  const char *rest;
  if (!transact (s, "setting the lines", req->str, line, &rest, error))
    return FALSE;
  for (guint i = 0; i < s->n; i++)
    s->last[i] = values[i] ? 1 : 0;
  return TRUE;
}

static gboolean
socket_get (gpointer impl, int *values, GError **error)
{
  SocketLines *s = impl;
  char line[DS_GPIO_WIRE_MAX_LINE];
  const char *rest;
  if (!transact (s, "reading the lines back", "get", line, &rest, error))
    return FALSE;
  g_auto (GStrv) parts = g_strsplit (rest, ",", -1);
  guint n = g_strv_length (parts);
  for (guint i = 0; i < n && n == s->n; i++) {
    if (strcmp (parts[i], "0") != 0 && strcmp (parts[i], "1") != 0)
      n = 0;
    else
      values[i] = parts[i][0] - '0';
  }
  if (n != s->n) {
    drop (s);
    g_set_error (error, G_IO_ERROR, G_IO_ERROR_INVALID_DATA, "GPIO %s: reading the lines back: answer \"%.64s\" "
                 "is not %u levels", s->chip, rest, s->n);
    return FALSE;
  }
  return TRUE;
}

static gboolean
socket_reopen (gpointer impl, GError **error)
{
  return connect_and_request (impl, error);
}

static void
socket_free (gpointer impl)
{
  SocketLines *s = impl;
  drop (s);
  g_free (s->chip);
  g_free (s->path);
  g_free (s->consumer);
  g_free (s);
}

static const DsGpioLinesOps socket_ops = {
  .name = "labsim-socket",
  .set_values = socket_set,
  .get_values = socket_get,
  .reopen = socket_reopen,
  .free = socket_free,
};

DsGpioLines *
ds_gpio_lines_request_socket (const char *chip, const char *socket_path, const guint *offsets, guint n_lines,
                              const int *initial, const char *consumer, GError **error)
{
  SocketLines *s = g_new0 (SocketLines, 1);
  s->fd = -1;
  s->chip = g_strdup (chip);
  s->path = g_strdup (socket_path);
  /* The wire separates words by spaces: a consumer is one word. */
  s->consumer = g_strdelimit (g_strdup (consumer && *consumer ? consumer : "descatter"), " \t\r\n", '-');
  s->n = MIN (n_lines, DS_GPIO_MAX_LINES);
  for (guint i = 0; i < s->n; i++) {
    s->offsets[i] = offsets[i];
    s->last[i] = initial && initial[i] ? 1 : 0;
  }
  DsGpioLines *l = ds_gpio_lines_new (&socket_ops, s, chip, offsets, n_lines, error);
  if (!l) {
    socket_free (s);
    return NULL;
  }
  if (!connect_and_request (s, error)) {
    ds_gpio_lines_free (l);
    return NULL;
  }
  return l;
}
