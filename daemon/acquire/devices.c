/* The devices opened from the configuration: which backend (Aravis, Modbus, GPIO, simulated
 * lab, built-in scene) stands behind each interface. Runs on the acquisition thread (opening
 * may block on the network); fails with the backend's error when a device does not open. */
#include "daemon/acquire/devices.h"

#include <string.h>

#include "drivers/aravis/aravis_camera.h"
#include "drivers/core/projector_sync.h"
#include "drivers/modbus/modbus_illuminator.h"
#include "drivers/sim/renderer.h"
#include "drivers/sim/scene.h"
#include "drivers/simdev/sim_lab.h"
#include "drivers/gpio/gpio_backends.h"
#include "daemon/acquire/default_scene.h"

static gboolean
parse_roi (const char *roi, DsCameraSettings *cs, GError **error)
{
  guint v[4];
  if (!roi || !*roi)
    return TRUE;
  if (!ds_config_parse_roi (roi, v, error))
    return FALSE;
  cs->roi_x = v[0];
  cs->roi_y = v[1];
  cs->roi_width = v[2];
  cs->roi_height = v[3];
  return TRUE;
}

/* The simulated illuminator can only project what the scene declares: its geometry replaces
 * the configuration's [illuminator] pattern keys. Its blur and how its pixels see it are exact
 * too: they reach the probe and the sets as a calibration's lines would, through the record a
 * noise-free `descatterctl calibrate` on a clear reference would give
 * (daemon/operating/pattern_knowledge.h), so that --sim is never less informed than a rig, and
 * never more: the scene's medium and objects are not read. */
static void
pattern_from_scene (const DsScene *scene, DsStripePattern *p, DsPatternKnowledge *known)
{
  p->kind = ds_scene_pattern_is_sine (scene) ? DS_STRIPES_SINE : DS_STRIPES_SQUARE;
  p->period_px = ds_scene_period_px (scene);
  p->duty = ds_scene_duty (scene);
  p->black_level = ds_scene_black_level (scene);
  double w = ds_scene_pattern_aperture_px (scene);
  DsStripeModel g = { .kind = ds_scene_pattern_is_sine (scene) ? DS_PATTERN_SINE : DS_PATTERN_SQUARE,
                      .period_px = p->period_px, .duty = p->duty, .black_level = p->black_level,
                      .blur_px = ds_scene_edge_blur_px (scene),
                      .pixel_aperture = w > 0 ? w : DS_STRIPE_POINT_APERTURE };
  ds_pattern_knowledge_from_geometry (&g, known);
  known->open_field_dn_per_ms = ds_scene_open_field_dn_per_ms (scene);
  /* The simulated lens's cone, as a rig's user knows theirs ([camera] acceptance-half-angle-deg). */
  known->acceptance_half_angle_deg = ds_scene_spec (scene)->acceptance_half_angle_deg;
}

static DsSimLab *
open_sim_lab (const DsConfig *config, DsStripePattern *pattern, DsPatternKnowledge *known, GError **error)
{
  /* Faults first: an opening stretched by open-delay-ms comes before whatever fails it. */
  DsSimFaults faults;
  if (!ds_sim_faults_parse (config->sim_faults, &faults, error)) {
    g_prefix_error (error, "[sim] ");
    return NULL;
  }
  if (faults.open_delay_ms)
    g_usleep ((gulong) faults.open_delay_ms * 1000);
  g_autoptr (DsScene) scene = NULL;
  if (config->sim_scene && *config->sim_scene)
    scene = ds_scene_load (config->sim_scene, error);
  else
    scene = ds_scene_load_data (ds_default_scene_text, strlen (ds_default_scene_text),
                                "built-in scene (" DS_DEFAULT_SCENE_NAME ")", error);
  if (!scene)
    return NULL;
  pattern_from_scene (scene, pattern, known);
  /* The unit sets DESCATTER_CACHE_DIR (systemd CacheDirectory=): scattering kernels survive
   * restarts there. */
  DsRenderer *renderer = ds_renderer_new (scene, g_getenv ("DESCATTER_CACHE_DIR"), error);
  if (!renderer)
    return NULL;
  DsSimLab *lab = ds_sim_lab_new (renderer, config->sim_seed);
  ds_sim_lab_set_faults (lab, &faults);
  ds_sim_lab_set_any_pattern (lab, config->sim_geometry && strcmp (config->sim_geometry, "config") == 0);
  return lab;
}

