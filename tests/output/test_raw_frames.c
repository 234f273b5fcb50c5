/* The raw frames of a set (daemon/output/raw_frames.h): frames added after room was reserved go
 * into that room, not into new memory, and hold exactly the frame's samples and bit depth,
 * also from a view whose rows are further apart than its width; a frame of another type or
 * size is copied into memory of its own; room not used is freed by trim, and never counted. */
#include <glib.h>
#include <string.h>

#include "daemon/output/raw_frames.h"

static DsImage *
pattern_u16 (guint w, guint h, guint seed, guint bits)
{
  DsImage *img = ds_image_new (DS_SAMPLE_U16, w, h, NULL);
  img->bit_depth = bits;
  for (guint y = 0; y < h; y++)
    for (guint x = 0; x < w; x++)
      ((guint16 *) ds_image_row (img, y))[x] = (guint16) ((x * 31 + y * 17 + seed * 101) & ((1u << bits) - 1));
  return img;
}

static void
assert_same_samples (const DsImage *a, const DsImage *b)
{
  g_assert_cmpint (a->type, ==, b->type);
  g_assert_cmpuint (a->width, ==, b->width);
  g_assert_cmpuint (a->height, ==, b->height);
  g_assert_cmpuint (a->bit_depth, ==, b->bit_depth);
  for (guint y = 0; y < a->height; y++)
    g_assert_cmpmem (ds_image_row (a, y), a->width * ds_sample_size (a->type), ds_image_row (b, y),
                     b->width * ds_sample_size (b->type));
}

static void
test_reserved_room (void)
{
  const guint w = 100, h = 7;
  g_autoptr (DsRawFrames) raw = ds_raw_frames_new (3);
  g_assert_true (ds_raw_frames_reserve (raw, 3, DS_SAMPLE_U16, w, h, NULL));
  g_assert_cmpuint (raw->spare->len, ==, 3);
  const void *room[3];
  for (guint i = 0; i < 3; i++)
    room[i] = ((DsImage *) raw->spare->pdata[i])->data;
  g_assert_cmpuint (ds_raw_frames_bytes (raw), ==, 0);

  /* Two frames of their own, and one a view of every other row of a taller frame. */
  g_autoptr (DsImage) f0 = pattern_u16 (w, h, 0, 12);
  g_autoptr (DsImage) f1 = pattern_u16 (w, h, 1, 16);
  g_autoptr (DsImage) tall = pattern_u16 (w, 2 * h, 2, 10);
  DsImage view = *tall;
  view.stride = tall->stride * 2;
  view.height = h;
  view.allocation = NULL;
  const DsImage *frames[] = { f0, f1, &view };
  for (guint i = 0; i < 3; i++)
    g_assert_true (ds_raw_frames_add (raw, i, 10 + i, 1000 + i, frames[i], NULL));
  g_assert_cmpuint (raw->spare->len, ==, 0);
  for (guint i = 0; i < 3; i++) {
    const DsRawFrame *f = raw->frames->pdata[i];
    g_assert_cmpuint (f->phase, ==, i);
    g_assert_cmpuint (f->frame_id, ==, 10 + i);
    assert_same_samples (f->image, frames[i]);
    /* into reserved room: one of the three reserved buffers, each used once */
    guint hits = 0;
    for (guint r = 0; r < 3; r++)
      hits += f->image->data == room[r];
    g_assert_cmpuint (hits, ==, 1);
    for (guint j = 0; j < i; j++)
      g_assert_true (((DsRawFrame *) raw->frames->pdata[j])->image->data != f->image->data);
  }

  /* No room left, or room of another size: a copy of its own, the room kept for its size. */
  g_autoptr (DsImage) f3 = pattern_u16 (w, h, 3, 12);
  g_assert_true (ds_raw_frames_add (raw, 0, 13, 1003, f3, NULL));
  g_assert_true (ds_raw_frames_reserve (raw, 2, DS_SAMPLE_U16, w + 1, h, NULL));
  g_autoptr (DsImage) f4 = pattern_u16 (w, h, 4, 12);
  g_assert_true (ds_raw_frames_add (raw, 1, 14, 1004, f4, NULL));
  g_assert_cmpuint (raw->spare->len, ==, 2);
  assert_same_samples (((DsRawFrame *) raw->frames->pdata[3])->image, f3);
  assert_same_samples (((DsRawFrame *) raw->frames->pdata[4])->image, f4);

  /* Only frames count; trim frees the room. */
  gsize row_bytes = 0;
  for (guint i = 0; i < raw->frames->len; i++) {
    const DsImage *img = ((DsRawFrame *) raw->frames->pdata[i])->image;
    row_bytes += img->stride * img->height;
  }
  g_assert_cmpuint (ds_raw_frames_bytes (raw), ==, row_bytes);
  ds_raw_frames_trim (raw);
  g_assert_cmpuint (raw->spare->len, ==, 0);
  g_assert_cmpuint (raw->frames->len, ==, 5);
  g_assert_cmpuint (ds_raw_frames_per_phase (raw), ==, 1);
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  g_test_add_func ("/raw-frames/reserved-room", test_reserved_room);
  return g_test_run ();
}
