/* An LD_PRELOAD fault layer for tests: while the file named by DS_ENOSPC_FLAG exists, every
 * write to a file whose path ends with DS_ENOSPC_SUFFIX writes nothing and fails with ENOSPC,
 * as a full disk does. When the flag file holds a number, only writes of at least that many
 * bytes fail (a disk with a little room: an HDF5 file's metadata still fits, its image chunks
 * do not). It lets a test put the failure inside a library's write (HDF5's), where
 * a filled filesystem would be refused earlier by the writer's own check of the room left.
 * Only pwrite/pwrite64/write/writev are wrapped; everything else passes through. */
#ifndef _GNU_SOURCE
#define _GNU_SOURCE
#endif
#include <dlfcn.h>
#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/types.h>
#include <sys/uio.h>
#include <unistd.h>

static int
refused (int fd, size_t count)
{
  const char *flag = getenv ("DS_ENOSPC_FLAG"), *suffix = getenv ("DS_ENOSPC_SUFFIX");
  if (!flag || !suffix)
    return 0;
  int ff = open (flag, O_RDONLY | O_CLOEXEC);
  if (ff < 0)
    return 0;
  char text[32] = { 0 };
  ssize_t got = read (ff, text, sizeof text - 1);
  close (ff);
  if (got > 0 && count < strtoull (text, NULL, 10))
    return 0;
  char link[64], path[PATH_MAX];
  snprintf (link, sizeof link, "/proc/self/fd/%d", fd);
  ssize_t n = readlink (link, path, sizeof path - 1);
  if (n <= 0)
    return 0;
  path[n] = '\0';
  size_t ls = strlen (suffix);
  return (size_t) n >= ls && strcmp (path + n - ls, suffix) == 0;
}

#define NEXT(name) ((__typeof__ (&name)) dlsym (RTLD_NEXT, #name))

ssize_t
pwrite (int fd, const void *buf, size_t count, off_t offset)
{
  if (refused (fd, count)) {
    errno = ENOSPC;
    return -1;
  }
  return NEXT (pwrite) (fd, buf, count, offset);
}

ssize_t
pwrite64 (int fd, const void *buf, size_t count, off_t offset)
{
  if (refused (fd, count)) {
    errno = ENOSPC;
    return -1;
  }
  return NEXT (pwrite64) (fd, buf, count, offset);
}

ssize_t
write (int fd, const void *buf, size_t count)
{
  if (refused (fd, count)) {
    errno = ENOSPC;
    return -1;
  }
  return NEXT (write) (fd, buf, count);
}

ssize_t
writev (int fd, const struct iovec *iov, int iovcnt)
{
  size_t count = 0;
  for (int i = 0; i < iovcnt; i++)
    count += iov[i].iov_len;
  if (refused (fd, count)) {
    errno = ENOSPC;
    return -1;
  }
  return NEXT (writev) (fd, iov, iovcnt);
}
