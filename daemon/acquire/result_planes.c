/* The pool of result planes: a set writes into planes of results nobody holds any more, so
 * that no page fault falls between the last frame and the result. Any thread; one mutex
 * guards the free list. */
#include "daemon/acquire/result_planes.h"

#include <string.h>

struct DsPlanePool {
  gint ref;
  guint max_free;
  GMutex lock;
  GSList *free;            /* DsSeparation, most recently released first */
  guint n_free;
};

DsPlanePool *
ds_plane_pool_new (guint max_free)
{
  DsPlanePool *pool = g_new0 (DsPlanePool, 1);
  pool->ref = 1;
  pool->max_free = max_free;
  g_mutex_init (&pool->lock);
  return pool;
}

DsPlanePool *
ds_plane_pool_ref (DsPlanePool *pool)
{
  g_atomic_int_inc (&pool->ref);
  return pool;
}

void
ds_plane_pool_unref (DsPlanePool *pool)
{
  if (!pool || !g_atomic_int_dec_and_test (&pool->ref))
    return;
  g_slist_free_full (pool->free, (GDestroyNotify) ds_separation_free);
  g_mutex_clear (&pool->lock);
  g_free (pool);
}

static DsImage *
packed_plane (DsSampleType type, guint w, guint h, GError **error)
{
  DsImage *img = ds_image_new_with_stride (type, w, h, (gsize) w * ds_sample_size (type), error);
  if (img)
    for (guint y = 0; y < h; y++)
      memset (ds_image_row (img, y), 0, img->stride);
  return img;
}

DsSeparation *
ds_plane_pool_take (DsPlanePool *pool, guint width, guint height, GError **error)
{
  DsSeparation *sep = NULL;
  GSList *stale = NULL;
  g_mutex_lock (&pool->lock);
  while (pool->free && !sep) {
    DsSeparation *s = pool->free->data;
    pool->free = g_slist_delete_link (pool->free, pool->free);
    pool->n_free--;
    if (s->transmissive && s->transmissive->width == width && s->transmissive->height == height)
      sep = s;
    else
      stale = g_slist_prepend (stale, s); /* another size: the ROI changed */
  }
  g_mutex_unlock (&pool->lock);
  g_slist_free_full (stale, (GDestroyNotify) ds_separation_free);
  if (sep)
    return sep;
  g_autoptr (DsSeparation) fresh = g_new0 (DsSeparation, 1);
  if (!(fresh->transmissive = packed_plane (DS_SAMPLE_F32, width, height, error)) ||
      !(fresh->scattered = packed_plane (DS_SAMPLE_F32, width, height, error)) ||
      !(fresh->mask = packed_plane (DS_SAMPLE_U8, width, height, error)))
    return NULL;
  return g_steal_pointer (&fresh);
}

void
ds_plane_pool_give (DsPlanePool *pool, DsSeparation *sep)
{
  if (!sep)
    return;
  g_mutex_lock (&pool->lock);
  gboolean keep = pool->n_free < pool->max_free;
  if (keep) {
    pool->free = g_slist_prepend (pool->free, sep);
    pool->n_free++;
  }
  g_mutex_unlock (&pool->lock);
  if (!keep)
    ds_separation_free (sep);
}

guint
ds_plane_pool_n_free (DsPlanePool *pool)
{
  g_mutex_lock (&pool->lock);
  guint n = pool->n_free;
  g_mutex_unlock (&pool->lock);
  return n;
}

struct DsResultPlanes {
  gint ref;
  DsSeparation *sep;
  DsPlanePool *pool;
};

DsResultPlanes *
ds_result_planes_new (DsSeparation *sep, DsPlanePool *pool)
{
  DsResultPlanes *p = g_new0 (DsResultPlanes, 1);
  p->ref = 1;
  p->sep = sep;
  p->pool = pool ? ds_plane_pool_ref (pool) : NULL;
  return p;
}

DsResultPlanes *
ds_result_planes_ref (DsResultPlanes *planes)
{
  g_atomic_int_inc (&planes->ref);
  return planes;
}

void
ds_result_planes_unref (DsResultPlanes *planes)
{
  if (!planes || !g_atomic_int_dec_and_test (&planes->ref))
    return;
  if (planes->pool) {
    ds_plane_pool_give (planes->pool, planes->sep);
    ds_plane_pool_unref (planes->pool);
  } else
    ds_separation_free (planes->sep);
  g_free (planes);
}

const DsSeparation *
ds_result_planes_separation (const DsResultPlanes *planes)
{
  return planes->sep;
}

GBytes *
ds_result_planes_bytes (DsResultPlanes *planes, const DsImage *image)
{
  gsize row = (gsize) image->width * ds_sample_size (image->type);
  if (row != image->stride)
    return ds_image_to_packed_bytes (image);
  return g_bytes_new_with_free_func (image->data, row * image->height,
                                     (GDestroyNotify) ds_result_planes_unref,
                                     ds_result_planes_ref (planes));
}
