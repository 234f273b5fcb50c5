#include "daemon/protocol/json_file.h"

#include <errno.h>
#include <fcntl.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "daemon/protocol/json_text.h"
#include "daemon/protocol/protocol.h"

static void
close_fd (int *fd)
{
  if (*fd >= 0)
    close (*fd);
}

JsonNode *
ds_json_read_file_strict (const char *path, gsize max_bytes, guint max_depth, GError **error)
{
  /* O_NONBLOCK: opening a FIFO for reading would otherwise wait for a writer; the type is
   * checked on the open descriptor, so the file cannot be swapped after the check. */
  __attribute__ ((cleanup (close_fd))) int fd = open (path, O_RDONLY | O_NONBLOCK | O_CLOEXEC | O_NOCTTY);
  if (fd < 0) {
    int e = errno;
    g_set_error (error, G_FILE_ERROR, g_file_error_from_errno (e), "cannot open: %s", g_strerror (e));
    return NULL;
  }
  struct stat st;
  if (fstat (fd, &st) != 0 || !S_ISREG (st.st_mode)) {
    g_set_error (error, DS_PROTOCOL_ERROR, DS_PROTOCOL_ERROR_BAD_ARGUMENT, "not a regular file");
    return NULL;
  }
  if ((guint64) st.st_size > max_bytes) {
    g_set_error (error, DS_PROTOCOL_ERROR, DS_PROTOCOL_ERROR_LIMIT, "%" G_GUINT64_FORMAT
                 " bytes, more than the %" G_GSIZE_FORMAT " a JSON sidecar may have",
                 (guint64) st.st_size, max_bytes);
    return NULL;
  }
  /* One byte more than the limit is read, so that a file growing after fstat is still caught. */
  g_autofree char *text = g_malloc (max_bytes + 1);
  gsize len = 0;
  while (len <= max_bytes) {
    ssize_t r = read (fd, text + len, max_bytes + 1 - len);
    if (r < 0 && errno == EINTR)
      continue;
    if (r < 0) {
      int e = errno;
      g_set_error (error, G_FILE_ERROR, g_file_error_from_errno (e), "cannot read: %s", g_strerror (e));
      return NULL;
    }
    if (r == 0)
      break;
    len += (gsize) r;
  }
  if (len > max_bytes) {
    g_set_error (error, DS_PROTOCOL_ERROR, DS_PROTOCOL_ERROR_LIMIT,
                 "more than the %" G_GSIZE_FORMAT " bytes a JSON sidecar may have", max_bytes);
    return NULL;
  }
  const char *nul = memchr (text, '\0', len);
  if (nul) {
    g_set_error (error, DS_PROTOCOL_ERROR, DS_PROTOCOL_ERROR_BAD_JSON, "not valid JSON at byte %zu: a NUL byte",
                 (gsize) (nul - text));
    return NULL;
  }
  const char *bad = NULL;
  if (!g_utf8_validate (text, (gssize) len, &bad)) {
    g_set_error (error, DS_PROTOCOL_ERROR, DS_PROTOCOL_ERROR_BAD_JSON, "not valid JSON at byte %zu: not UTF-8",
                 (gsize) (bad - text));
    return NULL;
  }
  return ds_json_parse_strict (text, len, max_depth, error);
}
