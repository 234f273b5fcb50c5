/* The daemon's `calibrate` command (docs/protocol.md): a phase set of a reference with little
 * scattering, taken as a capture that keeps its raw frames, measured by proc/calibration.h
 * into the reply's body. Main thread (the measurement is a few passes over the raw frames: it
 * runs once per request, not per set of a run). */
#pragma once
#include <json-glib/json-glib.h>

#include "daemon/service/result.h"

G_BEGIN_DECLS

typedef struct {
  double period_px;       /* > 0: known, not measured */
  double pixel_aperture;  /* > 0: the sensor's, for the blur model */
} DsCalibrateRequest;

/* The calibration of result's raw frames, as the reply body: the members of
 * proc/calibration_json.h plus set_id and `config`, the descatterd.conf [illuminator] lines
 * that use it. Fails with the calibration's error (no raw frames, no stripes, all clipped). */
JsonNode *ds_calibrate_result (DsResult *result, const DsCalibrateRequest *request, GError **error);

G_END_DECLS
