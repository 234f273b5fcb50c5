/* One finished phase set as the daemon publishes it: the separation, the settings it was taken
 * with, and its accounting. Reference-counted and immutable once published, so every client
 * (and the spool) shares one copy. Created by the acquisition thread, then handed to the main
 * thread; the lazily built wire payloads are made on the main thread only. */
#pragma once
#include <glib.h>
#include <json-glib/json-glib.h>

#include "daemon/output/raw_frames.h"
#include "daemon/output/output_result.h"
#include "daemon/acquire/capture_settings.h"
#include "daemon/acquire/frame_counters.h"
#include "daemon/protocol/protocol.h"
#include "drivers/core/camera.h"
#include "proc/separation.h"

G_BEGIN_DECLS

typedef struct DsResult DsResult;
typedef struct DsPlanePool DsPlanePool;

/* Takes ownership of sep; when the result and every payload sent from it are gone, sep goes
 * back to pool (result_planes.h), or is freed when pool is NULL. */
DsResult *ds_result_new (guint64 set_id, DsSeparation *sep, DsPlanePool *pool,
                         const DsCaptureSettings *settings,
                         const DsFrameCounters *counters, gint64 started_us, gint64 acquired_us,
                         gint64 finished_us);
DsResult *ds_result_ref (DsResult *result);
void ds_result_unref (DsResult *result);
G_DEFINE_AUTOPTR_CLEANUP_FUNC (DsResult, ds_result_unref)

guint64 ds_result_set_id (const DsResult *result);
const DsSeparation *ds_result_separation (const DsResult *result);
const DsCaptureSettings *ds_result_settings (const DsResult *result);

/* What a result cannot know by itself: where and with what it was taken. Stamped by the service
 * (main thread) before the result is used (docs/operations.md, "Result metadata"). */
typedef struct {
  char program[32];              /* "descatterd" */
  char config_sha256[65];        /* of the effective configuration text */
  char camera_backend[16], illuminator_backend[16], trigger_backend[16];
  DsCameraInfo camera;
  char pixel_format[32];         /* as configured (aravis) or "simulated" */
  guint roi_x, roi_y, roi_width, roi_height; /* roi_width 0: the full sensor */
  double illuminator_temperature_c;          /* NAN: unknown */
  double phase_offset_cycles;                /* NAN: not learned */
  /* The object-plane pixel size is pixel_pitch_um / magnification (metadata pixel_size_um). */
  double pixel_pitch_um;                     /* NAN: unknown */
  char pixel_pitch_source[16];               /* "config", "camera" or "" (unknown) */
  double magnification;                      /* NAN: unknown */
} DsResultProvenance;

void ds_result_set_provenance (DsResult *result, const DsResultProvenance *provenance);

/* Where the time after the set's last frame went (the metadata's monotonic_us and timing_ms):
 * monotonic stamps of its verification's start and end and of the end of its fold, which
 * includes the set's finalize where the frame is folded on the finalize's pass (maxmin, one
 * frame per phase). All 0: not known; the metadata leaves them out then, and when the camera
 * did not stamp the frame's arrival. Set by the sequencer before the result is shared. */
typedef struct {
  gint64 verify_started_us, verified_us, folded_us;
} DsLastFrameTimes;
void ds_result_set_last_frame_times (DsResult *result, const DsLastFrameTimes *times);

/* A per-frame result's sliding window (continuous mode `results = per-frame`): the metadata's
 * `window` object (docs/protocol.md, "Per-frame results"). Acquisition thread, before the
 * result is emitted; a set's result has none. */
typedef struct {
  guint frames;             /* N: one frame per phase */
  guint64 span;             /* frames pushed from the window's oldest to its newest, inclusive */
  guint64 newest_frame_id;  /* the camera's id of the frame that completed this result */
  guint64 since_break;      /* good frames since the window was last broken */
  guint64 breaks;           /* breaks since continuous mode started */
  char last_break[48];      /* the last break's reason ("" none) */
} DsResultWindow;
void ds_result_set_window (DsResult *result, const DsResultWindow *window);
/* Whether the result is a per-frame one (it has a window). Any thread. */
gboolean ds_result_per_frame (const DsResult *result);

/* The raw frames of the set (capture with save_phases); takes ownership. Acquisition thread,
 * before the result is emitted. */
void ds_result_set_raw_frames (DsResult *result, DsRawFrames *raw);
const DsRawFrames *ds_result_raw_frames (const DsResult *result);

/* Metadata (docs/operations.md, "Result metadata"): format, set id, UTC times, producer (with
 * host and the configuration's hash), camera (backend, identity, pixel format, ROI), pattern,
 * settings, separation, planes (units, long names), mask_bits, frames, timings, raw_frames.
 * Built once (main thread) and shared: the caller gets a reference and must not modify it. */
JsonNode *ds_result_to_json (DsResult *result);

/* The planes and metadata for the file writers (daemon/output). planes->meta is a new copy
 * the caller unrefs; the images stay the result's. Main thread (builds the metadata). */
void ds_result_to_output (DsResult *result, DsOutputResult *planes);

typedef enum { DS_OUTPUT_F32 = 0, DS_OUTPUT_U16 = 1 } DsOutputFormat;

/* Wire payloads: transmissive, scattered (f32, or u16 clamped and rounded), mask (u8), and
 * max/min/mean when the set kept them and `extrema` is asked. Built once per format and
 * shared; f32 and u8 payloads are the result's planes themselves (no copy), and a client may
 * keep the bytes after the result is gone. Returns the number of payloads; infos/bytes point
 * into the result. Main thread. */
guint ds_result_payloads (DsResult *result, DsOutputFormat format, gboolean extrema,
                          const DsPayloadInfo **infos, GBytes *const **bytes);
/* The raw frames as payloads named like their phase-folder files ("phase-03-0", "black"), in
 * the order of the metadata's raw_frames.frames; 0 without raw frames. Main thread. */
guint ds_result_raw_payloads (DsResult *result, const DsPayloadInfo **infos, GBytes *const **bytes);

G_END_DECLS
