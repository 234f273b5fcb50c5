#include "drivers/gpio/gpio_lines.h"

#include <errno.h>
#include <gpiod.h>
#include <string.h>

DsGpioLines *
ds_gpio_lines_new (const DsGpioLinesOps *ops, gpointer impl, const char *chip,
                   const guint *offsets, guint n_lines, GError **error)
{
  if (n_lines == 0 || n_lines > DS_GPIO_MAX_LINES) {
    g_set_error (error, G_IO_ERROR, G_IO_ERROR_INVALID_ARGUMENT, "GPIO %s: %u lines (1..%u in one request)",
                 chip, n_lines, DS_GPIO_MAX_LINES);
    return NULL;
  }
  for (guint i = 0; i < n_lines; i++)
    for (guint j = 0; j < i; j++)
      if (offsets[i] == offsets[j]) {
        g_set_error (error, G_IO_ERROR, G_IO_ERROR_INVALID_ARGUMENT, "GPIO %s: line %u listed twice",
                     chip, offsets[i]);
        return NULL;
      }
  DsGpioLines *l = g_new0 (DsGpioLines, 1);
  l->ops = ops;
  l->impl = impl;
  l->n_lines = n_lines;
  memcpy (l->offsets, offsets, n_lines * sizeof *offsets);
  l->chip = g_strdup (chip);
  return l;
}

gboolean
ds_gpio_lines_set (DsGpioLines *lines, const int *values, GError **error)
{
  return lines->ops->set_values (lines->impl, values, error);
}

gboolean
ds_gpio_lines_get (DsGpioLines *lines, int *values, GError **error)
{
  return lines->ops->get_values (lines->impl, values, error);
}

gboolean
ds_gpio_lines_reopen (DsGpioLines *lines, GError **error)
{
  return lines->ops->reopen (lines->impl, error);
}

void
ds_gpio_lines_free (DsGpioLines *lines)
{
  if (!lines)
    return;
  if (lines->ops && lines->ops->free)
    lines->ops->free (lines->impl);
  g_free (lines->chip);
  g_free (lines);
}

DsDeviceError
ds_gpio_device_error_code (const GError *e)
{
  if (!e || e->domain != G_IO_ERROR)
    return DS_DEVICE_ERROR_FAULT;
  switch (e->code) {
  case G_IO_ERROR_BUSY:
    return DS_DEVICE_ERROR_BUSY;
  case G_IO_ERROR_INVALID_ARGUMENT:
    return DS_DEVICE_ERROR_INVALID;
  case G_IO_ERROR_TIMED_OUT: /* a chip across a socket that stopped answering (gpio_lines_socket.h) */
    return DS_DEVICE_ERROR_TIMEOUT;
  case G_IO_ERROR_NOT_FOUND:
  case G_IO_ERROR_CLOSED:
  case G_IO_ERROR_NO_SUCH_DEVICE:
    return DS_DEVICE_ERROR_DISCONNECTED;
  default:
    return DS_DEVICE_ERROR_FAULT;
  }
}

void
ds_gpio_propagate_error (GError **dest, GError *io_error, GQuark domain)
{
  g_set_error_literal (dest, domain, (int) ds_gpio_device_error_code (io_error), io_error->message);
  g_error_free (io_error);
}

gboolean
ds_gpio_parse_offsets (const char *list, guint *offsets, guint *n_lines, GError **error)
{
  *n_lines = 0;
  if (!list || !*list) {
    g_set_error (error, G_IO_ERROR, G_IO_ERROR_INVALID_ARGUMENT, "GPIO line list: empty");
    return FALSE;
  }
  g_auto (GStrv) parts = g_strsplit (list, ",", -1);
  for (guint i = 0; parts[i]; i++) {
    const char *p = g_strstrip (parts[i]);
    guint64 v = 0;
    if (!g_ascii_string_to_unsigned (p, 10, 0, 4095, &v, NULL)) {
      g_set_error (error, G_IO_ERROR, G_IO_ERROR_INVALID_ARGUMENT,
                   "GPIO line list \"%s\": element %u \"%s\" is not a line offset 0..4095", list, i + 1, p);
      return FALSE;
    }
    if (*n_lines == DS_GPIO_MAX_LINES) {
      g_set_error (error, G_IO_ERROR, G_IO_ERROR_INVALID_ARGUMENT,
                   "GPIO line list \"%s\": more than %u lines", list, DS_GPIO_MAX_LINES);
      return FALSE;
    }
    offsets[(*n_lines)++] = (guint) v;
  }
  return TRUE;
}

