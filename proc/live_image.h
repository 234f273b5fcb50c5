/* Small pictures of frames and planes for the live view: an integer box-filter downscale to at
 * most max_side pixels per side mapped to 8 bits between two levels, and a histogram. Per-pixel
 * work for people looking at a browser, not for measurement. Pure functions, any thread. */
#pragma once
#include <glib.h>

#include "proc/image.h"

G_BEGIN_DECLS

/* The factor by which ds_live_downscale_u8 divides each side: the smallest integer that brings
 * both sides to max_side or below. */
guint ds_live_downscale_factor (guint width, guint height, guint max_side);

/* Box averages of factor x factor pixels (partial boxes at the edges average what they cover),
 * mapped linearly so that lo -> 0 and hi -> 255 (clamped); non-finite averages become 0. For the
 * mask (u8 flags), pass lo = hi = NAN: each box then keeps the OR of its flags. */
DsImage *ds_live_downscale_u8 (const DsImage *image, guint max_side, double lo, double hi, GError **error);

/* The lo_p-th and hi_p-th percentiles (0..100) for a picture's levels: exact for integer
 * images (a histogram of every pixel), from a regular sample of about 16384 finite pixels for
 * float ones (a picture does not need more); NAN when there are none. */
void ds_image_levels (const DsImage *image, double lo_p, double hi_p, double *lo, double *hi);

/* n_bins equal bins over [0, top); values at or above top land in the last bin and are counted
 * in *at_or_above (may be NULL); non-finite values are left out. */
void ds_image_histogram (const DsImage *image, double top, guint n_bins, guint32 *bins, guint64 *at_or_above);

/* a * wa + b * wb per pixel (f32 planes of one size): e.g. the plain average of a phase set,
 * pattern_mean * (transmissive + scattered), when the set kept no mean. */
DsImage *ds_image_weighted_sum (const DsImage *a, double wa, const DsImage *b, double wb, GError **error);

G_END_DECLS
