/* JSON text on the wire, read and written strictly (RFC 8259, with the I-JSON limits of
 * RFC 7493): json-glib's own parser is lenient (single quotes, comments, hex numbers, a second
 * value after the first silently ignored, \u0000 cutting a string short, 1e999 read as
 * infinity) and its generator writes some control characters raw and infinity as `inf.0`, so
 * neither may stand between a hostile client and the daemon. The trees are plain JsonNodes.
 * Pure functions: any thread, never block. */
#pragma once
#include <glib.h>
#include <json-glib/json-glib.h>

G_BEGIN_DECLS

/* Parses exactly one JSON value (surrounded by optional whitespace) from text[0..len).
 * Refused, with DS_PROTOCOL_ERROR_BAD_JSON and the byte offset: anything RFC 8259 does not
 * allow, more than one value, control characters in strings, \u0000, lone surrogates,
 * duplicate member names, numbers that are not finite doubles, integers outside 64 bits.
 * Nesting deeper than max_depth fails with DS_PROTOCOL_ERROR_TOO_DEEP before going deeper
 * (the parser recurses once per level). The text must be valid UTF-8 without NUL bytes
 * (the caller checks, to name the byte). */
JsonNode *ds_json_parse_strict (const char *text, gsize len, guint max_depth, GError **error);

/* Appends the compact JSON text of node: every string escaped (control characters as \u00XX,
 * invalid UTF-8 replaced by U+FFFD), non-finite doubles as null, integral doubles with ".0"
 * so that they read back as doubles. The output never contains a raw newline. */
void ds_json_write (GString *out, JsonNode *node);
/* The same as a new string. */
char *ds_json_to_text (JsonNode *node, gsize *len);

G_END_DECLS
