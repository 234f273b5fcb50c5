/* The device-error domain's policy and the one table from internal errors to wire codes
 * (issue 10: device failures reached clients as `failed` and rejected frames as
 * `device_error`, the reverse of docs/protocol.md). The expectations are docs/protocol.md's
 * table and docs/design.md's policy table, written out here independently of the code. */
#include <gio/gio.h>

#include "daemon/config/config.h"
#include "daemon/acquire/sequencer.h"
#include "daemon/operating/operating_error.h"
#include "daemon/service/wire_error.h"
#include "drivers/core/device_error.h"
#include "proc/proc_error.h"

static void
test_policy (void)
{
  const struct { DsDeviceError code; DsDevicePolicy policy; } table[] = {
    { DS_DEVICE_ERROR_TIMEOUT, DS_DEVICE_POLICY_RETRY },
    { DS_DEVICE_ERROR_INCOMPLETE, DS_DEVICE_POLICY_RETRY },
    { DS_DEVICE_ERROR_BUSY, DS_DEVICE_POLICY_RETRY },
    { DS_DEVICE_ERROR_FAULT, DS_DEVICE_POLICY_RETRY },
    { DS_DEVICE_ERROR_DISCONNECTED, DS_DEVICE_POLICY_RECONNECT },
    { DS_DEVICE_ERROR_INVALID, DS_DEVICE_POLICY_FAIL },
    { DS_DEVICE_ERROR_UNSUPPORTED, DS_DEVICE_POLICY_FAIL },
  };
  for (guint i = 0; i < G_N_ELEMENTS (table); i++) {
    g_autoptr (GError) e = g_error_new (DS_DEVICE_ERROR, table[i].code, "x");
    g_assert_cmpint (ds_device_error_policy (e), ==, table[i].policy);
    g_assert_true (ds_device_error_is_transient (e) == (table[i].policy == DS_DEVICE_POLICY_RETRY));
    /* A prefix added on the way up keeps domain and code, hence the policy. */
    g_prefix_error (&e, "phase 3: camera: ");
    g_assert_cmpint (ds_device_error_policy (e), ==, table[i].policy);
  }
  /* Unknown codes and other domains are never retried blindly. */
  g_autoptr (GError) unknown = g_error_new (DS_DEVICE_ERROR, 99, "from a newer backend");
  g_assert_cmpint (ds_device_error_policy (unknown), ==, DS_DEVICE_POLICY_FAIL);
  g_autoptr (GError) io = g_error_new (G_IO_ERROR, G_IO_ERROR_TIMED_OUT, "x");
  g_assert_cmpint (ds_device_error_policy (io), ==, DS_DEVICE_POLICY_FAIL);
  g_assert_cmpint (ds_device_error_policy (NULL), ==, DS_DEVICE_POLICY_FAIL);
  /* The three device kinds share the one domain. */
  g_assert_true (DS_CAMERA_ERROR == DS_DEVICE_ERROR && DS_ILLUMINATOR_ERROR == DS_DEVICE_ERROR &&
                 DS_TRIGGER_ERROR == DS_DEVICE_ERROR);
}

static void
test_wire_codes (void)
{
  /* Every device failure, of every kind, is `device_error`. */
  for (int code = DS_DEVICE_ERROR_TIMEOUT; code <= DS_DEVICE_ERROR_UNSUPPORTED; code++) {
    GQuark kinds[] = { DS_CAMERA_ERROR, DS_ILLUMINATOR_ERROR, DS_TRIGGER_ERROR };
    for (guint k = 0; k < G_N_ELEMENTS (kinds); k++) {
      g_autoptr (GError) e = g_error_new (kinds[k], code, "device says no");
      g_prefix_error (&e, "phase 0: retries exhausted: ");
      g_assert_cmpstr (ds_protocol_error_name (ds_wire_error_code (e)), ==, "device_error");
    }
  }
  const struct { GQuark domain; int code; const char *wire; } table[] = {
    { DS_SEQUENCER_ERROR, DS_SEQUENCER_ERROR_FRAME_REJECTED, "failed" },
    { DS_SEQUENCER_ERROR, DS_SEQUENCER_ERROR_NOT_READY, "device_error" },
    { DS_CONFIG_ERROR, DS_CONFIG_ERROR_BAD_VALUE, "failed" },
    { DS_OPERATING_ERROR, DS_OPERATING_ERROR_PILOT_FRAMES, "bad_argument" },
    { DS_OPERATING_ERROR, DS_OPERATING_ERROR_NO_MODULATION, "device_error" },
    { DS_OPERATING_ERROR, DS_OPERATING_ERROR_CLIPPED, "device_error" },
    { DS_OPERATING_ERROR, DS_OPERATING_ERROR_NO_STRIPES, "failed" },
    { DS_OPERATING_ERROR, DS_OPERATING_ERROR_CONFIGURATION, "bad_argument" },
    { DS_OPERATING_ERROR, DS_OPERATING_ERROR_UNREACHABLE, "bad_argument" },
    { DS_PROC_ERROR, 1, "failed" },
    { G_IO_ERROR, G_IO_ERROR_CANCELLED, "cancelled" },
    { G_IO_ERROR, G_IO_ERROR_FAILED, "failed" },
    { G_FILE_ERROR, G_FILE_ERROR_NOSPC, "failed" },
    { DS_PROTOCOL_ERROR, DS_PROTOCOL_ERROR_CANCELLED, "cancelled" },
    { DS_PROTOCOL_ERROR, DS_PROTOCOL_ERROR_BUSY, "busy" },
    { DS_PROTOCOL_ERROR, DS_PROTOCOL_ERROR_BAD_ARGUMENT, "bad_argument" },
  };
  for (guint i = 0; i < G_N_ELEMENTS (table); i++) {
    g_autoptr (GError) e = g_error_new (table[i].domain, table[i].code, "why");
    g_assert_cmpstr (ds_protocol_error_name (ds_wire_error_code (e)), ==, table[i].wire);
    g_autoptr (GError) w = ds_wire_error_new (e);
    g_assert_true (w->domain == DS_PROTOCOL_ERROR);
    g_assert_cmpstr (w->message, ==, "why");
  }
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  g_test_add_func ("/wire-error/device-policy", test_policy);
  g_test_add_func ("/wire-error/codes", test_wire_codes);
  return g_test_run ();
}
