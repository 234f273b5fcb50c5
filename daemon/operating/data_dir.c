#include "daemon/operating/data_dir.h"

#include "build_info.h"

const char *
ds_data_dir (void)
{
  const char *dir = g_getenv ("DESCATTER_DATA_DIR");
  return dir && *dir ? dir : DS_DATA_DIR;
}

char *
ds_data_path (const char *relative)
{
  return g_build_filename (ds_data_dir (), relative, NULL);
}
