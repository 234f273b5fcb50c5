#include "report_json.h"

JsonNode *
report_json (const DsOperatingReport *report)
{
  g_autoptr (JsonBuilder) b = json_builder_new ();
  json_builder_begin_object (b);
  ds_operating_report_to_json (report, b);
  json_builder_end_object (b);
  return json_builder_get_root (b);
}
