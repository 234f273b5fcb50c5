/* One frame as delivered by a camera backend. The image is already unpacked (proc/pixfmt) so
 * that everything above drivers/ sees DsImage only. A backend may lend its own memory (the
 * Aravis buffer itself, for Mono8/Mono16): then the image borrows those pixels, and
 * ds_frame_free gives them back. Frames taken from a DsFramePool go back to it when freed, so
 * that acquiring a frame allocates nothing once the pool is warm. */
#pragma once
#include <glib.h>

#include "proc/image.h"

G_BEGIN_DECLS

typedef struct DsFramePool DsFramePool;

typedef struct {
  DsImage *image;          /* owned, or borrowing the backend's pixels (see release); u8 or u16
                              with the sensor's bit depth */
  guint64 frame_id;        /* the camera's id, extended across 16-bit wrap (monotonic) */
  guint64 timestamp_ns;    /* camera timestamp if it has one, else host receive time */
  guint64 host_time_us;    /* g_get_monotonic_time () at arrival */
  double exposure_us;      /* as configured when the frame was exposed */
  double gain_db;
  guint32 ids_skipped;     /* frame ids missing between the previous frame and this one */
  /* Private to frame.c and the backend that made the frame. */
  DsFramePool *pool;       /* where the frame goes back to; NULL: freed */
  GDestroyNotify release;  /* borrowed pixels: hands them back to the backend */
  gpointer release_data;
} DsFrame;

/* Gives a borrowed image's pixels back (returns the camera buffer), then frees the frame or
 * returns it to its pool. Call it from the thread that drives the camera (a backend's release
 * may touch its stream). */
void ds_frame_free (DsFrame *frame);
G_DEFINE_AUTOPTR_CLEANUP_FUNC (DsFrame, ds_frame_free)

/* A pool of frames for one backend. Thread-safe; reference-counted so that frames outliving
 * their backend (a frame still held when the camera closes) stay valid. */
DsFramePool *ds_frame_pool_new (void);
DsFramePool *ds_frame_pool_ref (DsFramePool *pool);
void ds_frame_pool_unref (DsFramePool *pool);
G_DEFINE_AUTOPTR_CLEANUP_FUNC (DsFramePool, ds_frame_pool_unref)
/* A frame whose image owns width x height pixels of `type`: one of the pool's when one of that
 * shape is free (its pixels are stale: overwrite them all), else a new one. Fields other than
 * the image are zeroed. Fails only when the image cannot be allocated (DS_PROC_ERROR). */
DsFrame *ds_frame_pool_take (DsFramePool *pool, DsSampleType type, guint width, guint height,
                             GError **error);
/* A frame whose image borrows `pixels` (rows `stride` bytes apart, at least width * sample
 * size); release (release_data) is called once, when the frame is freed. */
DsFrame *ds_frame_pool_take_borrowed (DsFramePool *pool, DsSampleType type, guint width,
                                      guint height, gsize stride, guint bit_depth, void *pixels,
                                      GDestroyNotify release, gpointer release_data);
/* Frames waiting in the pool, and frames of the pool given out and not yet freed. */
void ds_frame_pool_counts (DsFramePool *pool, guint *n_free, guint *n_out);

/* Extends 16-bit (GigE Vision 1.x) frame ids to 64 bits across wrap-around and counts gaps.
 * Id 0 is invalid in GigE Vision and is skipped by the wrap.
 *
 * A gap is an id missing that no loss accounts for. The backend notes each frame it already
 * reported lost whose id it never saw (a grab that timed out, a frame that came without its id):
 * up to that many ids missing before the next id seen are that loss, counted once already (a
 * timeout, an incomplete frame), and not a gap again. Notes excuse only the gap before the next
 * id seen, whatever it is: a lost trigger makes no id, and its note must not excuse a later gap. */
typedef struct {
  gboolean started;
  guint64 last;            /* extended id of the last frame */
  guint bits;              /* width of the raw id: 16 or 64 */
  guint last_raw;          /* last raw 16-bit id (the extended id's low bits do not follow it
                              because the raw sequence skips 0) */
  guint lost;              /* losses noted since the last id seen */
} DsFrameIdTracker;

void ds_frame_id_tracker_init (DsFrameIdTracker *tracker, guint bits);
/* The backend reported a frame lost whose id it did not see (ds_frame_id_tracker_note_lost
 * before the next update). */
void ds_frame_id_tracker_note_lost (DsFrameIdTracker *tracker);
/* Returns the extended id of raw; *skipped receives how many ids were missed that no noted loss
 * accounts for (0 if contiguous, or if every missing id was noted lost). Clears the notes. */
guint64 ds_frame_id_tracker_update (DsFrameIdTracker *tracker, guint64 raw, guint32 *skipped);

G_END_DECLS
