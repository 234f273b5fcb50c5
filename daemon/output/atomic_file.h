/* Files that appear whole or not at all: written under a hidden temporary name in the final
 * folder (".NAME.tmp-PID-RANDOM.EXT", so a reader listing the folder skips it and a writer that
 * picks the encoder by extension still sees the real one), fsynced, renamed over the final
 * name, and the folder fsynced so that the rename survives a power cut. Any thread. */
#pragma once
#include <glib.h>

G_BEGIN_DECLS

/* The temporary name for `path` (same folder, same extension). */
char *ds_atomic_temp_path (const char *path);
/* fsyncs tmp, renames it to path, fsyncs the folder. On failure tmp is removed. */
gboolean ds_atomic_commit (const char *tmp, const char *path, GError **error);
/* The same, but on failure `from` stays (it may hold data worth keeping). */
gboolean ds_durable_rename (const char *from, const char *to, GError **error);
/* Writes bytes to path atomically. */
gboolean ds_atomic_write_bytes (const char *path, const void *data, gsize len, GError **error);
/* fsync of a file or folder (O_DIRECTORY when is_dir). */
gboolean ds_fsync_path (const char *path, gboolean is_dir, GError **error);

G_END_DECLS
