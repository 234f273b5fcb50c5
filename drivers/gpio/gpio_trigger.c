#include "drivers/gpio/gpio_trigger.h"

typedef struct {
  DsGpioLines *line;
  guint pulse_us;
  int active, idle;
  gboolean reopen;         /* the line request was lost: request it again before the next pulse */
} GpioTrigger;

static gboolean
set_level (GpioTrigger *t, int level, GError **error)
{
  GError *io = NULL;
  if (!ds_gpio_lines_set (t->line, &level, &io)) {
    DsDeviceError code = ds_gpio_device_error_code (io);
    t->reopen = code == DS_DEVICE_ERROR_DISCONNECTED || code == DS_DEVICE_ERROR_TIMEOUT;
    ds_gpio_propagate_error (error, io, DS_TRIGGER_ERROR);
    g_prefix_error (error, "GPIO trigger line %u: ", t->line->offsets[0]);
    return FALSE;
  }
  return TRUE;
}

static gboolean
gpio_fire (gpointer backend, GError **error)
{
  GpioTrigger *t = backend;
  /* The trigger interface has no reconnect op (the sequencer reconnects camera and illuminator):
   * a trigger whose chip went away requests its line again here, at the idle level, so the set
   * after the chip comes back pulses normally. */
  if (t->reopen) {
    GError *io = NULL;
    if (!ds_gpio_lines_reopen (t->line, &io)) {
      ds_gpio_propagate_error (error, io, DS_TRIGGER_ERROR);
      g_prefix_error (error, "GPIO trigger line %u: requesting it again: ", t->line->offsets[0]);
      return FALSE;
    }
    t->reopen = FALSE;
    if (!set_level (t, t->idle, error))
      return FALSE;
  }
  if (!set_level (t, t->active, error))
    return FALSE;
  g_usleep (t->pulse_us);
  /* The line must not stay active: if going back fails, say so (the camera may re-trigger). */
  if (!set_level (t, t->idle, error)) {
    g_prefix_error (error, "pulse end: ");
    return FALSE;
  }
  return TRUE;
}

static void
gpio_trigger_close (gpointer backend)
{
  GpioTrigger *t = backend;
  ds_gpio_lines_free (t->line);
  g_free (t);
}

static const DsTriggerOps gpio_trigger_ops = {
  .name = "gpio",
  .fire = gpio_fire,
  .close = gpio_trigger_close,
};

DsTrigger *
ds_gpio_trigger_new (DsGpioLines *line, guint pulse_us, gboolean active_low, GError **error)
{
  if (!line || line->n_lines != 1 || pulse_us < 1 || pulse_us > 1000000) {
    g_set_error (error, DS_TRIGGER_ERROR, DS_DEVICE_ERROR_INVALID,
                 "GPIO trigger: expected one line and a pulse of 1..1000000 us (got %u lines, %u us)",
                 line ? line->n_lines : 0, pulse_us);
    ds_gpio_lines_free (line);
    return NULL;
  }
  GpioTrigger *t = g_new0 (GpioTrigger, 1);
  t->line = line;
  t->pulse_us = pulse_us;
  t->active = active_low ? 0 : 1;
  t->idle = 1 - t->active;
  /* Idle level now, whatever the line was requested with. */
  if (!set_level (t, t->idle, error)) {
    gpio_trigger_close (t);
    return NULL;
  }
  DsTrigger *trig = g_new0 (DsTrigger, 1);
  trig->ops = &gpio_trigger_ops;
  trig->backend = t;
  return trig;
}
