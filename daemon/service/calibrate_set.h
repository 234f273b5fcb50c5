/* The daemon's `calibrate` command (docs/protocol.md): a phase set of a reference with little
 * scattering, taken as a capture that keeps its raw frames, measured by proc/calibration.h
 * into the reply's body. Sine stripes' black level cannot be told from their blur at one period
 * (proc/calibration_sine.h): where the illuminator can change its period the service takes a
 * second set at twice the period and measures it with ds_calibrate_measure (second = TRUE).
 * Main thread (the measurement is a few passes over the raw frames: it runs once per request,
 * not per set of a run). */
#pragma once
#include <json-glib/json-glib.h>

#include "daemon/acquire/result.h"
#include "proc/calibration.h"

G_BEGIN_DECLS

typedef struct {
  double period_px;       /* > 0: known, not measured */
  double pixel_aperture;  /* > 0: the sensor's, for the blur model */
} DsCalibrateRequest;

/* The calibration of result's raw frames. second_period_px > 0: the set is the second period of
 * a sine reference, taken at about that period (measured there, the pattern taken as sine).
 * Fails with the calibration's error (no raw frames, no stripes, all clipped). */
gboolean ds_calibrate_measure (DsResult *result, const DsCalibrateRequest *request, double second_period_px,
                               DsCalibration *out, GError **error);

/* The reply body: the members of proc/calibration_json.h plus set_id, `config` (the
 * descatterd.conf [illuminator] lines that use it), second_set_id when a second period was
 * taken (0: none), and second_period_error when it was tried and failed (NULL: not). */
JsonNode *ds_calibrate_reply (guint64 set_id, const DsCalibration *cal, guint64 second_set_id,
                              const char *second_period_error);

G_END_DECLS
