/* What labsim's camera puts in a frame: the scene as the renderer sees it under the light that
 * is on, with the sensor's noise, written in the frame's pixel format.
 *
 * Speed (issue 13: 1 MP at >= 50 frames/s): the light of each lighting state (illuminator
 * on/off, phase, phases, stripe period) is rendered off the camera thread (lab_states.h); the
 * noise-free frame of a state at an exposure and gain is derived from it once (linear in both)
 * and kept with its noise sigma; a frame is that mean plus
 * Gaussian noise with the EMVA 1288 variance K^2 (shot + dark electrons) + K^2 read^2, drawn
 * from a bank of normal deviates at a random offset per row, then quantised, clipped at full
 * well and the ADC range. The Gaussian stands in for the Poisson shot noise: mean and variance
 * are exact; below ~10 electrons the skew differs (descatter-sim and the in-process simulated
 * camera keep the exact model). `noiseless` skips the noise: the frame is the expectation,
 * rounded to whole DN and clipped.
 *
 * Pixel formats (GenICam PFNC; GigE Vision for Mono12Packed): each carries the sensor's value
 * less the low bits the format lacks (value >> (depth - bits) when the sensor has more bits):
 *   Mono8 one byte; Mono10/12/16 a little-endian 16-bit word; Mono10p/12p a continuous
 *   bitstream, pixel i in bits [i b, i b + b) counted from the least significant bit of byte 0;
 *   Mono12Packed pairs of pixels in 3 bytes: P0[11:4], P1[3:0] << 4 | P0[3:0], P1[11:4].
 * Rows follow each other in one stream (the payload is width x height x bits / 8).
 *
 * Triggers: the router calls ds_lab_fill_arm at each trigger it accepts, which samples the light
 * on at that edge; ds_lab_fill_take_ready says when the oldest such trigger's state is rendered,
 * and the router then hands it to the camera thread, whose fill serves exactly that light. A
 * trigger whose state is not rendered 10 s after its edge is dropped (counted, logged): a
 * frame never shows the light of another phase. Free-running (TriggerMode Off) a frame takes
 * the light at its fill, waiting up to 0.2 s on the camera thread for its state, else it is
 * sent black (no stripes: no phase check passes it).
 *
 * Threads: new/prepare/free on the main thread; ds_lab_fill_buffer on the camera thread only;
 * arm/take_ready/cancel on the router thread; the counters from any thread. */
#pragma once
#include <arv.h>
#include <glib.h>

#include "drivers/labsim/lab_camera.h"

G_BEGIN_DECLS

typedef struct DsLabFill DsLabFill;

DsLabFill *ds_lab_fill_new (const DsRenderer *renderer, DsLabIlluminationFunc illumination, gpointer user_data,
                            guint64 seed, gboolean noiseless);
/* Renders every lighting state of the set lit now (lab_states.h), blocking, and starts the
 * background renderer. Call before the camera appears. */
gboolean ds_lab_fill_prepare (DsLabFill *fill, guint *n_states, double *seconds, GError **error);
/* A trigger was accepted: the light now is the frame's. Non-blocking (an external controller:
 * one Modbus read). */
void ds_lab_fill_arm (DsLabFill *fill);
/* With take: TRUE when the oldest trigger not yet handed over has its state rendered; it is then
 * marked handed, and the caller must make the camera take one frame. Either way drops triggers
 * that waited too long. *waiting: triggers not handed over yet. */
gboolean ds_lab_fill_take_ready (DsLabFill *fill, gboolean take, guint *waiting);
/* Forgets the triggers not yet filled (the camera vanished). */
void ds_lab_fill_cancel (DsLabFill *fill);
/* Triggers dropped because their state was not rendered in time. */
guint64 ds_lab_fill_dropped (DsLabFill *fill);
/* Fills the buffer's image region; returns the frame's index (0, 1, ...). */
guint64 ds_lab_fill_buffer (DsLabFill *fill, ArvBuffer *buffer, double exposure_us, double gain_db,
                            guint32 pixel_format);
guint64 ds_lab_fill_frames (DsLabFill *fill);
void ds_lab_fill_free (DsLabFill *fill);

/* Bits a pixel occupies in the payload for a PFNC code this camera offers; 0 for others. */
guint ds_lab_pixel_bits (guint32 pixel_format);
/* Writes w x h values (row stride `stride` values, sensor depth `depth`) as pixel_format into
 * out (out_size bytes, at least w h bits / 8). FALSE for a format this camera does not offer. */
gboolean ds_lab_pack (guint32 pixel_format, const guint16 *values, gsize stride, guint depth, guint w, guint h,
                      guint8 *out, gsize out_size);

G_END_DECLS
