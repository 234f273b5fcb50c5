#include "daemon/operating/rig_timing.h"

void
ds_rig_timing_init (DsRigTiming *t)
{
  t->settle_ms = 3.0;
  t->trigger_overhead_us = 200.0;
  t->link_mbit_s = 1000.0;
  t->link_efficiency = 0.9;
  t->bytes_per_pixel = 2;
}

double
ds_rig_timing_set_ms (const DsRigTiming *t, guint width, guint height, guint n_phases,
                      guint averages, double exposure_us, gboolean dark_frame)
{
  double bytes = (double) width * height * t->bytes_per_pixel;
  double readout_us = bytes * 8.0 / (t->link_mbit_s * t->link_efficiency);
  double frame_us = t->trigger_overhead_us + exposure_us + readout_us;
  double phases_ms = n_phases * (t->settle_ms + averages * frame_us / 1000.0);
  double dark_ms = dark_frame ? t->settle_ms + averages * frame_us / 1000.0 : 0.0;
  return phases_ms + dark_ms;
}

