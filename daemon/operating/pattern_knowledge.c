#include "daemon/operating/calibration_knowledge.h"

#include <string.h>

#include "proc/harmonic_gain.h"

void
ds_calibration_from_geometry (const DsStripeModel *g, DsCalibration *out)
{
  memset (out, 0, sizeof *out);
  out->pattern = g->kind;
  out->period_px = g->period_px;
  out->period_measured = TRUE;
  out->duty = g->kind == DS_PATTERN_SINE ? 0.5 : g->duty;
  out->black_level = g->black_level;
  out->black_level_measured = TRUE;
  out->harmonic_gain = ds_stripe_harmonic (g, 1);
  out->harmonic_gain_theory = ds_harmonic_gain_theory (g->kind, out->duty, g->black_level);
  double mean = ds_pattern_mean (g->kind, out->duty, g->black_level);
  out->contrast = mean > 0 ? out->harmonic_gain / mean : 0;
  out->edge_blur_px = g->blur_px;
}

void
ds_pattern_knowledge_from_calibration (const DsCalibration *cal, DsPatternKnowledge *out)
{
  memset (out, 0, sizeof *out);
  out->black_level = cal->black_level;
  out->harmonic_gain = cal->harmonic_gain;
  /* The lines carry a square pattern's edge blur; a sine's is in its harmonic gain. */
  out->edge_blur_known = cal->pattern != DS_PATTERN_SINE;
  out->edge_blur_px = out->edge_blur_known ? cal->edge_blur_px : 0;
  out->open_field_dn_per_ms = cal->open_field_dn_per_ms > 0 ? cal->open_field_dn_per_ms : 0;
}

void
ds_pattern_knowledge_from_geometry (const DsStripeModel *g, DsPatternKnowledge *out)
{
  DsCalibration cal;
  ds_calibration_from_geometry (g, &cal);
  ds_pattern_knowledge_from_calibration (&cal, out);
}
