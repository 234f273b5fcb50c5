#include "rate_ceiling.h"

#include <gio/gio.h>
#include <math.h>
#include <stdio.h>
#include <string.h>
#include <unistd.h>

#include "daemon/acquire/capture_settings.h"
#include "daemon/config/config.h"
#include "daemon/acquire/devices.h"

/* The loop, configured as the sequencer configures the devices for a set with the
 * configuration's defaults (ds_devices_open, ds_devices_camera_settings, the camera's configure
 * and start, the illuminator's set_pattern). Each frame goes back to the camera at once. A
 * trigger without a frame is fired again, as the daemon does; an incomplete frame is not
 * counted. */
static gboolean
run_here (const char *conf_text, double seconds, gboolean with_phase, RateSample *out)
{
  g_autoptr (GError) e = NULL;
  g_autoptr (DsConfig) config = ds_config_load_data (conf_text, "rate benchmark", &e);
  g_autoptr (DsDevices) dev = config ? ds_devices_open (config, &e) : NULL;
  if (!dev) {
    fprintf (stderr, "ceiling: %s\n", e->message);
    return FALSE;
  }
  DsCaptureSettings s;
  ds_capture_settings_from_config (&s, config);
  DsCameraSettings cs;
  ds_devices_camera_settings (dev, s.exposure_us, s.gain_db, &cs);
  DsCamera *cam = dev->camera;
  DsIlluminator *ill = dev->illuminator;
  if (!cam->ops->configure (cam->backend, &cs, &e) || !cam->ops->start (cam->backend, &e) ||
      (with_phase && !ill->ops->set_pattern (ill->backend, &dev->pattern, &e))) {
    fprintf (stderr, "ceiling: %s\n", e->message);
    return FALSE;
  }
  memset (out, 0, sizeof *out);
  guint64 frames = 0, k = 0;
  gint64 t0 = 0, end = 0;
  gboolean ok = TRUE;
  /* The CPU of this loop's threads and of the rig's (the parent: the benchmark, whose threads
   * are the fake camera and the Modbus controller) over the measured interval. */
  g_autoptr (ThreadCpu) self0 = NULL;
  g_autoptr (ThreadCpu) rig0 = NULL;
  /* The first frames warm up (socket buffers, page faults of the stream buffers). */
  for (guint i = 0; ok; i++) {
    if (i == 3) {
      self0 = thread_cpu_read (0);
      rig0 = thread_cpu_read (getppid ());
      t0 = g_get_monotonic_time ();
      end = t0 + (gint64) (seconds * 1e6);
      frames = 0;
      out->incomplete = out->lost = out->reconnects = 0;
    }
    if (t0 && g_get_monotonic_time () >= end)
      break;
    if (with_phase && !ill->ops->set_phase (ill->backend, (guint) (k++ % dev->pattern.n_phases),
                                            dev->settle_timeout_ms, &e)) {
      fprintf (stderr, "ceiling: set_phase: %s\n", e->message);
      ok = FALSE;
    } else if (!dev->trigger->ops->fire (dev->trigger->backend, &e)) {
      fprintf (stderr, "ceiling: trigger: %s\n", e->message);
      ok = FALSE;
    } else {
      DsFrame *f = cam->ops->grab (cam->backend, dev->grab_timeout_ms, &e);
      if (f) {
        frames++;
        ds_frame_free (f);
      } else if (g_error_matches (e, DS_DEVICE_ERROR, DS_DEVICE_ERROR_INCOMPLETE)) {
        out->incomplete++;
      } else if (g_error_matches (e, DS_DEVICE_ERROR, DS_DEVICE_ERROR_TIMEOUT) && out->lost < 10) {
        out->lost++;
      } else if (ds_device_error_policy (e) == DS_DEVICE_POLICY_RECONNECT && out->reconnects < 3) {
        /* The camera's heartbeat answered too late on a starved machine (control lost): the
         * daemon reconnects and configures again, so does the ceiling; the time counts. */
        out->reconnects++;
        g_clear_error (&e);
        cam->ops->stop (cam->backend);
        if (!cam->ops->reconnect (cam->backend, &e) || !cam->ops->configure (cam->backend, &cs, &e) ||
            !cam->ops->start (cam->backend, &e)) {
          fprintf (stderr, "ceiling: reconnect: %s\n", e->message);
          ok = FALSE;
        }
      } else {
        fprintf (stderr, "ceiling: grab: %s\n", e->message);
        ok = FALSE;
      }
      g_clear_error (&e);
    }
  }
  gint64 t1 = g_get_monotonic_time ();
  out->fps = frames / ((t1 - t0) / 1e6);
  out->from_us = t0;
  out->to_us = t1;
  out->frames = frames;
  g_autoptr (ThreadCpu) self1 = thread_cpu_read (0);
  g_autoptr (ThreadCpu) rig1 = thread_cpu_read (getppid ());
  thread_cpu_add_delta (&out->cpu, self0, self1);
  thread_cpu_add_delta (&out->rig_cpu, rig0, rig1);
  cam->ops->stop (cam->backend);
  return ok;
}

