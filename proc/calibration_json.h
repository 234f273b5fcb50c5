/* A calibration (proc/calibration.h) as JSON: the document `descatterctl calibrate --json`
 * prints and the daemon's `calibrate` reply carries (docs/protocol.md), one member per field
 * with the same names, and the configuration lines that use it. Any thread; no shared state. */
#pragma once
#include <json-glib/json-glib.h>

#include "proc/calibration.h"

G_BEGIN_DECLS

/* Adds the calibration's members to the object b is building. */
void ds_calibration_add_json_members (JsonBuilder *b, const DsCalibration *cal);
/* Reads them back; fails DS_PROC_ERROR_INVALID_ARGUMENT naming the missing or mistyped member. */
gboolean ds_calibration_from_json (JsonObject *obj, DsCalibration *cal, GError **error);

/* The descatterd.conf lines that use it: "[illuminator]\npattern=...\nperiod-px=...\n..." */
char *ds_calibration_config_lines (const DsCalibration *cal);

G_END_DECLS
