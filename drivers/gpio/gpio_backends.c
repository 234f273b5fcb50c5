#include "drivers/gpio/gpio_backends.h"

#include <string.h>

#include "drivers/gpio/gpio_lines_socket.h"
#include "drivers/gpio/gpio_wire.h"

DsGpioLines *
ds_gpio_lines_open (const char *chip, const guint *offsets, guint n_lines, const int *initial,
                    const char *consumer, GError **error)
{
  if (!g_str_has_prefix (chip, DS_GPIO_WIRE_CHIP_PREFIX))
    return ds_gpio_lines_request (chip, offsets, n_lines, initial, consumer, error);
  const char *path = chip + strlen (DS_GPIO_WIRE_CHIP_PREFIX);
  if (!g_path_is_absolute (path)) {
    g_set_error (error, G_IO_ERROR, G_IO_ERROR_INVALID_ARGUMENT,
                 "GPIO chip \"%s\": expected %s followed by the absolute path of descatter-labsim's "
                 "--gpio-chip socket", chip, DS_GPIO_WIRE_CHIP_PREFIX);
    return NULL;
  }
  return ds_gpio_lines_request_socket (chip, path, offsets, n_lines, initial, consumer, error);
}

DsIlluminator *
ds_gpio_illuminator_open_from_config (const char *chip, const char *lines, int enable_line,
                                      GError **error)
{
  guint offsets[DS_GPIO_MAX_LINES], n = 0;
  GError *io = NULL;
  if (!chip || !*chip) {
    g_set_error (error, DS_ILLUMINATOR_ERROR, DS_DEVICE_ERROR_INVALID, "GPIO illuminator: no chip given");
    return NULL;
  }
  if (!ds_gpio_parse_offsets (lines, offsets, &n, &io)) {
    ds_gpio_propagate_error (error, io, DS_ILLUMINATOR_ERROR);
    return NULL;
  }
  for (guint i = 0; enable_line >= 0 && i < n; i++)
    if (offsets[i] == (guint) enable_line) {
      g_set_error (error, DS_ILLUMINATOR_ERROR, DS_DEVICE_ERROR_INVALID,
                   "GPIO illuminator: enable line %d is also a stripe line", enable_line);
      return NULL;
    }
  DsGpioLines *stripes = ds_gpio_lines_open (chip, offsets, n, NULL, "descatter-stripes", &io);
  if (!stripes) {
    ds_gpio_propagate_error (error, io, DS_ILLUMINATOR_ERROR);
    return NULL;
  }
  DsGpioLines *enable = NULL;
  if (enable_line >= 0) {
    guint e = (guint) enable_line;
    enable = ds_gpio_lines_open (chip, &e, 1, NULL, "descatter-enable", &io);
    if (!enable) {
      ds_gpio_lines_free (stripes);
      ds_gpio_propagate_error (error, io, DS_ILLUMINATOR_ERROR);
      return NULL;
    }
  }
  return ds_gpio_illuminator_new (stripes, enable, error);
}

DsTrigger *
ds_gpio_trigger_open_from_config (const char *chip, int line, guint pulse_us, gboolean active_low,
                                  GError **error)
{
  if (!chip || !*chip || line < 0) {
    g_set_error (error, DS_TRIGGER_ERROR, DS_DEVICE_ERROR_INVALID, "GPIO trigger: chip and line required");
    return NULL;
  }
  guint off = (guint) line;
  int idle = active_low ? 1 : 0;
  GError *io = NULL;
  DsGpioLines *l = ds_gpio_lines_open (chip, &off, 1, &idle, "descatter-trigger", &io);
  if (!l) {
    ds_gpio_propagate_error (error, io, DS_TRIGGER_ERROR);
    return NULL;
  }
  return ds_gpio_trigger_new (l, pulse_us, active_low, error);
}