DsDevices *
ds_devices_open (const DsConfig *config, GError **error)
{
  g_autoptr (DsDevices) dev = g_new0 (DsDevices, 1);
  DsSimLab *lab = NULL;
  DsStripePattern scene_pattern = { 0 };
  DsPatternKnowledge scene_known = { 0 };
  gboolean want_lab = strcmp (config->camera_backend, "sim") == 0 ||
                      strcmp (config->illuminator_backend, "sim") == 0;
  if (want_lab) {
    lab = open_sim_lab (config, &scene_pattern, &scene_known, error);
    if (!lab) {
      g_prefix_error (error, "simulated lab: ");
      return NULL;
    }
    dev->owner = lab;
    dev->free_owner = (GDestroyNotify) ds_sim_lab_unref;
  }
  if (strcmp (config->camera_backend, "sim") == 0)
    dev->camera = ds_sim_camera_new (lab);
  else {
    DsAravisStreamOptions o = DS_ARAVIS_STREAM_OPTIONS_DEFAULT;
    o.receive_buffer_frames = config->receive_buffer_frames;
    o.frame_retention_ms = config->frame_retention_ms;
    dev->camera = ds_aravis_camera_open_with (config->camera_address, &o, error);
  }
  if (!dev->camera) {
    g_prefix_error (error, "[camera] backend=%s: ", config->camera_backend);
    return NULL;
  }
  if (strcmp (config->illuminator_backend, "sim") == 0)
    dev->illuminator = ds_sim_illuminator_new (lab);
  else if (strcmp (config->illuminator_backend, "modbus") == 0) {
    dev->illuminator = ds_modbus_illuminator_open (config->modbus_uri, config->modbus_unit_id,
                                                   config->modbus_timeout_ms, error);
  }
  else {
    dev->illuminator = ds_gpio_illuminator_open_from_config (config->gpio_chip, config->gpio_lines,
                                                             config->gpio_enable_line, error);
  }
  if (!dev->illuminator) {
    g_prefix_error (error, "[illuminator] backend=%s: ", config->illuminator_backend);
    return NULL;
  }
  if (strcmp (config->trigger_backend, "gpio") == 0) {
    dev->trigger = ds_gpio_trigger_open_from_config (config->gpio_chip, config->trigger_gpio_line,
                                                     config->trigger_pulse_us,
                                                     config->trigger_active_low, error);
    if (!dev->trigger) {
      g_prefix_error (error, "[trigger] backend=gpio: ");
      return NULL;
    }
  } else if (strcmp (config->trigger_backend, "projector-sync") == 0)
    /* Applying a phase is the trigger: the illuminator is wrapped so each fire is one apply. */
    dev->illuminator = ds_projector_sync_wrap (dev->illuminator, &dev->trigger);
  else
    dev->trigger = ds_software_trigger_new (dev->camera);

  DsCameraSettings *cs = &dev->camera_settings;
  cs->exposure_us = config->exposure_us;
  cs->gain_db = config->gain_db;
  g_strlcpy (cs->pixel_format, config->pixel_format, sizeof cs->pixel_format);
  if (!parse_roi (config->roi, cs, error))
    return NULL;
  if (g_str_has_prefix (config->camera_trigger, "line")) {
    cs->trigger_source = DS_CAMERA_TRIGGER_LINE;
    cs->trigger_line = (guint) g_ascii_strtoull (config->camera_trigger + 4, NULL, 10);
  } else
    cs->trigger_source = DS_CAMERA_TRIGGER_SOFTWARE;
  dev->pattern.kind = strcmp (config->pattern, "sine") == 0 ? DS_STRIPES_SINE : DS_STRIPES_SQUARE;
  dev->pattern.period_px = config->period_px;
  dev->pattern.duty = config->duty;
  dev->pattern.black_level = config->black_level;
  dev->pattern.intensity = config->intensity;
  dev->pattern.n_phases = config->phases;
  if (strcmp (config->illuminator_backend, "sim") == 0 &&
      !(config->sim_geometry && strcmp (config->sim_geometry, "config") == 0)) {
    dev->pattern.kind = scene_pattern.kind;
    dev->pattern.period_px = scene_pattern.period_px;
    dev->pattern.duty = scene_pattern.duty;
    dev->pattern.black_level = scene_pattern.black_level;
    dev->pattern_known = TRUE;
    dev->known = scene_known;
  }
  dev->grab_timeout_ms = config->grab_timeout_ms;
  dev->settle_timeout_ms = config->settle_timeout_ms;
  dev->sends_after_exposure = config->sends_after_exposure;
  dev->description = g_strdup_printf ("camera=%s illuminator=%s trigger=%s",
                                      config->camera_backend, config->illuminator_backend,
                                      config->trigger_backend);
  return g_steal_pointer (&dev);
}