/* ---- libgpiod v1 -------------------------------------------------------------------------- */

typedef struct {
  struct gpiod_chip *chip;
  struct gpiod_line_bulk bulk;
  gboolean requested;
  char *chip_name, *consumer;
  guint n;
  unsigned int offsets[DS_GPIO_MAX_LINES];
  int last[DS_GPIO_MAX_LINES];
} Gpiod;

static void
gpiod_error (GError **error, const Gpiod *g, const char *what)
{
  int e = errno;
  g_set_error (error, G_IO_ERROR, g_io_error_from_errno (e), "GPIO %s: %s: %s", g->chip_name, what,
               g_strerror (e));
}

static gboolean
gpiod_request (Gpiod *g, const int *initial, GError **error)
{
  g->chip = gpiod_chip_open_lookup (g->chip_name);
  if (!g->chip) {
    gpiod_error (error, g, "cannot open the chip");
    return FALSE;
  }
  guint n_chip = gpiod_chip_num_lines (g->chip);
  for (guint i = 0; i < g->n; i++)
    if (g->offsets[i] >= n_chip) {
      g_set_error (error, G_IO_ERROR, G_IO_ERROR_NOT_FOUND, "GPIO %s: line %u beyond the chip's %u lines",
                   g->chip_name, g->offsets[i], n_chip);
      return FALSE;
    }
  gpiod_line_bulk_init (&g->bulk);
  if (gpiod_chip_get_lines (g->chip, g->offsets, g->n, &g->bulk) < 0) {
    gpiod_error (error, g, "cannot get the lines");
    return FALSE;
  }
  if (gpiod_line_request_bulk_output (&g->bulk, g->consumer, initial) < 0) {
    gpiod_error (error, g, "cannot request the lines as outputs");
    return FALSE;
  }
  g->requested = TRUE;
  return TRUE;
}

static void
gpiod_release (Gpiod *g)
{
  if (g->requested)
    gpiod_line_release_bulk (&g->bulk);
  g->requested = FALSE;
  if (g->chip)
    gpiod_chip_close (g->chip);
  g->chip = NULL;
}

static gboolean
gpiod_set (gpointer impl, const int *values, GError **error)
{
  Gpiod *g = impl;
  if (!g->requested || gpiod_line_set_value_bulk (&g->bulk, values) < 0) {
    if (!g->requested)
      errno = ENODEV;
    gpiod_error (error, g, "setting the lines");
    return FALSE;
  }
  memcpy (g->last, values, g->n * sizeof *values);
  return TRUE;
}

static gboolean
gpiod_get (gpointer impl, int *values, GError **error)
{
  Gpiod *g = impl;
  if (!g->requested || gpiod_line_get_value_bulk (&g->bulk, values) < 0) {
    if (!g->requested)
      errno = ENODEV;
    gpiod_error (error, g, "reading the lines back");
    return FALSE;
  }
  return TRUE;
}

static gboolean
gpiod_reopen (gpointer impl, GError **error)
{
  Gpiod *g = impl;
  gpiod_release (g);
  return gpiod_request (g, g->last, error);
}

static void
gpiod_free (gpointer impl)
{
  Gpiod *g = impl;
  gpiod_release (g);
  g_free (g->chip_name);
  g_free (g->consumer);
  g_free (g);
}

static const DsGpioLinesOps gpiod_ops = {
  .name = "gpiod",
  .set_values = gpiod_set,
  .get_values = gpiod_get,
  .reopen = gpiod_reopen,
  .free = gpiod_free,
};

DsGpioLines *
ds_gpio_lines_request (const char *chip, const guint *offsets, guint n_lines, const int *initial,
                       const char *consumer, GError **error)
{
  Gpiod *g = g_new0 (Gpiod, 1);
  g->chip_name = g_strdup (chip);
  g->consumer = g_strdup (consumer ? consumer : "descatter");
  g->n = MIN (n_lines, DS_GPIO_MAX_LINES);
  for (guint i = 0; i < g->n; i++) {
    g->offsets[i] = offsets[i];
    g->last[i] = initial ? initial[i] : 0;
  }
  DsGpioLines *l = ds_gpio_lines_new (&gpiod_ops, g, chip, offsets, n_lines, error);
  if (!l) {
    gpiod_free (g);
    return NULL;
  }
  if (!gpiod_request (g, g->last, error)) {
    ds_gpio_lines_free (l);
    return NULL;
  }
  return l;
}
