/* The one check of the pilot frames' shape, shared by the scene probe and the pattern check so
 * that both refuse the same inputs with the same error. */
#include "daemon/operating/scene_probe.h"

#include "daemon/operating/operating_error.h"

static gboolean
frame_fits (const DsImage *frame, const char *name, const DsImage *dark, GError **error)
{
  if (!frame) {
    g_set_error (error, DS_OPERATING_ERROR, DS_OPERATING_ERROR_PILOT_FRAMES, "pilot frames: the %s is missing", name);
    return FALSE;
  }
  if (!ds_image_same_shape (frame, dark)) {
    g_set_error (error, DS_OPERATING_ERROR, DS_OPERATING_ERROR_PILOT_FRAMES,
                 "pilot frames: the %s is %ux%u %s, the dark frame %ux%u %s: all pilot frames must "
                 "have one size and sample type",
                 name, frame->width, frame->height, ds_sample_type_name (frame->type), dark->width, dark->height,
                 ds_sample_type_name (dark->type));
    return FALSE;
  }
  return TRUE;
}

gboolean
ds_probe_frames_check (const DsProbeFrames *fr, GError **error)
{
  if (!fr->dark) {
    g_set_error (error, DS_OPERATING_ERROR, DS_OPERATING_ERROR_PILOT_FRAMES, "pilot frames: the dark frame is missing");
    return FALSE;
  }
  if (!frame_fits (fr->lit[0], "phase-0 frame at the period", fr->dark, error) ||
      !frame_fits (fr->lit[1], "phase-1/2 frame at the period", fr->dark, error))
    return FALSE;
  /* The pair at 2P is optional, but never half of it. */
  if ((fr->coarse[0] || fr->coarse[1]) &&
      !(frame_fits (fr->coarse[0], "phase-0 frame at twice the period", fr->dark, error) &&
        frame_fits (fr->coarse[1], "phase-1/2 frame at twice the period", fr->dark, error)))
    return FALSE;
  /* The finer pairs: whole, below the period. */
  if (fr->n_finer > DS_PROBE_FINER_MAX) {
    g_set_error (error, DS_OPERATING_ERROR, DS_OPERATING_ERROR_PILOT_FRAMES,
                 "pilot frames: %u finer periods, at most %u", fr->n_finer, DS_PROBE_FINER_MAX);
    return FALSE;
  }
  for (guint i = 0; i < fr->n_finer; i++) {
    g_autofree char *n0 = g_strdup_printf ("phase-0 frame at %g px", fr->finer[i].period_px);
    g_autofree char *n1 = g_strdup_printf ("phase-1/2 frame at %g px", fr->finer[i].period_px);
    if (!frame_fits (fr->finer[i].frame[0], n0, fr->dark, error) ||
        !frame_fits (fr->finer[i].frame[1], n1, fr->dark, error))
      return FALSE;
    if (!(fr->finer[i].period_px > 0 && fr->finer[i].period_px < fr->geometry.period_px)) {
      g_set_error (error, DS_OPERATING_ERROR, DS_OPERATING_ERROR_PILOT_FRAMES,
                   "pilot frames: a finer period of %g px is not below the period %g px", fr->finer[i].period_px,
                   fr->geometry.period_px);
      return FALSE;
    }
  }
  return TRUE;
}
