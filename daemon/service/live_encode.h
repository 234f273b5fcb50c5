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

/* What the live view knows of a raw frame besides its pixels (copied by the frame hook). */
typedef struct {
  guint phase, n_phases;   /* phase k of N as the sequencer lit it */
  guint64 frame_id;
  double period_px;        /* the configured stripe period */
  double saturation_dn;    /* [camera] saturation-dn; 0: the pixel format's top */
  double exposure_us, gain_db;
  gint64 time_unix_ms;     /* when the hook copied it (the daemon's clock) */
} DsLiveFrameInfo;

/* A raw frame: the picture (0.1..99.9th percentile); the sensor's samples at full resolution
 * ("sensor": u8, u16 little-endian or f32, 4-byte aligned after the pictures; absent for frames
 * above 16 Mpixel) so that a page can zoom to single pixels and read their values; the
 * significant bit depth (from saturation_dn when it is set, else the image's), a 64-bin
 * histogram from 0 to full scale (the last bin also counts the samples at full scale), the
 * 1st, 50th, 99th and 99.9th percentiles and the mean; the stripe period measured (searched
 * within period_px / 2 .. 2 period_px) and the stripe phase at that period, with modulation
 * (for focusing) and snr. */
GBytes *ds_live_encode_frame (const DsImage *frame, const DsLiveFrameInfo *info, guint max_side);

/* A result: transmissive, scattered (0.5..99.5th percentile each), the plain average of the
 * phases (the set's mean, or pattern_mean * (transmissive + scattered)), and the mask's flags
 * (OR over each box). meta_json: the result's metadata text, embedded as the header's "meta". */
GBytes *ds_live_encode_result (const DsSeparation *sep, const char *meta_json, guint max_side);

G_END_DECLS
