/* Convolutions of the scattering stage at two scales (internal to drivers/sim; docs/scene-format.md,
 * "Cost"). The slab's kernels hold 99.5 % of the scattered light and reach hundreds of pixels,
 * but beyond a few dozen pixels from their centre they are smooth: each kernel is split by a
 * smooth window into a core (radius rc, every pixel) and a tail done on blocks of f x f pixels,
 * whose result is interpolated back. A field (light on a plane) is kept at both scales: every
 * pixel over the frame plus a small margin, block sums over the frame plus a wide one.
 *
 * Levels: a field at level L covers the frame plus L rc pixels (fine) and 1 + L rb blocks
 * (coarse); a step convolves level-L fields into a level L - 1 field, so that the result is exact
 * wherever the kernels reach, with no border rule. A field whose rows are all alike (the stripes
 * before any object) is kept as one row and convolved with the kernels' column sums: the same
 * numbers as the 2-D path, which the chain without objects relies on.
 *
 * How far the light is followed: a field whose rows differ (light that met an object) is kept
 * at blocks only as far as one kernel reaches around the frame (1 + rb blocks), whatever its
 * level; beyond that it is taken to be the object-free light (the chain's x-only fields, which
 * keep every level's full reach). A step from such a field pads its difference from the
 * object-free light with zeros and adds the object-free light's own convolution, so a clear
 * object is still no object, and the last step (to the frame) is exact. Without the cap a chain
 * of 2n steps covered 2n kernel radii around the frame: a 2048 px kernel through 3 planes was
 * convolved over 3110^2 blocks to light 24 x 18 of them (docs/scene-format.md, "Cost"). What is
 * lost is light that at some plane lay farther than the kernel's radius from the frame and
 * still came back into it, which the kernel's radius leaves out anyway (it holds 99.5 %).
 *
 * Kernels with radius <= 2 DS_SCALE_CORE are done at one scale (f = 1: no coarse part, no cap).
 * Immutable once built: steps may be applied from any thread at once. */
#pragma once
#include <glib.h>

#include "proc/image.h"

G_BEGIN_DECLS

#define DS_SCALE_CORE 64u  /* core radius, px */
#define DS_SCALE_BLOCK 8u  /* block side, px */

typedef struct {
  guint f;             /* block side; 1: one scale */
  guint rc;            /* core radius (px): the whole kernel at one scale */
  guint rb;            /* coarse kernels' radius (blocks) */
  guint width, height; /* the frame */
} DsScale;

void ds_scale_init (DsScale *sc, guint kernel_radius, guint width, guint height);
guint ds_scale_fine_margin (const DsScale *sc, guint level);
/* The block margin of an x-only field (the full reach) and of a 2-D one (capped, above). */
guint ds_scale_block_margin (const DsScale *sc, guint level);
guint ds_scale_block_margin_2d (const DsScale *sc, guint level);
/* The incident row must reach this far beyond the frame on each side for a level-L field and
 * 1-D convolutions of the given radius on it. */
guint ds_scale_row_margin (const DsScale *sc, guint level, guint radius);

typedef struct {
  DsImage *core;       /* (2 rc + 1)^2, every pixel */
  DsImage *tail;       /* (2 rb + 1)^2 blocks: the kernel outside the core, as block-sum weights */
  DsImage *whole;      /* (2 rb + 1)^2 blocks: the whole kernel */
  double *core_x, *tail_x, *whole_x; /* their column sums (fields with rows all alike) */
} DsScaleKernel;

DsScaleKernel *ds_scale_kernel_new (const DsScale *sc, const DsImage *kernel, GError **error);
void ds_scale_kernel_free (DsScaleKernel *k);

typedef struct {
  guint level;
  gboolean x_only;  /* one row stands for all */
  DsImage *fine;    /* (W + 2 m) x (H + 2 m), m = fine margin; height 1 when x_only */
  DsImage *coarse;  /* block sums, (ceil(W/f) + 2 b) x (ceil(H/f) + 2 b); NULL at one scale */
  guint block_margin; /* b: ds_scale_block_margin, or _2d for a 2-D field */
} DsField;

DsField *ds_field_new (const DsScale *sc, guint level, gboolean x_only, GError **error);
void ds_field_free (DsField *f);
G_DEFINE_AUTOPTR_CLEANUP_FUNC (DsField, ds_field_free)

/* An x-only field from a row of the incident light: row[i] is at frame column row_x0 + i and must
 * cover the field's coarse extent. Values times scale. */
DsField *ds_field_from_row (const DsScale *sc, guint level, const float *row, int row_x0, double scale,
                            GError **error);
/* src cropped to a lower level, times scale. */
DsField *ds_field_crop (const DsScale *sc, const DsField *src, guint level, double scale, GError **error);
/* dst += scale src (src cropped to dst's level); dst must be 2-D unless src is x-only. */
void ds_field_add (const DsScale *sc, DsField *dst, const DsField *src, double scale);

/* An object plane's transmittance at both scales: `fine` with margin fine_margin, `coarse` block
 * means with block_margin blocks (NULL at one scale). Borrowed by the fields' operations. */
typedef struct {
  const DsImage *fine;
  guint fine_margin;
  DsImage *coarse;
  guint block_margin;
} DsScaleMap;

/* dst = p(O) src over dst's level, p(t) = sum_k poly[k] t^k (k < n_poly). Blocks inside the fine
 * domain get the exact sums of the fine products; farther ones p(block mean of O) times src's
 * sums. The result is 2-D. */
DsField *ds_field_weigh (const DsScale *sc, const DsField *src, const DsScaleMap *map, const double *poly,
                         guint n_poly, guint level, GError **error);

typedef struct DsScaleStep DsScaleStep;
/* out (level - 1) = sum_i kernels[i] (*) in_i (level). */
DsScaleStep *ds_scale_step_new (const DsScale *sc, guint level, const DsScaleKernel *const *kernels, guint n,
                                GError **error);
/* in[i] may be NULL (no light of that kind). The result is x-only when every input is. clear[i]:
 * the x-only object-free counterpart of a 2-D in[i], which stands for it beyond its blocks
 * (needed for a 2-D input above level 1; else may be NULL). */
DsField *ds_scale_step_apply (const DsScaleStep *st, const DsField *const *in, const DsField *const *clear,
                              GError **error);
void ds_scale_step_free (DsScaleStep *st);

G_END_DECLS
