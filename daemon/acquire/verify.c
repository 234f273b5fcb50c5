/* Frame verification (docs/design.md, "The sequencer contract"): a frame is folded into phase
 * k only if it arrived after k was applied, no frame id is missing before it, it shows the
 * stripes the scene is expected to show, and the stripe phase measured in it is not another
 * phase's (a frame whose stripes cannot tell, where the scene is known to show so little, is
 * folded unverified). Checked in that order; the first failure is the reason. */
#include <math.h>

#include "daemon/acquire/fold_worker.h"

void
ds_seq_verify_frame (DsPhaseCheck *check, const DsCaptureSettings *s, guint k, const DsFrame *frame,
                     gint64 applied_at_us, DsFrameVerdict *v)
{
  v->reason = DS_DROP_N_REASONS;
  v->detail = NULL;
  v->reapply_phase = FALSE;
  v->unverified = FALSE;
  if (frame->host_time_us != 0 && (gint64) frame->host_time_us < applied_at_us) {
    v->reason = DS_DROP_STALE;
    v->detail = g_strdup ("frame arrived before the phase was applied");
  } else if (frame->ids_skipped > 0) {
    v->reason = DS_DROP_FRAME_GAP;
    v->detail = g_strdup_printf ("%u frame id(s) missing before id %" G_GUINT64_FORMAT,
                                 frame->ids_skipped, frame->frame_id);
  } else if (s->verify_phase) {
    double measured = NAN;
    DsPhaseVerdict pv = ds_phase_check_frame (check, frame->image, k, s->phases,
                                              &measured, &v->detail);
    if (pv == DS_PHASE_VERDICT_WRONG) {
      v->reason = DS_DROP_WRONG_PHASE;
      v->reapply_phase = TRUE; /* the illuminator may have applied another phase */
    } else if (pv == DS_PHASE_VERDICT_NO_STRIPES) {
      v->reason = DS_DROP_UNVERIFIABLE;
      v->reapply_phase = TRUE; /* the illuminator may be off, or show another pattern */
    } else if (pv == DS_PHASE_VERDICT_UNVERIFIABLE)
      /* Frames that cannot tell the phases apart where the scene is known to show too little
       * are not refused for it: a correct frame of such a scene would never pass. It is folded
       * and counted; the set's check as a whole still judges it (ds_phase_check_confirm). */
      v->unverified = TRUE;
    else
      g_clear_pointer (&v->detail, g_free);
  }
}

void
ds_frame_verdict_clear (DsFrameVerdict *v)
{
  g_clear_pointer (&v->detail, g_free);
}
