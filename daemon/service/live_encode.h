/* The live view's updates as binary WebSocket messages: a little-endian u32 with the length of
 * a JSON header, the header, then 8-bit images back to back (each described in the header's
 * "images": name, width, height, offset, and the levels lo..hi that map to 0..255). Small
 * pictures (at most max_side pixels a side), not data: the result files are the data.
 * Pure functions, any thread (the live view's encoder thread). */
#pragma once
#include <glib.h>

#include "daemon/acquire/result.h"
#include "proc/image.h"

G_BEGIN_DECLS

/* Phase `phase` of n_phases, as the camera delivered it: the picture (0.1..99.9th percentile),
 * a 64-bin histogram over the ADC's range, the stripe period measured in it (searched within
 * period_px / 2 .. 2 period_px, period_px being the configured one) and the stripe phase
 * measured at that period, with modulation (for focusing) and snr. */
GBytes *ds_live_encode_frame (const DsImage *frame, guint phase, guint n_phases, guint64 frame_id,
                              double period_px, guint max_side);

/* A result: transmissive, scattered (0.5..99.5th percentile each), the plain average of the
 * phases (the set's mean, or pattern_mean * (transmissive + scattered)), and the mask's flags
 * (OR over each box). meta_json: the result's metadata text, embedded as the header's "meta". */
GBytes *ds_live_encode_result (const DsSeparation *sep, const char *meta_json, guint max_side);

G_END_DECLS
