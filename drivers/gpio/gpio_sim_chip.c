#include "drivers/gpio/gpio_sim_chip.h"

#include <errno.h>
#include <string.h>

struct DsGpioSimChip {
  gint ref;
  char *name;
  guint n_lines;
  int *driven;             /* what was last written */
  int *stuck;              /* -1 or the level the line is stuck at */
  char **consumer;         /* NULL: free */
  GArray *writes;          /* DsGpioSimWrite */
  gboolean fail_armed, fail_sticky;
  guint fail_countdown;
  int fail_errno;
};

typedef struct {
  DsGpioSimChip *chip;
  guint n;
  guint offsets[DS_GPIO_MAX_LINES];
  gboolean released;
} SimLines;

DsGpioSimChip *
ds_gpio_sim_chip_new (const char *name, guint n_lines)
{
  DsGpioSimChip *c = g_new0 (DsGpioSimChip, 1);
  c->ref = 1;
  c->name = g_strdup (name);
  c->n_lines = n_lines;
  c->driven = g_new0 (int, n_lines);
  c->stuck = g_new (int, n_lines);
  for (guint i = 0; i < n_lines; i++)
    c->stuck[i] = -1;
  c->consumer = g_new0 (char *, n_lines);
  c->writes = g_array_new (FALSE, TRUE, sizeof (DsGpioSimWrite));
  return c;
}

DsGpioSimChip *
ds_gpio_sim_chip_ref (DsGpioSimChip *chip)
{
  chip->ref++;
  return chip;
}

void
ds_gpio_sim_chip_unref (DsGpioSimChip *c)
{
  if (!c || --c->ref > 0)
    return;
  for (guint i = 0; i < c->n_lines; i++)
    g_free (c->consumer[i]);
  g_free (c->consumer);
  g_free (c->driven);
  g_free (c->stuck);
  g_array_unref (c->writes);
  g_free (c->name);
  g_free (c);
}

static gboolean
sim_fail (DsGpioSimChip *c, const char *what, GError **error)
{
  if (!c->fail_armed)
    return FALSE;
  if (c->fail_countdown > 0) {
    c->fail_countdown--;
    return FALSE;
  }
  if (!c->fail_sticky)
    c->fail_armed = FALSE;
  g_set_error (error, G_IO_ERROR, g_io_error_from_errno (c->fail_errno), "GPIO %s: %s: %s", c->name,
               what, g_strerror (c->fail_errno));
  return TRUE;
}

static gboolean
sim_set (gpointer impl, const int *values, GError **error)
{
  SimLines *l = impl;
  DsGpioSimChip *c = l->chip;
  if (l->released) {
    g_set_error (error, G_IO_ERROR, G_IO_ERROR_CLOSED, "GPIO %s: lines released", c->name);
    return FALSE;
  }
  if (sim_fail (c, "setting the lines", error))
    return FALSE;
  DsGpioSimWrite w = { .time_us = g_get_monotonic_time (), .n_lines = l->n };
  for (guint i = 0; i < l->n; i++) {
    c->driven[l->offsets[i]] = values[i] ? 1 : 0;
    w.offsets[i] = l->offsets[i];
    w.values[i] = values[i] ? 1 : 0;
  }
  g_array_append_val (c->writes, w);
  return TRUE;
}

static gboolean
sim_get (gpointer impl, int *values, GError **error)
{
  SimLines *l = impl;
  if (l->released) {
    g_set_error (error, G_IO_ERROR, G_IO_ERROR_CLOSED, "GPIO %s: lines released", l->chip->name);
    return FALSE;
  }
  for (guint i = 0; i < l->n; i++)
    values[i] = ds_gpio_sim_chip_value (l->chip, l->offsets[i]);
  return TRUE;
}

static gboolean
sim_reopen (gpointer impl, GError **error)
{
  SimLines *l = impl;
  (void) error;
  /* The lines stay requested by us; a fresh request clears a one-shot failure. */
  l->released = FALSE;
  return TRUE;
}

static void
sim_free (gpointer impl)
{
  SimLines *l = impl;
  for (guint i = 0; i < l->n; i++)
    g_clear_pointer (&l->chip->consumer[l->offsets[i]], g_free);
  ds_gpio_sim_chip_unref (l->chip);
  g_free (l);
}

static const DsGpioLinesOps sim_ops = {
  .name = "sim",
  .set_values = sim_set,
  .get_values = sim_get,
  .reopen = sim_reopen,
  .free = sim_free,
};

DsGpioLines *
ds_gpio_sim_chip_request (DsGpioSimChip *c, const guint *offsets, guint n_lines, const int *initial,
                          const char *consumer, GError **error)
{
  for (guint i = 0; i < n_lines; i++) {
    if (offsets[i] >= c->n_lines) {
      g_set_error (error, G_IO_ERROR, G_IO_ERROR_NOT_FOUND, "GPIO %s: line %u beyond the chip's %u lines",
                   c->name, offsets[i], c->n_lines);
      return NULL;
    }
    if (c->consumer[offsets[i]]) {
      g_set_error (error, G_IO_ERROR, G_IO_ERROR_BUSY, "GPIO %s: line %u already requested by %s",
                   c->name, offsets[i], c->consumer[offsets[i]]);
      return NULL;
    }
  }
  SimLines *l = g_new0 (SimLines, 1);
  l->chip = ds_gpio_sim_chip_ref (c);
  l->n = MIN (n_lines, DS_GPIO_MAX_LINES);
  memcpy (l->offsets, offsets, l->n * sizeof *offsets);
  DsGpioLines *lines = ds_gpio_lines_new (&sim_ops, l, c->name, offsets, n_lines, error);
  if (!lines) {
    ds_gpio_sim_chip_unref (l->chip);
    g_free (l);
    return NULL;
  }
  for (guint i = 0; i < l->n; i++) {
    c->consumer[offsets[i]] = g_strdup (consumer ? consumer : "descatter");
    c->driven[offsets[i]] = initial && initial[i] ? 1 : 0;
  }
  return lines;
}

guint
ds_gpio_sim_chip_n_writes (const DsGpioSimChip *c)
{
  return c->writes->len;
}

const DsGpioSimWrite *
ds_gpio_sim_chip_get_write (const DsGpioSimChip *c, guint i)
{
  return i < c->writes->len ? &g_array_index (c->writes, DsGpioSimWrite, i) : NULL;
}

void
ds_gpio_sim_chip_clear_writes (DsGpioSimChip *c)
{
  g_array_set_size (c->writes, 0);
}

int
ds_gpio_sim_chip_value (const DsGpioSimChip *c, guint offset)
{
  if (offset >= c->n_lines)
    return -1;
  return c->stuck[offset] >= 0 ? c->stuck[offset] : c->driven[offset];
}

const char *
ds_gpio_sim_chip_consumer (const DsGpioSimChip *c, guint offset)
{
  return offset < c->n_lines ? c->consumer[offset] : NULL;
}

void
ds_gpio_sim_chip_fail_after (DsGpioSimChip *c, guint n_ok, int errno_value, gboolean sticky)
{
  c->fail_armed = TRUE;
  c->fail_countdown = n_ok;
  c->fail_errno = errno_value;
  c->fail_sticky = sticky;
}

void
ds_gpio_sim_chip_clear_failure (DsGpioSimChip *c)
{
  c->fail_armed = FALSE;
}

void
ds_gpio_sim_chip_stick_line (DsGpioSimChip *c, guint offset, int value)
{
  if (offset < c->n_lines)
    c->stuck[offset] = value;
}
