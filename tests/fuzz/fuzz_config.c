/* Fuzz target: the configuration parser. Any text yields a configuration or an error naming
 * the place; an accepted configuration prints and re-parses to the same configuration. */
#include <stdint.h>
#include <string.h>

#include "daemon/config/config.h"

int LLVMFuzzerTestOneInput (const uint8_t *data, size_t size);

int
LLVMFuzzerTestOneInput (const uint8_t *data, size_t size)
{
  g_autofree char *text = g_strndup ((const char *) data, size);
  GError *error = NULL;
  DsConfig *c = ds_config_load_data (text, "fuzz.conf", &error);
  if (!c) {
    g_assert (error && error->message && *error->message);
    g_error_free (error);
    return 0;
  }
  g_autofree char *printed = ds_config_to_data (c);
  DsConfig *again = ds_config_load_data (printed, "printed.conf", &error);
  g_assert (again != NULL);
  g_autofree char *printed2 = ds_config_to_data (again);
  g_assert (strcmp (printed, printed2) == 0);
  ds_config_free (again);
  ds_config_free (c);
  return 0;
}
