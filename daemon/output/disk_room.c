#include "daemon/output/disk_room.h"

#include <errno.h>
#include <fcntl.h>
#include <glib/gstdio.h>
#include <sys/statvfs.h>
#include <sys/stat.h>
#include <unistd.h>

guint64
ds_disk_free_bytes (const char *path)
{
  struct statvfs st;
  if (statvfs (path, &st) != 0)
    return G_MAXUINT64;
  return (guint64) st.f_bavail * (guint64) st.f_frsize;
}

char *
ds_disk_reserve_path (const char *path)
{
  g_autofree char *dir = g_path_get_dirname (path);
  g_autofree char *base = g_path_get_basename (path);
  g_autofree char *name = g_strdup_printf (".%s.reserve.tmp", base);
  return g_build_filename (dir, name, NULL);
}

gboolean
ds_disk_reserve_take (const char *reserve_path)
{
  GStatBuf st;
  if (g_stat (reserve_path, &st) == 0 && (guint64) st.st_blocks * 512 >= DS_DISK_RESERVE_BYTES)
    return TRUE;
  int fd = g_open (reserve_path, O_WRONLY | O_CREAT | O_CLOEXEC, 0600);
  if (fd < 0)
    return FALSE;
  /* Allocated blocks, not a sparse file: a sparse reserve would give nothing back. */
  int r = posix_fallocate (fd, 0, DS_DISK_RESERVE_BYTES);
  close (fd);
  if (r != 0) {
    g_unlink (reserve_path);
    return FALSE;
  }
  return TRUE;
}

void
ds_disk_reserve_release (const char *reserve_path)
{
  if (g_unlink (reserve_path) != 0 && errno != ENOENT)
    g_warning ("%s: cannot remove: %s", reserve_path, g_strerror (errno));
}
