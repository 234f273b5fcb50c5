/* Phase frames for the separation kernels' tests (tests/proc/test_separation_fused.c,
 * test_separation_sine_fast.c): stripes whose levels vary along x only, so that the noise
 * estimate (second differences along y) sees the noise, plus noise of 1 % of full scale, and
 * hard pixels chosen by a hash of the position. Each test gives its stripes (a level function)
 * and its hard pixels (a table of kinds); the frames are a function of those and the GRand's
 * seed: pixels are drawn row by row, the noise first, the kind's own draw after it. */
#pragma once

#include <glib.h>
#include <math.h>

#include "proc/image.h"

/* A 64-bit mixer (splitmix64's finaliser): the hash that picks hard pixels and column levels. */
static inline guint64
phase_frames_mix (guint64 v)
{
  v ^= v >> 33;
  v *= 0xff51afd7ed558ccdull;
  v ^= v >> 33;
  v *= 0xc4ceb9fe1a85ec53ull;
  return v ^ (v >> 33);
}

/* What a hard pixel does, in every phase k of N. */
typedef enum {
  PHASE_PIXEL_STRIPES,         /* nothing: the stripes and the noise */
  PHASE_PIXEL_CLIPPED_LIT,     /* full scale in the phases that light it */
  PHASE_PIXEL_CLIPPED_THIRD,   /* full scale in phases 0, 3, 6, ... */
  PHASE_PIXEL_ZERO,            /* 0 in every phase */
  PHASE_PIXEL_ZERO_THEN_FULL,  /* 0 in phase 0, full scale in phase 1 */
  PHASE_PIXEL_FLAT,            /* the column's unlit level, no modulation, no noise */
  PHASE_PIXEL_FULL,            /* full scale in every phase */
  PHASE_PIXEL_HALF_FULL,       /* the largest modulation: full scale in the first half, 0 after */
  PHASE_PIXEL_FEW_DN,          /* 0 to 4 DN */
  PHASE_PIXEL_STEP,            /* 0.2 of full scale brighter after phase 0, as when an edge passed */
} PhasePixelKind;

/* A pixel's stripes under phase k, before noise. */
typedef struct {
  double level;  /* its value */
  double flat;   /* its column's unlit level (PHASE_PIXEL_FLAT) */
  gboolean lit;  /* lit by phase k (PHASE_PIXEL_CLIPPED_LIT) */
} PhaseLevel;

typedef void (*PhaseLevelFunc) (gconstpointer data, guint k, guint x, guint64 col_hash, guint full, PhaseLevel *out);

typedef struct {
  guint n;                    /* phases */
  guint full;                 /* the largest sample value */
  PhaseLevelFunc stripes;     /* col_hash: phase_frames_mix (x) */
  gconstpointer data;         /* for stripes */
  /* A pixel whose position hash h has h % modulus < n_kinds is kinds[h % modulus]. */
  guint modulus;
  const PhasePixelKind *kinds;
  guint n_kinds;
} PhaseFrames;

/* Frame k's value at (x, y), drawing from r. */
static inline guint
phase_frames_value (const PhaseFrames *f, guint k, guint x, guint y, GRand *r)
{
  guint64 id = phase_frames_mix ((guint64) y * 100003u + x), col = phase_frames_mix (x);
  guint slot = (guint) (id % f->modulus);
  PhasePixelKind kind = slot < f->n_kinds ? f->kinds[slot] : PHASE_PIXEL_STRIPES;
  PhaseLevel s;
  f->stripes (f->data, k, x, col, f->full, &s);
  double full = f->full;
  double v = s.level + 0.01 * full * (g_rand_double (r) - 0.5);
  switch (kind) {
  case PHASE_PIXEL_STRIPES:
    break;
  case PHASE_PIXEL_CLIPPED_LIT:
    v = s.lit ? full : v;
    break;
  case PHASE_PIXEL_CLIPPED_THIRD:
    v = k % 3 == 0 ? full : v;
    break;
  case PHASE_PIXEL_ZERO:
    v = 0;
    break;
  case PHASE_PIXEL_ZERO_THEN_FULL:
    v = k == 0 ? 0 : k == 1 ? full : v;
    break;
  case PHASE_PIXEL_FLAT:
    v = s.flat;
    break;
  case PHASE_PIXEL_FULL:
    v = full;
    break;
  case PHASE_PIXEL_HALF_FULL:
    v = 2 * k < f->n ? full : 0;
    break;
  case PHASE_PIXEL_FEW_DN:
    v = (double) ((id >> 24) % 4) + (g_rand_int (r) & 1);
    break;
  case PHASE_PIXEL_STEP:
    v += k > 0 ? 0.2 * full : 0;
    break;
  }
  return (guint) CLAMP (lround (v), 0, (long) f->full);
}

/* Stores v at (x, y) of a u8 or u16 image. */
static inline void
phase_frames_put (DsImage *img, guint x, guint y, guint v)
{
  if (img->type == DS_SAMPLE_U8)
    ((guint8 *) ds_image_row (img, y))[x] = (guint8) v;
  else
    ((guint16 *) ds_image_row (img, y))[x] = (guint16) v;
}

/* Fills img (u8 or u16, any stride) with frame k, row by row. */
static inline void
phase_frames_fill (DsImage *img, const PhaseFrames *f, guint k, GRand *r)
{
  for (guint y = 0; y < img->height; y++)
    for (guint x = 0; x < img->width; x++)
      phase_frames_put (img, x, y, phase_frames_value (f, k, x, y, r));
}

/* A dark frame: a few DN (a hash of the position modulo `spread`), full / 2 in the top-left
 * quarter, far above the signal there. */
static inline DsImage *
phase_frames_dark (DsSampleType type, guint bit_depth, guint w, guint h, guint spread)
{
  guint full = (1u << bit_depth) - 1;
  DsImage *img = ds_image_new (type, w, h, NULL);
  g_assert_nonnull (img);
  img->bit_depth = bit_depth;
  for (guint y = 0; y < h; y++)
    for (guint x = 0; x < w; x++)
      phase_frames_put (img, x, y, x < w / 4 && y < h / 4 ? full / 2 : (guint) (phase_frames_mix (x * 7 + y) % spread));
  return img;
}
