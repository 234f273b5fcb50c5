#include "drivers/core/device_error.h"

G_DEFINE_QUARK (ds-camera-error-quark, ds_camera_error)
G_DEFINE_QUARK (ds-illuminator-error-quark, ds_illuminator_error)
G_DEFINE_QUARK (ds-trigger-error-quark, ds_trigger_error)

const char *
ds_device_error_name (DsDeviceError code)
{
  switch (code) {
  case DS_DEVICE_ERROR_TIMEOUT:
    return "timeout";
  case DS_DEVICE_ERROR_INCOMPLETE:
    return "incomplete";
  case DS_DEVICE_ERROR_DISCONNECTED:
    return "disconnected";
  case DS_DEVICE_ERROR_INVALID:
    return "invalid";
  case DS_DEVICE_ERROR_BUSY:
    return "busy";
  case DS_DEVICE_ERROR_FAULT:
    return "fault";
  case DS_DEVICE_ERROR_UNSUPPORTED:
    return "unsupported";
  }
  return "unknown";
}

gboolean
ds_device_error_is_transient (const GError *error)
{
  if (!error || (error->domain != DS_CAMERA_ERROR && error->domain != DS_ILLUMINATOR_ERROR &&
                 error->domain != DS_TRIGGER_ERROR))
    return FALSE;
  switch ((DsDeviceError) error->code) {
  case DS_DEVICE_ERROR_TIMEOUT:
  case DS_DEVICE_ERROR_INCOMPLETE:
  case DS_DEVICE_ERROR_BUSY:
  case DS_DEVICE_ERROR_FAULT:
    return TRUE;
  default:
    return FALSE;
  }
}
