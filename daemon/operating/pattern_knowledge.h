/* What the daemon knows of the stripe pattern it projects, whatever told it: the configuration,
 * the lines `descatterctl calibrate` prints, or a simulated illuminator whose geometry is exact
 * (descatterd --sim --scene). Every source enters through one record, the calibration's
 * (proc/calibration.h), and reaches the probe and the phase sets through the quantities its
 * lines carry (docs/accuracy.md, "What is measured, what is assumed"):
 *   [illuminator] black-level, harmonic-gain, and edge-blur-px for square stripes,
 *   and open-field-dn-per-ms where the calibration knew its exposure and took a dark frame
 * (a sine's blur and its pixel's aperture are both in its harmonic gain: they only scale the
 * first harmonic, which is all a sine has, and the probe splits that gain again,
 * ds_stripe_match_gain). So a simulated rig is never less informed than a calibrated one: its
 * record is what a noise-free calibration on a clear reference would measure, and the two
 * differ only by the calibration's own noise.
 * Pure functions, any thread. */
#pragma once
#include <glib.h>

#include "daemon/operating/stripe_model.h"

G_BEGIN_DECLS

typedef struct {
  double black_level;
  double harmonic_gain;     /* h the sine estimator divides by; 0 = not known (its theory) */
  gboolean edge_blur_known; /* edge_blur_px is known (square stripes' edge-blur-px) */
  double edge_blur_px;      /* Gaussian sigma, px */
  double open_field_dn_per_ms; /* a fully lit pixel's level on a clear path above dark, DN per ms at
                                  0 dB gain ([illuminator] open-field-dn-per-ms); 0 = not known */
  double acceptance_half_angle_deg; /* the lens's acceptance cone, object side ([camera]
                                       acceptance-half-angle-deg): not the pattern's, and no calibration
                                       measures it, but it travels with the open field; 0 = not known */
} DsPatternKnowledge;

/* What a noise-free calibration of a pattern of exactly this geometry measures
 * (ds_calibration_from_geometry, calibration_knowledge.h), through the lines that calibration
 * prints (ds_pattern_knowledge_from_calibration). The aperture of g is the renderer's or the
 * sensor's (DS_STRIPE_POINT_APERTURE for a pixel that samples at its centre). */
void ds_pattern_knowledge_from_geometry (const DsStripeModel *g, DsPatternKnowledge *out);

G_END_DECLS
