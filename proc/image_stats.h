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
/* The q-quantile (0..1) of the finite values of v[0..n), interpolated linearly between the two
 * sorted values about position q (m - 1) of the m finite ones (the median of an even count is
 * the mean of the middle two); NAN when fewer than min_count (at least 1) are finite. */
double ds_finite_quantile (const double *v, gsize n, double q, gsize min_count);

G_END_DECLS
