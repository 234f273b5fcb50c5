/* The settings a phase set is taken with. A result carries the settings it was taken with, so
 * that results are never mixed across settings (a SIGHUP or a client's capture arguments
 * change them between sets, never within one). Plain data: any thread. */
#pragma once
#include <glib.h>
#include <json-glib/json-glib.h>

#include "daemon/operating/operating_point.h"
#include "daemon/operating/pattern_knowledge.h"
#include "daemon/config/config.h"
#include "proc/separation.h"

G_BEGIN_DECLS

typedef struct {
  guint phases;          /* N */
  guint averages;        /* M frames per phase */
  double exposure_us;
  double gain_db;
  DsEstimator estimator;
  DsPatternKind pattern;
  double period_px;
  double period_override_px;  /* > 0: this set's period instead of the illuminator's (a calibration's
                                 second period, calibrate_set.h); the set records it as period_px */
  double duty;
  double black_level;
  /* What calibration measured ([illuminator] harmonic-gain, edge-blur-px) and the sensor's clip
   * level ([camera] saturation-dn): 0 = not configured. */
  double harmonic_gain;
  gboolean edge_blur_known;
  double edge_blur_px;
  double open_field_dn_per_ms; /* [illuminator] open-field-dn-per-ms; 0 = not known */
  char open_field_unused[200]; /* why the configured open field is not used (then 0); "" = none */
  double acceptance_half_angle_deg; /* [camera] acceptance-half-angle-deg; 0 = not known */
  double saturation_dn;
  /* The camera's noise model ([camera] gain-dn-per-e, read-noise-dn): 0 = none (the separation
   * reads the noise off the frames). */
  double system_gain;
  double read_noise_dn;
  gboolean dark_frame;
  guint phase_retries;
  guint max_failed_sets;      /* continuous mode: stop after this many failed sets in a row; 0 = never */
  gboolean verify_phase;
  gboolean detect_motion;     /* the mask's motion bit */
  double phase_tolerance_deg; /* resolved: never NAN here */
  gboolean keep_extrema;      /* also compute max, min and mean (asked for by a client) */
  gboolean save_phases;       /* keep the raw phase and dark frames in the result */
  gboolean per_frame;         /* continuous mode: a result for every frame from the newest frame of
                               * each phase (window_stream.c) instead of one per set; M = 1 */
  gboolean single_frame;      /* one frame lit with phase 0, separated alone (proc/single_frame.h):
                                 the estimator is maxmin or sine, no raw frames are kept */
  /* Automatic operating point (docs/accuracy.md): when either is > 0, a preview frame and the
   * model choose estimator, phases, averages and exposure; the choice is recorded below. */
  double target_error;        /* relative RMSE of transmissive; 0 = none */
  double time_budget_ms;      /* 0 = none */
  /* A declared speed of moving objects (px/s along x) for the automatic operating point; not
   * declared (as zeroed settings are): a still scene */
  gboolean speed_declared;
  double speed_px_s;
  gboolean automatic;         /* `operating` is valid */
  DsOperatingReport operating;
  /* The region the set's frames came from (x, y, width, height), filled in by the set runner
   * from the camera: 0 x 0 until then (no region reported). */
  guint roi_x, roi_y, roi_width, roi_height;
} DsCaptureSettings;

/* The separation parameters of a set taken with these settings: the one place the sequencer and
 * the automatic operating point's predictions take them from, so that what is predicted is what
 * is computed. */
void ds_capture_settings_separation_params (const DsCaptureSettings *settings, DsSeparationParams *params);
/* What is known of the pattern (daemon/operating/pattern_knowledge.h) into the settings: the black
 * level, harmonic gain and edge blur, the one way every source reaches the probe and the sets
 * (the configuration's keys, a calibration's lines, a simulated illuminator's geometry). */
void ds_capture_settings_take_knowledge (DsCaptureSettings *settings, const DsPatternKnowledge *known);
/* The configuration's acquisition defaults. */
void ds_capture_settings_from_config (DsCaptureSettings *settings, const DsConfig *config);
/* As a JSON object for result metadata and `status`. */
JsonNode *ds_capture_settings_to_json (const DsCaptureSettings *settings);
gboolean ds_capture_settings_equal (const DsCaptureSettings *a, const DsCaptureSettings *b);
/* What the set's motion bit says about an automatic capture's prediction: with no speed
 * declared and motion seen (mask bit 7 on any pixel), the prediction assumed a still scene and is
 * marked a lower bound (ds_motion_apply). Recorded in the operating point's `motion` block. */
void ds_capture_settings_note_motion (DsCaptureSettings *settings, const DsSeparationMeta *meta);

G_END_DECLS
