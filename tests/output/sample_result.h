/* A synthetic result whose every value follows a closed form, so that tests can check files
 * written from it with readers that share no code with the writers (Python's tifffile and h5py
 * recompute the same formulas; see sample_result.py). */
#pragma once
#include "daemon/output/output_result.h"

typedef struct {
  DsOutputResult planes;
  DsImage *images[6];
  DsRawFrames *raw;
} SampleResult;

#define SAMPLE_PHASES 4

/* transmissive = 1000 + 10 x + y + set / 4, scattered = 200 + 3 x + 2 y + set,
 * mask = (x + 2 y + set) % 64, mean = (t + s) / 2 when with_extrema;
 * raw (when with_raw): phase k frame = 100 + x + 10 k + set + y % 2 (u16, 12-bit), frame id
 * 1000 set + k, black = 50 + (x + y) % 3 with ids 1000 set + 900, 901. */
SampleResult *sample_result_new (guint width, guint height, guint set, gboolean with_raw, gboolean with_extrema);
void sample_result_free (SampleResult *s);
G_DEFINE_AUTOPTR_CLEANUP_FUNC (SampleResult, sample_result_free)
