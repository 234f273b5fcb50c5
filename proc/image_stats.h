/* Whole-image statistics for decisions made from a frame (dark level, what saturates first,
 * preview scaling). Any thread; CPU only. Non-finite float samples are left out. */
#pragma once
#include "proc/image.h"

G_BEGIN_DECLS

/* Mean over all finite samples; NAN when there are none. */
double ds_image_mean (const DsImage *image);
/* The p-th percentile (0..100) over finite samples, from a regular sample of at most about a
 * million pixels; NAN when there are none. */
double ds_image_percentile (const DsImage *image, double p);

G_END_DECLS
