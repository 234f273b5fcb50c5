/* Test helpers shared by every test folder: removing a scratch tree. */
#pragma once

#include <glib.h>
#include <glib/gstdio.h>

/* Removes `path` and everything below it; symbolic links are removed, never followed. Errors
 * are ignored: a test's scratch folder is in /tmp and its removal is best effort. */
static inline void
test_remove_tree (const char *path)
{
  if (g_file_test (path, G_FILE_TEST_IS_DIR) && !g_file_test (path, G_FILE_TEST_IS_SYMLINK)) {
    GDir *d = g_dir_open (path, 0, NULL);
    const char *name;
    while (d && (name = g_dir_read_name (d))) {
      g_autofree char *child = g_build_filename (path, name, NULL);
      test_remove_tree (child);
    }
    if (d)
      g_dir_close (d);
    g_rmdir (path);
  } else
    g_unlink (path);
}
