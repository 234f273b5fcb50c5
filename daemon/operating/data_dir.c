#include "daemon/operating/data_dir.h"

#include "build_info.h"

/* The source data folder named by the marker next to the running program, or NULL. Only the
 * build writes that marker (into its program folder, never installed: see CMakeLists.txt), so an
 * installed program finds none and keeps DS_DATA_DIR; no build path is compiled in. A marker
 * naming a folder that is gone (a moved or deleted source tree) counts as none. */
static char *
build_tree_data_dir (void)
{
  g_autofree char *exe = g_file_read_link ("/proc/self/exe", NULL);
  if (!exe)
    return NULL;
  g_autofree char *bindir = g_path_get_dirname (exe);
  g_autofree char *marker = g_build_filename (bindir, DS_DATA_DIR_MARKER, NULL);
  g_autofree char *text = NULL;
  if (!g_file_get_contents (marker, &text, NULL, NULL))
    return NULL;
  g_strstrip (text);
  if (!g_path_is_absolute (text) || !g_file_test (text, G_FILE_TEST_IS_DIR))
    return NULL;
  return g_steal_pointer (&text);
}

const char *
ds_data_dir (void)
{
  const char *dir = g_getenv ("DESCATTER_DATA_DIR");
  if (dir && *dir)
    return dir;
  /* Looked up once: the program's own location does not change while it runs. */
  static char *found;
  if (g_once_init_enter (&found)) {
    char *tree = build_tree_data_dir ();
    g_once_init_leave (&found, tree ? tree : g_strdup (DS_DATA_DIR));
  }
  return found;
}

char *
ds_data_path (const char *relative)
{
  return g_build_filename (ds_data_dir (), relative, NULL);
}
