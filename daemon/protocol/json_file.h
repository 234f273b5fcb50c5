/* A JSON file read as strictly as the wire (json_text.h) and within bounds: only a regular
 * file (a FIFO would block the reader forever, /dev/zero or a directory never ends or never
 * parses), at most max_bytes, nesting at most max_depth. Any thread; blocks on the file
 * system only. */
#pragma once
#include <glib.h>
#include <json-glib/json-glib.h>

G_BEGIN_DECLS

/* Fails with G_FILE_ERROR (cannot open), DS_PROTOCOL_ERROR_BAD_ARGUMENT (not a regular file),
 * DS_PROTOCOL_ERROR_LIMIT (larger than max_bytes), DS_PROTOCOL_ERROR_BAD_JSON (not UTF-8, a
 * NUL byte, or what ds_json_parse_strict refuses, with the byte offset) or
 * DS_PROTOCOL_ERROR_TOO_DEEP. Messages do not repeat the path: the caller prefixes it. */
JsonNode *ds_json_read_file_strict (const char *path, gsize max_bytes, guint max_depth, GError **error);

G_END_DECLS
