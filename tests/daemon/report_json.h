/* What the tests of the operating point's record (test_operating_point.c, test_probe_narrow.c)
 * share: a report turned into the JSON object a result's operating_point carries. */
#pragma once
#include <json-glib/json-glib.h>

#include "daemon/operating/operating_point.h"

G_BEGIN_DECLS

/* The report as ds_operating_report_to_json writes it into an object of its own: a node holding
 * that object, which the caller frees. */
JsonNode *report_json (const DsOperatingReport *report);

G_END_DECLS
