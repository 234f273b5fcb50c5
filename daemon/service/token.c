#include "daemon/service/token.h"

#include <errno.h>
#include <fcntl.h>
#include <gio/gio.h>
#include <stdio.h>
#include <string.h>
#include <sys/random.h>
#include <sys/stat.h>
#include <unistd.h>

gboolean
ds_token_equal (const char *expected, const char *given)
{
  gsize n = strlen (expected), m = given ? strlen (given) : 0;
  guint8 diff = (guint8) (n != m);
  for (gsize i = 0; i < n; i++)
    diff |= (guint8) (expected[i] ^ (i < m ? given[i] : 0));
  return diff == 0;
}

char *
ds_token_generate (GError **error)
{
  guint8 raw[32];
  gsize got = 0;
  while (got < sizeof raw) {
    ssize_t n = getrandom (raw + got, sizeof raw - got, 0);
    if (n < 0 && errno == EINTR)
      continue;
    if (n <= 0) {
      int e = errno;
      g_set_error (error, G_IO_ERROR, g_io_error_from_errno (e), "HTTP token: getrandom: %s", g_strerror (e));
      return NULL;
    }
    got += (gsize) n;
  }
  GString *hex = g_string_sized_new (2 * sizeof raw);
  for (gsize i = 0; i < sizeof raw; i++)
    g_string_append_printf (hex, "%02x", raw[i]);
  return g_string_free (hex, FALSE);
}

static gboolean
fail_errno (GError **error, const char *what, const char *path)
{
  int e = errno;
  g_set_error (error, G_IO_ERROR, g_io_error_from_errno (e), "HTTP token file %s: %s: %s", path, what, g_strerror (e));
  return FALSE;
}

gboolean
ds_token_write_for_socket (const char *path, const char *token, const char *socket_path, GError **error)
{
  struct stat sock;
  gboolean group = stat (socket_path, &sock) == 0 && (sock.st_mode & (S_IRGRP | S_IWGRP));
  mode_t mode = group ? 0640 : 0600;
  g_autofree char *tmp = g_strconcat (path, ".tmp", NULL);
  unlink (tmp);
  int fd = open (tmp, O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, mode);
  if (fd < 0)
    return fail_errno (error, "create", tmp);
  /* The socket's group, so that its members read it; the mode again, whatever the umask. */
  gboolean ok = (!group || fchown (fd, (uid_t) -1, sock.st_gid) == 0 || errno == EPERM) && fchmod (fd, mode) == 0;
  g_autofree char *text = g_strconcat (token, "\n", NULL);
  ok = ok && write (fd, text, strlen (text)) == (ssize_t) strlen (text) && fsync (fd) == 0;
  if (!ok) {
    fail_errno (error, "write", tmp);
    close (fd);
    unlink (tmp);
    return FALSE;
  }
  close (fd);
  if (rename (tmp, path) != 0) {
    fail_errno (error, "rename", path);
    unlink (tmp);
    return FALSE;
  }
  return TRUE;
}
