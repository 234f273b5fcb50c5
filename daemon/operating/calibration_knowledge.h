/* The calibration record's side of the pattern knowledge (pattern_knowledge.h): the record a
 * source of exact geometry gives, and what a record's lines carry. Apart from pattern_knowledge.h
 * because proc/calibration.h's pattern check shares a name with the operating model's
 * (pattern_check.h): a file that uses both includes this header only where it needs the record.
 * Pure functions, any thread. */
#pragma once
#include <glib.h>

#include "daemon/operating/pattern_knowledge.h"
#include "proc/calibration.h"

G_BEGIN_DECLS

/* What a noise-free calibration of a pattern of exactly this geometry measures: the pattern,
 * period, duty, black level (measured), the first harmonic as its pixels see it (blur and
 * aperture, ds_stripe_harmonic) as the harmonic gain, and the edge blur. */
void ds_calibration_from_geometry (const DsStripeModel *g, DsCalibration *out);

/* What the calibration's lines put in descatterd.conf (proc/calibration_json.h,
 * ds_calibration_config_lines): the black level, the harmonic gain, and for square stripes the
 * edge blur. */
void ds_pattern_knowledge_from_calibration (const DsCalibration *cal, DsPatternKnowledge *out);

G_END_DECLS
