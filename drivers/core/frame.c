#include "drivers/core/frame.h"

void
ds_frame_free (DsFrame *frame)
{
  if (!frame)
    return;
  ds_image_free (frame->image);
  g_free (frame);
}

void
ds_frame_id_tracker_init (DsFrameIdTracker *t, guint bits)
{
  t->started = FALSE;
  t->last = 0;
  t->last_raw = 0;
  t->bits = bits == 16 ? 16 : 64;
}

guint64
ds_frame_id_tracker_update (DsFrameIdTracker *t, guint64 raw, guint32 *skipped)
{
  *skipped = 0;
  if (t->bits == 64) {
    if (t->started && raw > t->last + 1)
      *skipped = (guint32) MIN (raw - t->last - 1, G_MAXUINT32);
    t->started = TRUE;
    t->last = raw;
    return raw;
  }
  raw &= 0xffff;
  if (!t->started) {
    t->started = TRUE;
    t->last = raw;
    t->last_raw = (guint) raw;
    return raw;
  }
  /* Distance forward from the last id on the 16-bit circle, where id 0 does not exist (GigE
   * Vision 1.x wraps 65535 -> 1): count ids in 1..65535. */
  guint64 last16 = t->last_raw == 0 ? 65535 : t->last_raw;
  guint64 r = raw == 0 ? 65535 : raw;
  guint64 forward = r > last16 ? r - last16 : r + 65535 - last16;
  t->last_raw = (guint) raw;
  if (forward == 0 || forward > 32768) {
    /* Backwards or the same id: a duplicate or a restarted camera. Not a gap: the extended id
     * stays monotonic from here. */
    t->last += 1;
    return t->last;
  }
  *skipped = (guint32) (forward - 1);
  t->last += forward;
  return t->last;
}
