/* Where descatter's installed data lives: the example scenes (scenes/) and the operating model
 * (operating-model.conf). Installed programs read DS_DATA_DIR (build_info.h, from the install
 * prefix); $DESCATTER_DATA_DIR overrides it, which is how tests and the demo run the build
 * tree's programs against etc/ of the source tree. No source path is compiled in. Any thread. */
#pragma once
#include <glib.h>

G_BEGIN_DECLS

/* The data folder in use (the override or the installed one). Never NULL. */
const char *ds_data_dir (void);
/* ds_data_dir ()/relative, newly allocated. */
char *ds_data_path (const char *relative);

G_END_DECLS
