/* The camera interface: one ops table per backend (aravis, sim), driven by the sequencer.
 *
 * Threads: a DsCamera is created, used and closed by ONE thread, the acquisition thread. No op
 * may be called concurrently. Backends may run their own internal threads (Aravis's stream
 * thread) but never call back into the daemon from them.
 * Errors: DS_CAMERA_ERROR with DsDeviceError codes (drivers/core/device_error.h). */
#pragma once
#include <glib.h>

#include "drivers/core/device_error.h"
#include "drivers/core/frame.h"

G_BEGIN_DECLS

typedef enum {
  DS_CAMERA_TRIGGER_SOFTWARE = 0, /* ops->trigger sends a software trigger */
  DS_CAMERA_TRIGGER_LINE = 1,     /* an external pulse on a hardware line (see trigger.h) */
} DsCameraTriggerSource;

typedef struct {
  double exposure_us;
  double gain_db;
  guint roi_x, roi_y, roi_width, roi_height; /* width 0: full sensor */
  char pixel_format[32];   /* GenICam name: Mono8, Mono10, Mono12, Mono16, Mono10p, Mono12p, Mono12Packed */
  DsCameraTriggerSource trigger_source;
  guint trigger_line;      /* for DS_CAMERA_TRIGGER_LINE */
} DsCameraSettings;

typedef struct {
  guint64 completed;       /* frames delivered by grab */
  guint64 failures;        /* buffers that came back with a non-success status */
  guint64 missing_packets; /* GVSP packets lost (as the library counts them) */
  guint64 resend_requests;
  guint64 timeouts;
  guint64 ids_skipped;     /* frame-id gaps seen */
  guint64 reconnects;
  guint64 unfilled_buffers; /* buffers the library handed back without a frame in them: no frames */
} DsCameraStats;

typedef struct {
  char vendor[64], model[64], serial[64], address[64];
  guint sensor_width, sensor_height;
  gboolean connected;
  /* What the camera allows, read when it opens (descatterd --check --probe prints it):
   * its PixelFormat entries ("Mono8, Mono16"; "" when it lists none), and its ranges. */
  char pixel_formats[256];
  gboolean has_gain;                       /* FALSE: the camera has no Gain feature */
  double gain_min_db, gain_max_db;
  double exposure_min_us, exposure_max_us; /* 0, 0: unknown */
  double pixel_pitch_um;                   /* the sensor's pixel pitch (SensorPixelWidth); 0: unknown */
} DsCameraInfo;

typedef struct DsCameraOps DsCameraOps;

typedef struct {
  const DsCameraOps *ops;
  gpointer backend;        /* opaque state owned by the backend */
} DsCamera;

struct DsCameraOps {
  const char *name;        /* "aravis", "sim" */
  /* Applies settings; the camera must be stopped. Blocks for device round trips (< 1 s).
   * Fails INVALID (value out of the device's range, unknown pixel format), UNSUPPORTED,
   * DISCONNECTED. */
  gboolean (*configure) (gpointer backend, const DsCameraSettings *settings, GError **error);
  /* Starts acquisition in triggered mode with the buffer pool allocated once. < 1 s. */
  gboolean (*start) (gpointer backend, GError **error);
  /* Exposes one frame now (software trigger). Non-blocking beyond one command round trip.
   * With a line trigger source this fails INVALID: pulse the trigger device instead. */
  gboolean (*trigger) (gpointer backend, GError **error);
  /* Next complete frame, or an error within timeout_ms: TIMEOUT, INCOMPLETE (a buffer with
   * missing packets: it is returned to the pool before this returns), DISCONNECTED. */
  DsFrame *(*grab) (gpointer backend, guint timeout_ms, GError **error);
  /* Drops every frame already delivered but not grabbed (stale buffers), returning them to
   * the pool. Non-blocking. Returns how many were dropped. */
  guint (*flush) (gpointer backend);
  /* Stops acquisition. Never fails visibly (a lost camera is already stopped). */
  void (*stop) (gpointer backend);
  /* Reopens after DISCONNECTED, reapplying the last settings; the caller decides when and
   * how often (backoff lives in the sequencer). Blocks up to a few seconds. */
  gboolean (*reconnect) (gpointer backend, GError **error);
  void (*get_stats) (gpointer backend, DsCameraStats *stats);
  void (*get_info) (gpointer backend, DsCameraInfo *info);
  /* Stops if needed and frees everything. */
  void (*close) (gpointer backend);
  /* How many frames the camera has begun sending since it was opened (a count that only
   * grows), waiting up to timeout_ms for it to exceed `after` (0: no wait). A camera begins
   * sending a frame once it has read the sensor out, so its exposure is over: the sequencer
   * moves the illuminator to the next phase then, during the transfer (docs/design.md, "The
   * pipeline"). Blocks at most timeout_ms; never fails (a lost camera's count stops growing).
   * NULL: the backend cannot tell, and the illuminator moves only after grab returned. */
  guint64 (*frames_begun) (gpointer backend, guint64 after, guint timeout_ms);
};

/* Convenience wrappers so callers read as ds_camera_grab (cam, ...). */
void ds_camera_close (DsCamera *camera); /* NULL-safe; frees the DsCamera itself */
G_DEFINE_AUTOPTR_CLEANUP_FUNC (DsCamera, ds_camera_close)

G_END_DECLS
