/* Error domains of the device interfaces: one per device kind, stable codes (never renumber;
 * add at the end). The sequencer decides on retry/reconnect/fail from the code alone, so a
 * backend must map its library's failures onto these faithfully. */
#pragma once
#include <glib.h>

G_BEGIN_DECLS

#define DS_CAMERA_ERROR (ds_camera_error_quark ())
#define DS_ILLUMINATOR_ERROR (ds_illuminator_error_quark ())
#define DS_TRIGGER_ERROR (ds_trigger_error_quark ())
GQuark ds_camera_error_quark (void);
GQuark ds_illuminator_error_quark (void);
GQuark ds_trigger_error_quark (void);

/* Shared by the three domains so that the sequencer's policy is one switch. */
typedef enum {
  DS_DEVICE_ERROR_TIMEOUT = 1,      /* no answer/frame within the deadline: retry may help */
  DS_DEVICE_ERROR_INCOMPLETE = 2,   /* frame with missing packets, short read: retry may help */
  DS_DEVICE_ERROR_DISCONNECTED = 3, /* link lost: reconnect before anything else */
  DS_DEVICE_ERROR_INVALID = 4,      /* bad argument or configuration: retry will not help */
  DS_DEVICE_ERROR_BUSY = 5,         /* device not ready (e.g. illuminator still applying) */
  DS_DEVICE_ERROR_FAULT = 6,        /* the device reports a fault (over-temperature, exception) */
  DS_DEVICE_ERROR_UNSUPPORTED = 7,  /* the device lacks a feature the configuration asks for */
} DsDeviceError;

const char *ds_device_error_name (DsDeviceError code);
/* TRUE for the codes where retrying the same operation can succeed. */
gboolean ds_device_error_is_transient (const GError *error);

G_END_DECLS
