/* The acquisition-time model of the rig, shared by the accuracy study and the automatic
 * operating point. Plain arithmetic, any thread. */
#pragma once
#include <glib.h>

G_BEGIN_DECLS

/* What one phase set costs on the rig: per phase the illuminator settles, then per frame the
 * camera is triggered, exposes and reads out over the link (no overlap: the sequencer verifies
 * each frame before the next trigger). */
typedef struct {
  double settle_ms;          /* illuminator: phase write to applied */
  double trigger_overhead_us;/* trigger round trip and frame start */
  double link_mbit_s;        /* GigE: 1000 */
  double link_efficiency;    /* payload share of the link (GVSP headers, gaps): 0.9 */
  guint bytes_per_pixel;     /* 2 for Mono12/16 */
} DsRigTiming;

void ds_rig_timing_init (DsRigTiming *t);
/* Acquisition time of one set (ms), including an optional dark frame set of M frames. */
double ds_rig_timing_set_ms (const DsRigTiming *t, guint width, guint height, guint n_phases,
                             guint averages, double exposure_us, gboolean dark_frame);

G_END_DECLS