guint64
rate_udp_rcvbuf_errors (void)
{
  g_autofree char *text = NULL;
  if (!g_file_get_contents ("/proc/net/snmp", &text, NULL, NULL))
    return 0;
  /* Two "Udp:" lines: the names, then the values in the same order. */
  g_auto (GStrv) lines = g_strsplit (text, "\n", -1);
  for (guint i = 0; lines[i] && lines[i + 1]; i++) {
    if (!g_str_has_prefix (lines[i], "Udp: ") || !g_str_has_prefix (lines[i + 1], "Udp: "))
      continue;
    g_auto (GStrv) names = g_strsplit (lines[i], " ", -1);
    g_auto (GStrv) values = g_strsplit (lines[i + 1], " ", -1);
    for (guint k = 0; names[k] && values[k]; k++)
      if (strcmp (names[k], "RcvbufErrors") == 0)
        return g_ascii_strtoull (values[k], NULL, 10);
    break;
  }
  return 0;
}

int
rate_ceiling_main (int argc, char **argv)
{
  if (argc != 5 || strcmp (argv[1], "--ceiling") != 0)
    return -1;
  RateSample r;
  if (!run_here (argv[2], g_ascii_strtod (argv[3], NULL), strcmp (argv[4], "1") == 0, &r))
    return 1;
  g_autofree char *cpu = thread_cpu_totals_serialize (&r.cpu, "cpu");
  g_autofree char *rig_cpu = thread_cpu_totals_serialize (&r.rig_cpu, "rig");
  printf ("%.3f %u %u %u %" G_GUINT64_FORMAT " %" G_GINT64_FORMAT " %" G_GINT64_FORMAT "\n%s%s", r.fps,
          r.incomplete, r.lost, r.reconnects, r.frames, r.from_us, r.to_us, cpu, rig_cpu);
  return 0;
}

gboolean
rate_ceiling_measure (const char *self_path, const char *conf_text, double seconds,
                      gboolean with_phase, RateSample *out)
{
  g_autofree char *ss = g_strdup_printf ("%g", seconds);
  g_autoptr (GError) e = NULL;
  guint64 drops0 = rate_udp_rcvbuf_errors ();
  g_autoptr (GSubprocess) p = g_subprocess_new (G_SUBPROCESS_FLAGS_STDOUT_PIPE, &e, self_path,
                                                "--ceiling", conf_text, ss, with_phase ? "1" : "0",
                                                NULL);
  g_autofree char *text = NULL;
  if (!p || !g_subprocess_communicate_utf8 (p, NULL, NULL, &text, NULL, &e) ||
      !g_subprocess_get_successful (p)) {
    fprintf (stderr, "ceiling: %s\n", e ? e->message : "the loop failed");
    return FALSE;
  }
  memset (out, 0, sizeof *out);
  if (sscanf (text, "%lf %u %u %u %" G_GUINT64_FORMAT " %" G_GINT64_FORMAT " %" G_GINT64_FORMAT, &out->fps,
              &out->incomplete, &out->lost, &out->reconnects, &out->frames, &out->from_us, &out->to_us) != 7 ||
      !isfinite (out->fps)) {
    fprintf (stderr, "ceiling: unexpected answer \"%s\"\n", text);
    return FALSE;
  }
  out->rcvbuf_drops = rate_udp_rcvbuf_errors () - drops0;
  thread_cpu_totals_parse (&out->cpu, text, "cpu");
  thread_cpu_totals_parse (&out->rig_cpu, text, "rig");
  return TRUE;
}
