/* One frame as delivered by a camera backend. The image is already unpacked (proc/pixfmt) so
 * that everything above drivers/ sees DsImage only. */
#pragma once
#include <glib.h>

#include "proc/image.h"

G_BEGIN_DECLS

typedef struct {
  DsImage *image;          /* owned; u8 or u16 with the sensor's bit depth */
  guint64 frame_id;        /* the camera's id, extended across 16-bit wrap (monotonic) */
  guint64 timestamp_ns;    /* camera timestamp if it has one, else host receive time */
  guint64 host_time_us;    /* g_get_monotonic_time () at arrival */
  double exposure_us;      /* as configured when the frame was exposed */
  double gain_db;
  guint32 ids_skipped;     /* frame ids missing between the previous frame and this one */
} DsFrame;

void ds_frame_free (DsFrame *frame);
G_DEFINE_AUTOPTR_CLEANUP_FUNC (DsFrame, ds_frame_free)

/* Extends 16-bit (GigE Vision 1.x) frame ids to 64 bits across wrap-around and counts gaps.
 * Id 0 is invalid in GigE Vision and is skipped by the wrap. */
typedef struct {
  gboolean started;
  guint64 last;            /* extended id of the last frame */
  guint bits;              /* width of the raw id: 16 or 64 */
  guint last_raw;          /* last raw 16-bit id (the extended id's low bits do not follow it
                              because the raw sequence skips 0) */
} DsFrameIdTracker;

void ds_frame_id_tracker_init (DsFrameIdTracker *tracker, guint bits);
/* Returns the extended id of raw; *skipped receives how many ids were missed (0 if contiguous). */
guint64 ds_frame_id_tracker_update (DsFrameIdTracker *tracker, guint64 raw, guint32 *skipped);

G_END_DECLS
