/* Live camera settings: exposure, gain and the region of interest as a client's `set` changes
 * them on the open camera (docs/protocol.md, `set`). They become the defaults of the sets that
 * follow (a capture's own exposure or gain still wins) and hold until the daemon restarts: a
 * configuration reload and a reopening of the devices keep them.
 *
 * Plain data and a CPU-only check: any thread. What applies them on the acquisition thread is
 * declared in acquisition.h (camera_live.c). */
#pragma once
#include <glib.h>

#include "drivers/core/camera.h"

G_BEGIN_DECLS

/* The camera's settings that a `set` changes, as they stand. */
typedef struct {
  double exposure_us;
  double gain_db;
  guint roi_x, roi_y, roi_width, roi_height; /* the frames' region; the whole sensor spelled out */
} DsCameraLive;

/* What a `set` asks to change: only the members flagged. */
typedef struct {
  gboolean has_exposure, has_gain, has_roi;
  double exposure_us;
  double gain_db;
  guint roi_x, roi_y, roi_width, roi_height;
} DsCameraChange;

/* Checks `want` against the camera's own ranges (what the camera reported when it opened: its
 * exposure and gain bounds, whether it has a gain, its sensor's size). FALSE with
 * DS_PROTOCOL_ERROR_BAD_ARGUMENT naming the setting, the value and the range, in the words of
 * the backends' own refusals ("aravis camera: gain 12 dB outside [0, 10]"); `backend` is the
 * camera ops' name. An unknown bound (0, 0) is not checked here: the camera's configure checks
 * it. */
gboolean ds_camera_live_validate (const char *backend, const DsCameraInfo *info, const DsCameraLive *want,
                                  GError **error);
/* current with the members that change flags, overlaid. */
void ds_camera_live_apply_change (DsCameraLive *current, const DsCameraChange *change);

G_END_DECLS
