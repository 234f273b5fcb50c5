#include "drivers/core/device_error.h"

G_DEFINE_QUARK (ds-device-error-quark, ds_device_error)

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

DsDevicePolicy
ds_device_error_policy (const GError *error)
{
  if (!error || error->domain != DS_DEVICE_ERROR)
    return DS_DEVICE_POLICY_FAIL;
  switch ((DsDeviceError) error->code) {
  case DS_DEVICE_ERROR_TIMEOUT:
  case DS_DEVICE_ERROR_INCOMPLETE:
  case DS_DEVICE_ERROR_BUSY:
  case DS_DEVICE_ERROR_FAULT:
    return DS_DEVICE_POLICY_RETRY;
  case DS_DEVICE_ERROR_DISCONNECTED:
    return DS_DEVICE_POLICY_RECONNECT;
  case DS_DEVICE_ERROR_INVALID:
  case DS_DEVICE_ERROR_UNSUPPORTED:
    return DS_DEVICE_POLICY_FAIL;
  }
  /* A code this build does not know (a newer backend): retrying blindly could loop. */
  return DS_DEVICE_POLICY_FAIL;
}

const char *
ds_device_policy_name (DsDevicePolicy policy)
{
  switch (policy) {
  case DS_DEVICE_POLICY_RETRY:
    return "retry";
  case DS_DEVICE_POLICY_RECONNECT:
    return "reconnect";
  case DS_DEVICE_POLICY_FAIL:
    return "fail";
  }
  return "fail";
}

gboolean
ds_device_error_is_transient (const GError *error)
{
  return ds_device_error_policy (error) == DS_DEVICE_POLICY_RETRY;
}
