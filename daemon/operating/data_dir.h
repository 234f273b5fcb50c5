/* Where descatter's data lives: the example scenes (scenes/) and the operating model
 * (operating-model.conf). In order: $DESCATTER_DATA_DIR when set; a program run from the build
 * tree reads etc/ of its source tree, named by the marker file DS_DATA_DIR_MARKER that the build
 * writes next to the programs (build/bin); otherwise the installed DS_DATA_DIR (build_info.h,
 * from the install prefix). The marker is never installed and no source or build path is
 * compiled in, so an installed program lands on DS_DATA_DIR (unless a marker is put
 * next to it by hand). Any thread. */
#pragma once
#include <glib.h>

G_BEGIN_DECLS

/* The marker's name in the program folder; its text is an absolute folder path. */
#define DS_DATA_DIR_MARKER "descatter-source-data-dir"

/* The data folder in use (the override, the source tree's or the installed one). Never NULL. */
const char *ds_data_dir (void);
/* ds_data_dir ()/relative, newly allocated. */
char *ds_data_path (const char *relative);

G_END_DECLS
