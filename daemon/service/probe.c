#include "daemon/service/probe.h"

#include <math.h>
#include <string.h>

#include "daemon/acquire/capture_settings.h"
#include "daemon/config/config.h"
#include "daemon/acquire/devices.h"
#include "daemon/acquire/sequencer.h"

typedef struct {
  gboolean opened;
  GError *error; /* opening failed */
} ProbeState;

static DsDevices *
open_devices (gpointer data, GError **error)
{
  return ds_devices_open (data, error);
}

static void
on_event (const DsSequencerEvent *ev, gpointer data)
{
  ProbeState *st = data;
  /* A refusal is in the status read afterwards; the other events say nothing new here. */
  if (ev->kind == DS_SEQUENCER_EVENT_READY) {
    st->opened = TRUE;
    if (ev->error)
      st->error = g_error_copy (ev->error);
  }
}

static void
print_camera (const DsConfig *c, const DsCameraInfo *i, FILE *out)
{
  fprintf (out, "camera: %s (%s)\n", c->camera_backend, i->address);
  fprintf (out, "  vendor %s, model %s, serial %s\n", *i->vendor ? i->vendor : "(none)",
           *i->model ? i->model : "(none)", *i->serial ? i->serial : "(none)");
  fprintf (out, "  sensor %ux%u\n", i->sensor_width, i->sensor_height);
  fprintf (out, "  pixel formats offered: %s (configured pixel-format=%s)\n",
           *i->pixel_formats ? i->pixel_formats : "any (not listed)", c->pixel_format);
  if (i->has_gain)
    fprintf (out, "  gain range: %g .. %g dB (configured gain-db=%g)\n", i->gain_min_db, i->gain_max_db,
             c->gain_db);
  else
    fprintf (out, "  gain: none (configured gain-db=%g)\n", c->gain_db);
  if (i->exposure_max_us > 0)
    fprintf (out, "  exposure range: %g .. %g µs (configured exposure-us=%g)\n", i->exposure_min_us,
             i->exposure_max_us, c->exposure_us);
}

static void
print_illuminator (const DsConfig *c, const DsIlluminatorStatus *s, FILE *out)
{
  if (strcmp (c->illuminator_backend, "modbus") == 0)
    fprintf (out, "illuminator: modbus %s unit %u\n", c->modbus_uri, c->modbus_unit_id);
  else if (strcmp (c->illuminator_backend, "gpio") == 0)
    fprintf (out, "illuminator: gpio %s lines %s\n", c->gpio_chip, c->gpio_lines);
  else
    fprintf (out, "illuminator: %s\n", c->illuminator_backend);
  fprintf (out, "  firmware %u.%u, %s%s%s%s\n", s->firmware_version >> 8, s->firmware_version & 0xff,
           s->ready ? "ready" : "not ready", s->enabled ? ", lit" : ", dark", s->fault ? ", FAULT" : "",
           s->over_temperature ? ", OVER TEMPERATURE" : "");
  fprintf (out, "  patterns applied since power-up %" G_GUINT64_FORMAT, s->apply_count);
  if (!isnan (s->temperature_c))
    fprintf (out, ", temperature %.1f °C", s->temperature_c);
  fprintf (out, "\n");
}

gboolean
ds_probe_run (const DsPreflight *pf, FILE *out, GError **error)
{
  DsCaptureSettings defaults;
  ds_capture_settings_from_config (&defaults, pf->config);
  g_autoptr (GMainContext) ctx = g_main_context_new ();
  ProbeState st = { 0 };
  /* The acquisition thread opens the devices and applies the settings: the very code the
   * daemon runs at start (and again after a reconnect, a reload, acquire). */
  DsSequencer *seq = ds_sequencer_new (open_devices, pf->config, &defaults, ctx, on_event, &st);
  while (!st.opened)
    g_main_context_iteration (ctx, TRUE);
  DsSequencerStatus s;
  ds_sequencer_get_status (seq, &s);
  ds_sequencer_free (seq);
  if (st.error) {
    g_propagate_prefixed_error (error, st.error, "opening the devices: ");
    return FALSE;
  }
  print_camera (pf->config, &s.camera_info, out);
  print_illuminator (pf->config, &s.illuminator, out);
  fprintf (out, "trigger: %s (camera trigger %s)\n", pf->config->trigger_backend, pf->config->camera_trigger);
  fflush (out);
  if (!s.settings_ok) {
    g_set_error (error, DS_CONFIG_ERROR, DS_CONFIG_ERROR_BAD_VALUE, "the devices refuse the configured settings: %s",
                 s.settings_error);
    return FALSE;
  }
  /* Read when the devices opened, before any write of ours: a controller that is not idle
   * then (stuck applying, faulted, too hot) would fail the first phase of every set. */
  if (s.illuminator.fault || s.illuminator.over_temperature || !s.illuminator.ready) {
    g_set_error (error, DS_CONFIG_ERROR, DS_CONFIG_ERROR_BAD_VALUE, "the illuminator reports %s",
                 s.illuminator.fault              ? "a driver fault"
                 : s.illuminator.over_temperature ? "over-temperature"
                                                  : "not ready (busy applying a pattern) while idle");
    return FALSE;
  }
  return TRUE;
}
