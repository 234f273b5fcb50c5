/* One set of builders for every JSON object the service writes (json_build.h). */
#include "daemon/service/json_build.h"

JsonBuilder *
ds_json_object_begin (void)
{
  JsonBuilder *b = json_builder_new ();
  json_builder_begin_object (b);
  return b;
}

JsonNode *
ds_json_object_end (JsonBuilder *b)
{
  json_builder_end_object (b);
  return json_builder_get_root (b);
}

void
ds_json_add_string (JsonBuilder *b, const char *key, const char *value)
{
  json_builder_set_member_name (b, key);
  if (value)
    json_builder_add_string_value (b, value);
  else
    json_builder_add_null_value (b);
}

void
ds_json_add_int (JsonBuilder *b, const char *key, gint64 value)
{
  json_builder_set_member_name (b, key);
  json_builder_add_int_value (b, value);
}

void
ds_json_add_uint (JsonBuilder *b, const char *key, guint64 value)
{
  json_builder_set_member_name (b, key);
  json_builder_add_int_value (b, (gint64) value);
}

void
ds_json_add_bool (JsonBuilder *b, const char *key, gboolean value)
{
  json_builder_set_member_name (b, key);
  json_builder_add_boolean_value (b, value);
}

void
ds_json_add_double (JsonBuilder *b, const char *key, double value)
{
  json_builder_set_member_name (b, key);
  json_builder_add_double_value (b, value);
}

void
ds_json_add_node (JsonBuilder *b, const char *key, JsonNode *value)
{
  json_builder_set_member_name (b, key);
  json_builder_add_value (b, value ? value : json_node_new (JSON_NODE_NULL));
}

void
ds_json_begin_member_object (JsonBuilder *b, const char *key)
{
  json_builder_set_member_name (b, key);
  json_builder_begin_object (b);
}
