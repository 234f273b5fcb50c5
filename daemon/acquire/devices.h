/* The devices the acquisition thread drives, opened from the configuration. Which backend sits
 * behind each interface is decided here and nowhere else: the sequencer only sees the ops.
 *
 * Threads: ds_devices_open and ds_devices_close run on the acquisition thread (opening may
 * block for seconds: device discovery, the simulator's scattering kernels). */
#pragma once
#include <glib.h>

#include "daemon/config/config.h"
#include "daemon/operating/pattern_knowledge.h"
#include "drivers/core/camera.h"
#include "drivers/core/illuminator.h"
#include "drivers/core/trigger.h"

G_BEGIN_DECLS

typedef struct {
  DsCamera *camera;
  DsIlluminator *illuminator;
  DsTrigger *trigger;
  DsCameraSettings camera_settings; /* from [camera]; exposure/gain overridden per set */
  DsStripePattern pattern;          /* from [illuminator]; n_phases set per set */
  /* The simulated illuminator's pattern as a calibration would measure it (devices.c): it
   * replaces [illuminator] black-level, harmonic-gain and edge-blur-px as `pattern` replaces the
   * pattern keys. FALSE: the configuration's (ds_capture_settings_take_illuminator) */
  gboolean pattern_known;
  DsPatternKnowledge known;
  guint grab_timeout_ms;
  guint settle_timeout_ms;
  gboolean sends_after_exposure;    /* [camera]: the next phase may be applied once a frame's
                                     * transfer began (camera ops->frames_begun) */
  char *description;                /* "camera=sim illuminator=sim trigger=software" */
  gpointer owner;                   /* backend state shared by several devices (the sim lab) */
  GDestroyNotify free_owner;
} DsDevices;

DsDevices *ds_devices_open (const DsConfig *config, GError **error);
/* The settings the camera is configured with for a set exposed for exposure_us at gain_db:
 * [camera]'s, with the set's exposure and gain. The sequencer and the rate benchmark's
 * ceiling (tests/bench/daemon_rate.c) both configure the camera from this. */
void ds_devices_camera_settings (const DsDevices *devices, double exposure_us, double gain_db,
                                 DsCameraSettings *out);
void ds_devices_close (DsDevices *devices);
G_DEFINE_AUTOPTR_CLEANUP_FUNC (DsDevices, ds_devices_close)

G_END_DECLS
