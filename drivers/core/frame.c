#include "drivers/core/frame.h"

#include <string.h>

/* Frames kept per pool beyond those in use: enough for a camera's in-flight frames. */
#define POOL_MAX_FREE 8

struct DsFramePool {
  gint ref;
  GMutex lock;
  GQueue owned;            /* free frames whose image owns its pixels */
  GQueue headers;          /* free frames whose image has no pixels (for borrowing) */
  guint out;               /* frames given out */
};

static void
frame_destroy (DsFrame *frame)
{
  ds_image_free (frame->image);
  g_free (frame);
}

DsFramePool *
ds_frame_pool_new (void)
{
  DsFramePool *pool = g_new0 (DsFramePool, 1);
  pool->ref = 1;
  g_mutex_init (&pool->lock);
  g_queue_init (&pool->owned);
  g_queue_init (&pool->headers);
  return pool;
}

DsFramePool *
ds_frame_pool_ref (DsFramePool *pool)
{
  g_atomic_int_inc (&pool->ref);
  return pool;
}

void
ds_frame_pool_unref (DsFramePool *pool)
{
  if (!pool || !g_atomic_int_dec_and_test (&pool->ref))
    return;
  g_queue_clear_full (&pool->owned, (GDestroyNotify) frame_destroy);
  g_queue_clear_full (&pool->headers, (GDestroyNotify) frame_destroy);
  g_mutex_clear (&pool->lock);
  g_free (pool);
}

static void
reset (DsFrame *f, DsFramePool *pool)
{
  DsImage *img = f->image;
  memset (f, 0, sizeof *f);
  f->image = img;
  f->pool = ds_frame_pool_ref (pool);
}

DsFrame *
ds_frame_pool_take (DsFramePool *pool, DsSampleType type, guint width, guint height, GError **error)
{
  DsFrame *f = NULL;
  g_mutex_lock (&pool->lock);
  /* Any free frame of another shape is dropped: the camera changed its settings. */
  while (!f && !g_queue_is_empty (&pool->owned)) {
    DsFrame *c = g_queue_pop_head (&pool->owned);
    if (c->image->type == type && c->image->width == width && c->image->height == height)
      f = c;
    else
      frame_destroy (c);
  }
  g_mutex_unlock (&pool->lock);
  if (!f) {
    DsImage *img = ds_image_new (type, width, height, error);
    if (!img)
      return NULL;
    f = g_new0 (DsFrame, 1);
    f->image = img;
  }
  f->image->bit_depth = type == DS_SAMPLE_U8 ? 8 : type == DS_SAMPLE_U16 ? 16 : 32;
  reset (f, pool);
  g_mutex_lock (&pool->lock);
  pool->out++;
  g_mutex_unlock (&pool->lock);
  return f;
}

DsFrame *
ds_frame_pool_take_borrowed (DsFramePool *pool, DsSampleType type, guint width, guint height,
                             gsize stride, guint bit_depth, void *pixels, GDestroyNotify release,
                             gpointer release_data)
{
  g_mutex_lock (&pool->lock);
  DsFrame *f = g_queue_pop_head (&pool->headers);
  pool->out++;
  g_mutex_unlock (&pool->lock);
  if (!f) {
    f = g_new0 (DsFrame, 1);
    f->image = g_new0 (DsImage, 1);
  }
  reset (f, pool);
  DsImage *img = f->image;
  img->type = type;
  img->width = width;
  img->height = height;
  img->stride = stride;
  img->bit_depth = bit_depth;
  img->data = pixels;
  img->allocation = NULL;
  f->release = release;
  f->release_data = release_data;
  return f;
}

void
ds_frame_pool_counts (DsFramePool *pool, guint *n_free, guint *n_out)
{
  g_mutex_lock (&pool->lock);
  *n_free = pool->owned.length + pool->headers.length;
  *n_out = pool->out;
  g_mutex_unlock (&pool->lock);
}

void
ds_frame_free (DsFrame *frame)
{
  if (!frame)
    return;
  if (frame->release) {
    frame->release (frame->release_data);
    frame->release = NULL;
    frame->image->data = NULL;
  }
  DsFramePool *pool = frame->pool;
  if (!pool) {
    frame_destroy (frame);
    return;
  }
  frame->pool = NULL;
  g_mutex_lock (&pool->lock);
  pool->out--;
  GQueue *q = frame->image->data ? &pool->owned : &pool->headers;
  gboolean keep = q->length < POOL_MAX_FREE;
  if (keep)
    g_queue_push_head (q, frame);
  g_mutex_unlock (&pool->lock);
  if (!keep)
    frame_destroy (frame);
  ds_frame_pool_unref (pool);
}

void
ds_frame_id_tracker_init (DsFrameIdTracker *t, guint bits)
{
  t->started = FALSE;
  t->last = 0;
  t->last_raw = 0;
  t->lost = 0;
  t->bits = bits == 16 ? 16 : 64;
}

void
ds_frame_id_tracker_note_lost (DsFrameIdTracker *t)
{
  if (t->lost < G_MAXUINT)
    t->lost++;
}

/* missing ids before this one, less those the noted losses account for; the notes are used up. */
static guint32
unaccounted (DsFrameIdTracker *t, guint64 missing)
{
  guint64 accounted = MIN (missing, (guint64) t->lost);
  t->lost = 0;
  return (guint32) MIN (missing - accounted, G_MAXUINT32);
}

guint64
ds_frame_id_tracker_update (DsFrameIdTracker *t, guint64 raw, guint32 *skipped)
{
  *skipped = 0;
  if (t->bits == 64) {
    *skipped = unaccounted (t, t->started && raw > t->last + 1 ? raw - t->last - 1 : 0);
    t->started = TRUE;
    t->last = raw;
    return raw;
  }
  raw &= 0xffff;
  if (!t->started) {
    t->started = TRUE;
    t->last = raw;
    t->last_raw = (guint) raw;
    t->lost = 0;
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
    t->lost = 0;
    t->last += 1;
    return t->last;
  }
  *skipped = unaccounted (t, forward - 1);
  t->last += forward;
  return t->last;
}
