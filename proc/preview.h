/* 8-bit previews of float results for people to look at: scaled between robust percentiles so
 * that a few hot or negative pixels do not wash out the picture. Not for measurement. */
#pragma once
#include "proc/image.h"

G_BEGIN_DECLS

/* lo/hi percentiles in [0, 100], lo < hi, over finite pixels; non-finite pixels become 0.
 * A constant image maps to mid-grey. */
DsImage *ds_preview_u8 (const DsImage *image, double lo_percentile, double hi_percentile,
                        GError **error);

G_END_DECLS
