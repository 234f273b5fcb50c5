/* One finished phase set as the daemon publishes it: the separation, the settings it was taken
 * with, and its accounting. Reference-counted and immutable once published, so every client
 * (and the spool) shares one copy. Created by the acquisition thread, then handed to the main
 * thread; the lazily built wire payloads are made on the main thread only. */
#pragma once
#include <glib.h>
#include <json-glib/json-glib.h>

#include "daemon/capture_settings.h"
#include "daemon/protocol.h"
#include "proc/separation.h"

G_BEGIN_DECLS

/* Why a frame was not folded. Stable names: `status` and result metadata report them. */
typedef enum {
  DS_DROP_TIMEOUT = 0,
  DS_DROP_INCOMPLETE,
  DS_DROP_FRAME_GAP,
  DS_DROP_WRONG_PHASE,   /* stripe phase measured in the frame disagrees with the applied one */
  DS_DROP_STALE,         /* exposed before the phase was applied */
  DS_DROP_DEVICE,        /* any other device error */
  DS_DROP_ABORTED,       /* set abandoned (stop, shutdown, settings change) */
  DS_DROP_N_REASONS
} DsDropReason;

const char *ds_drop_reason_name (DsDropReason reason);

typedef struct {
  guint64 acquired;       /* frames that came out of the camera */
  guint64 folded;         /* frames folded into the set */
  guint64 retried;        /* phases retried */
  guint64 dropped;        /* frames not folded, = sum of by_reason */
  guint64 by_reason[DS_DROP_N_REASONS];
} DsFrameCounters;

void ds_frame_counters_add (DsFrameCounters *total, const DsFrameCounters *part);
JsonNode *ds_frame_counters_to_json (const DsFrameCounters *counters);

typedef struct DsResult DsResult;

/* Takes ownership of sep. */
DsResult *ds_result_new (guint64 set_id, DsSeparation *sep, const DsCaptureSettings *settings,
                         const DsFrameCounters *counters, gint64 started_us, gint64 acquired_us,
                         gint64 finished_us);
DsResult *ds_result_ref (DsResult *result);
void ds_result_unref (DsResult *result);
G_DEFINE_AUTOPTR_CLEANUP_FUNC (DsResult, ds_result_unref)

guint64 ds_result_set_id (const DsResult *result);
const DsSeparation *ds_result_separation (const DsResult *result);
const DsCaptureSettings *ds_result_settings (const DsResult *result);

/* Metadata: set id, settings, separation meta, counters, timings (acquisition, compute). */
JsonNode *ds_result_to_json (DsResult *result);

typedef enum { DS_OUTPUT_F32 = 0, DS_OUTPUT_U16 = 1 } DsOutputFormat;

/* Wire payloads: transmissive, scattered (f32, or u16 clamped and rounded), mask (u8), and
 * max/min/mean when the set kept them and `extrema` is asked. Built once per format and
 * shared. Returns the number of payloads; infos/bytes point into the result. */
guint ds_result_payloads (DsResult *result, DsOutputFormat format, gboolean extrema,
                          const DsPayloadInfo **infos, GBytes *const **bytes);

G_END_DECLS
