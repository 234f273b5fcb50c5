/* Building the JSON objects of replies, events and status documents: an object opened,
 * one member per call, and closed into its node, so that a document reads as the list of its
 * members. Doubles that may be NaN go through ds_json_add_double_or_null
 * (daemon/output/result_meta.h): JSON has no NaN. */
#pragma once
#include <json-glib/json-glib.h>

G_BEGIN_DECLS

/* A builder with an object open; ds_json_object_end closes it and returns the object. */
JsonBuilder *ds_json_object_begin (void);
JsonNode *ds_json_object_end (JsonBuilder *b);

/* Members of the object being built. A NULL string is written as null. */
void ds_json_add_string (JsonBuilder *b, const char *key, const char *value);
void ds_json_add_int (JsonBuilder *b, const char *key, gint64 value);
/* Counters: unsigned, written as JSON integers (exact up to 2^63). */
void ds_json_add_uint (JsonBuilder *b, const char *key, guint64 value);
void ds_json_add_bool (JsonBuilder *b, const char *key, gboolean value);
/* A finite double (ds_json_add_double_or_null for one that may not be). */
void ds_json_add_double (JsonBuilder *b, const char *key, double value);
/* Takes value; NULL is written as null. */
void ds_json_add_node (JsonBuilder *b, const char *key, JsonNode *value);
/* A member that is itself an object: its members follow, then json_builder_end_object. */
void ds_json_begin_member_object (JsonBuilder *b, const char *key);

G_END_DECLS
