/* A pilot pair and its dark frame as float frames of one shape, for the tests of proc/'s readers
 * of pairs (lit_level, stripe_replica). Header-only, static. */
#pragma once
#include <glib.h>

#include "proc/image.h"

typedef struct {
  DsImage *dark, *l0, *l1;
} PairFrames;

static inline void
pair_frames_init (PairFrames *f, guint width, guint height)
{
  f->dark = ds_image_new (DS_SAMPLE_F32, width, height, NULL);
  f->l0 = ds_image_new (DS_SAMPLE_F32, width, height, NULL);
  f->l1 = ds_image_new (DS_SAMPLE_F32, width, height, NULL);
  g_assert_true (f->dark && f->l0 && f->l1);
}

static inline void
pair_frames_clear (PairFrames *f)
{
  g_clear_pointer (&f->dark, ds_image_free);
  g_clear_pointer (&f->l0, ds_image_free);
  g_clear_pointer (&f->l1, ds_image_free);
}
