/* The device-error domain of the device interfaces: one domain for camera, illuminator and
 * trigger, with stable codes (never renumber; add at the end), and the one policy function
 * that says what a failure means for the sequencer (retry, reconnect, fail). A backend maps
 * its library's failures onto these codes faithfully; its message names the device and the
 * setting or register ("aravis camera: gain 12 dB outside [0, 10]").
 * How these errors reach clients (always as `device_error`) is decided in one table:
 * daemon/service/wire_error.c. */
#pragma once
#include <glib.h>

G_BEGIN_DECLS

#define DS_DEVICE_ERROR (ds_device_error_quark ())
GQuark ds_device_error_quark (void);

/* The same domain under the names the interfaces used when each kind had its own: the device
 * kind is in the message, the policy depends on the code alone. */
#define DS_CAMERA_ERROR DS_DEVICE_ERROR
#define DS_ILLUMINATOR_ERROR DS_DEVICE_ERROR
#define DS_TRIGGER_ERROR DS_DEVICE_ERROR

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

/* What a failed device operation calls for. */
typedef enum {
  DS_DEVICE_POLICY_RETRY = 0,     /* the same operation may succeed: retry, counted, up to
                                   * phase-retries (timeout, incomplete, busy, fault) */
  DS_DEVICE_POLICY_RECONNECT = 1, /* the device is gone: fail the set, reconnect before the next
                                   * operation (disconnected) */
  DS_DEVICE_POLICY_FAIL = 2,      /* retrying cannot help: fail the set now (invalid,
                                   * unsupported, and any error that is not a device error) */
} DsDevicePolicy;

DsDevicePolicy ds_device_error_policy (const GError *error);
const char *ds_device_policy_name (DsDevicePolicy policy);
/* ds_device_error_policy (error) == DS_DEVICE_POLICY_RETRY. */
gboolean ds_device_error_is_transient (const GError *error);

G_END_DECLS
