#include "daemon/service/provenance.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

void
ds_provenance_fill (DsResultProvenance *p, const DsConfig *config, const char *config_sha256,
                    const DsSequencerStatus *st)
{
  memset (p, 0, sizeof *p);
  g_strlcpy (p->program, "descatterd", sizeof p->program);
  g_strlcpy (p->config_sha256, config_sha256, sizeof p->config_sha256);
  g_strlcpy (p->camera_backend, config->camera_backend, sizeof p->camera_backend);
  g_strlcpy (p->illuminator_backend, config->illuminator_backend, sizeof p->illuminator_backend);
  g_strlcpy (p->trigger_backend, config->trigger_backend, sizeof p->trigger_backend);
  p->camera = st->camera_info;
  /* The simulated camera delivers the scene's sensor depth whatever the configuration asks. */
  g_strlcpy (p->pixel_format, ds_config_camera_pixel_format (config), sizeof p->pixel_format);
  /* devices.c refused a malformed ROI at start-up: this one parses. */
  guint v[4];
  if (config->roi && sscanf (config->roi, "%u,%u,%u,%u", &v[0], &v[1], &v[2], &v[3]) == 4) {
    p->roi_x = v[0];
    p->roi_y = v[1];
    p->roi_width = v[2];
    p->roi_height = v[3];
  }
  p->illuminator_temperature_c = st->illuminator.temperature_c;
  p->phase_offset_cycles = st->phase_offset_cycles;
  /* The configured pitch wins: it is what the user measured or read in the sensor's data sheet,
   * and binning the camera does not report changes it. */
  p->pixel_pitch_um = NAN;
  if (isfinite (config->pixel_pitch_um)) {
    p->pixel_pitch_um = config->pixel_pitch_um;
    g_strlcpy (p->pixel_pitch_source, "config", sizeof p->pixel_pitch_source);
  } else if (st->camera_info.pixel_pitch_um > 0) {
    p->pixel_pitch_um = st->camera_info.pixel_pitch_um;
    g_strlcpy (p->pixel_pitch_source, "camera", sizeof p->pixel_pitch_source);
  }
  p->magnification = config->magnification;
}
