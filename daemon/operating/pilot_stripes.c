/* Stripes in the pilot frames (pilot_stripes.h). */
#include "daemon/operating/pilot_stripes.h"

#include <math.h>

#include "daemon/operating/stripe_model.h"
#include "daemon/operating/operating_error.h"
#include "daemon/operating/scene_probe_pairs.h"
#include "proc/clip_level.h"
#include "proc/column_stats.h"
#include "proc/image_stats.h"

gboolean
ds_pilot_stripes_check (const DsProbeFrames *f, DsPilotStripes *out, GError **error)
{
  *out = (DsPilotStripes){ 0 };
  if (!ds_probe_frames_check (f, error))
    return FALSE;
  const DsImage *l0 = f->lit[0], *l1 = f->lit[1];
  double period = f->geometry.period_px;
  /* A pilot that clips is refused by the probe's own rule (scene_probe_pairs.h), before a fit
   * on the samples left would fail for want of columns, or read the few dim ones as the scene. */
  guint64 clipped = 0;
  DsClipLevel clip; /* the format's top, or a full well's pile-up below it (proc/clip_level.h) */
  ds_clip_level_find (f->dark, f->lit, 2, f->saturation_dn, &clip);
  if (!ds_probe_pair_check_clipping (l0, l1, clip.level, &clipped, error))
    return FALSE;
  DsColumnStats stats = { 0 };
  if (!ds_column_stats_compute (l0, l1, clip.level, &stats, error))
    return FALSE;
  DsStripeHarmonics h;
  g_autoptr (GError) local = NULL;
  gboolean fitted = ds_stripe_harmonics_fit (stats.mean_diff, stats.count, 0, stats.width, period, 1, &h, &local);
  if (!fitted)
    ds_probe_pair_refuse_unfitted (&stats, clipped, clip.level, period, local, error);
  ds_column_stats_clear (&stats);
  if (!fitted)
    return FALSE;
  out->amplitude = h.amplitude[1];
  out->sigma = h.sigma_amplitude;
  out->mean_dn = 0.5 * (ds_image_mean (l0) + ds_image_mean (l1));
  out->light_dn = out->mean_dn - ds_image_mean (f->dark);
  /* one frame's first harmonic is half the difference's */
  double modulation = out->mean_dn > 0 ? 0.5 * out->amplitude / out->mean_dn : 0;
  double snr = out->sigma > 0 ? out->amplitude / out->sigma : (out->amplitude > 0 ? INFINITY : 0);
  if (snr >= DS_PILOT_MIN_SNR && modulation >= DS_PILOT_MIN_MODULATION)
    return TRUE;
  g_set_error (error, DS_OPERATING_ERROR, DS_OPERATING_ERROR_NO_STRIPES,
               "no stripes at the configured period %g px: the pilot frames show no modulation there (phase 0 "
               "less phase 1/2: a first harmonic of %.3g DN, %.1f standard errors of the noise (%.3g DN) where %.0f "
               "are needed, and %.2g of the frames' mean level %.4g DN where %g is needed; the lit frames are "
               "%.4g DN above the dark frame). No direct light to separate: is the illuminator on and lighting "
               "the camera's view, and is [illuminator] period-px right (descatterctl calibrate)?",
               period, out->amplitude, snr, out->sigma, DS_PILOT_MIN_SNR, modulation, out->mean_dn,
               DS_PILOT_MIN_MODULATION, out->light_dn);
  return FALSE;
}
