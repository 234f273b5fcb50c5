#include "daemon/output/atomic_file.h"

#include <errno.h>
#include <fcntl.h>
#include <glib/gstdio.h>
#include <string.h>
#include <unistd.h>

#include "daemon/output/output_error.h"

char *
ds_atomic_temp_path (const char *path)
{
  g_autofree char *dir = g_path_get_dirname (path);
  g_autofree char *base = g_path_get_basename (path);
  const char *dot = strrchr (base, '.');
  int stem_len = dot && dot != base ? (int) (dot - base) : (int) strlen (base);
  return g_strdup_printf ("%s/.%.*s.tmp-%d-%08x%s", dir, stem_len, base, (int) getpid (), g_random_int (),
                          dot && dot != base ? dot : "");
}

gboolean
ds_fsync_path (const char *path, gboolean is_dir, GError **error)
{
  int fd = open (path, O_RDONLY | O_CLOEXEC | (is_dir ? O_DIRECTORY : 0));
  if (fd < 0 || fsync (fd) != 0) {
    int e = errno;
    if (fd >= 0)
      close (fd);
    g_set_error (error, DS_OUTPUT_ERROR, DS_OUTPUT_ERROR_IO, "%s: fsync failed: %s", path, g_strerror (e));
    return FALSE;
  }
  close (fd);
  return TRUE;
}

gboolean
ds_durable_rename (const char *from, const char *to, GError **error)
{
  if (!ds_fsync_path (from, FALSE, error))
    return FALSE;
  if (g_rename (from, to) != 0) {
    int e = errno;
    g_set_error (error, DS_OUTPUT_ERROR, DS_OUTPUT_ERROR_IO, "%s: rename failed: %s", to, g_strerror (e));
    return FALSE;
  }
  /* Without syncing the folder the rename itself may be lost in a power cut. */
  g_autofree char *dir = g_path_get_dirname (to);
  return ds_fsync_path (dir, TRUE, error);
}

gboolean
ds_atomic_commit (const char *tmp, const char *path, GError **error)
{
  if (ds_durable_rename (tmp, path, error))
    return TRUE;
  g_unlink (tmp);
  return FALSE;
}

gboolean
ds_atomic_write_bytes (const char *path, const void *data, gsize len, GError **error)
{
  g_autofree char *tmp = ds_atomic_temp_path (path);
  int fd = open (tmp, O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0644);
  if (fd < 0) {
    int e = errno;
    g_set_error (error, DS_OUTPUT_ERROR, DS_OUTPUT_ERROR_IO, "%s: cannot create: %s", path, g_strerror (e));
    return FALSE;
  }
  const guint8 *p = data;
  while (len > 0) {
    ssize_t n = write (fd, p, len);
    if (n < 0 && errno == EINTR)
      continue;
    if (n <= 0) {
      int e = errno;
      close (fd);
      g_unlink (tmp);
      g_set_error (error, DS_OUTPUT_ERROR, DS_OUTPUT_ERROR_IO, "%s: write failed: %s", path,
                   n < 0 ? g_strerror (e) : "no progress");
      return FALSE;
    }
    p += n;
    len -= (gsize) n;
  }
  if (close (fd) != 0) {
    int e = errno;
    g_unlink (tmp);
    g_set_error (error, DS_OUTPUT_ERROR, DS_OUTPUT_ERROR_IO, "%s: close failed: %s", path, g_strerror (e));
    return FALSE;
  }
  return ds_atomic_commit (tmp, path, error);
}
