/* The settings a phase set is taken with: from the configuration's defaults, to the
 * separation's parameters, to JSON for a result's metadata. Plain data, CPU only: any thread. */
#include "daemon/acquire/capture_settings.h"
#include "daemon/operating/motion_term.h"
#include "proc/phase_check.h"
#include "proc/single_frame.h"

#include <math.h>
#include <string.h>

void
ds_capture_settings_take_knowledge (DsCaptureSettings *s, const DsPatternKnowledge *k)
{
  s->black_level = k->black_level;
  s->harmonic_gain = k->harmonic_gain;
  s->edge_blur_known = k->edge_blur_known;
  s->edge_blur_px = k->edge_blur_known ? k->edge_blur_px : 0;
  s->open_field_dn_per_ms = k->open_field_dn_per_ms;
  s->open_field_unused[0] = '\0';
  s->acceptance_half_angle_deg = k->acceptance_half_angle_deg;
}

void
ds_capture_settings_from_config (DsCaptureSettings *s, const DsConfig *c)
{
  memset (s, 0, sizeof *s);
  s->phases = c->phases;
  s->averages = c->averages;
  s->exposure_us = c->exposure_us;
  s->gain_db = c->gain_db;
  if (!ds_estimator_from_name (c->estimator, &s->estimator))
    s->estimator = DS_ESTIMATOR_MAXMIN; /* unreachable: the config parser checked the name */
  s->pattern = strcmp (c->pattern, "sine") == 0 ? DS_PATTERN_SINE : DS_PATTERN_SQUARE;
  s->period_px = c->period_px;
  s->duty = c->duty;
  /* The open field's DN are the pixel format's it was measured in: under another one the same
   * light reads other DN (Mono8 holds a 12-bit sensor's top 8 bits, Mono16 all 12), so it is not
   * used. Where the configuration does not say, it is taken as the camera's. */
  const char *format = ds_config_camera_pixel_format (c);
  gboolean other_format = !isnan (c->open_field_dn_per_ms) && c->open_field_pixel_format &&
                          g_ascii_strcasecmp (c->open_field_pixel_format, format) != 0;
  DsPatternKnowledge known = { .black_level = c->black_level,
                               .harmonic_gain = isnan (c->harmonic_gain) ? 0 : c->harmonic_gain,
                               .edge_blur_known = !isnan (c->edge_blur_px),
                               .edge_blur_px = isnan (c->edge_blur_px) ? 0 : c->edge_blur_px,
                               .open_field_dn_per_ms =
                                 isnan (c->open_field_dn_per_ms) || other_format ? 0 : c->open_field_dn_per_ms,
                               .acceptance_half_angle_deg =
                                 isnan (c->acceptance_half_angle_deg) ? 0 : c->acceptance_half_angle_deg };
  ds_capture_settings_take_knowledge (s, &known);
  if (other_format)
    g_snprintf (s->open_field_unused, sizeof s->open_field_unused,
                "[illuminator] open-field-dn-per-ms was measured in %s and the camera delivers %s, whose DN "
                "differ (descatterctl calibrate again in %s)",
                c->open_field_pixel_format, format, format);
  s->saturation_dn = isnan (c->saturation_dn) ? 0 : c->saturation_dn;
  s->system_gain = isnan (c->gain_dn_per_e) ? 0 : c->gain_dn_per_e;
  s->read_noise_dn = isnan (c->read_noise_dn) || s->system_gain <= 0 ? 0 : c->read_noise_dn;
  s->speed_declared = !isnan (c->speed_px_s);
  s->speed_px_s = s->speed_declared ? c->speed_px_s : 0;
  s->dark_frame = c->dark_frame;
  s->phase_retries = c->phase_retries;
  s->max_failed_sets = c->max_failed_sets;
  s->verify_phase = c->verify_phase;
  s->single_frame = c->single_frame;
  s->detect_motion = c->detect_motion;
  /* A spool that records raw frames needs every set to keep them. */
  s->save_phases = c->spool_dir && c->spool_save_phases;
  s->per_frame = c->results && strcmp (c->results, "per-frame") == 0;
  /* A quarter of the phase step: a frame lit one phase off is then always refused. */
  s->phase_tolerance_deg = isnan (c->phase_tolerance_deg) ? ds_phase_check_default_tolerance_deg (c->phases)
                                                      : c->phase_tolerance_deg;
}

void
ds_capture_settings_separation_params (const DsCaptureSettings *s, DsSeparationParams *p)
{
  ds_separation_params_init (p, s->phases);
  p->estimator = s->estimator;
  p->pattern = s->pattern;
  p->duty = s->duty;
  p->black_level = s->black_level;
  /* 0 keeps the separation's own defaults: the sharp pattern's h, the frames' bit depth. */
  p->harmonic_gain = s->harmonic_gain;
  p->saturation_level = s->saturation_dn;
  p->keep_extrema = s->keep_extrema;
  p->detect_motion = s->detect_motion;
  /* With a system gain the separation's noise is per pixel, read^2 + K x signal (its sigma
   * planes, the motion bit's threshold); without, one frame's median noise. */
  p->system_gain = s->system_gain;
  p->read_noise_dn = s->read_noise_dn;
  /* The period is known (the illuminator's): maxmin and robust then flag the pixels a phase
   * never fully lights or darkens instead of being refused, and robust's windows fit it. */
  p->geometry.period_px = s->period_px;
  p->geometry.pixel_aperture = 1;
  /* A calibrated blur sets robust's margin (the edge's width in pixels); unknown, robust keeps
   * one phase of margin. */
  p->geometry.edge_blur_known = s->edge_blur_known;
  p->geometry.edge_blur_px = s->edge_blur_known ? s->edge_blur_px : 0;
}

JsonNode *
ds_capture_settings_to_json (const DsCaptureSettings *s)
{
  g_autoptr (JsonBuilder) b = json_builder_new ();
  json_builder_begin_object (b);
#define INT(k, v) (json_builder_set_member_name (b, k), json_builder_add_int_value (b, (gint64) (v)))
#define DBL(k, v) (json_builder_set_member_name (b, k), json_builder_add_double_value (b, v))
#define STR(k, v) (json_builder_set_member_name (b, k), json_builder_add_string_value (b, v))
#define BOOL(k, v) (json_builder_set_member_name (b, k), json_builder_add_boolean_value (b, v))
  INT ("phases", s->phases);
  INT ("averages", s->averages);
  DBL ("exposure_us", s->exposure_us);
  DBL ("gain_db", s->gain_db);
  STR ("estimator", ds_estimator_name (s->estimator));
  STR ("pattern", s->pattern == DS_PATTERN_SINE ? "sine" : "square");
  DBL ("period_px", s->period_px);
  DBL ("duty", s->duty);
  DBL ("black_level", s->black_level);
  if (s->harmonic_gain > 0)
    DBL ("harmonic_gain", s->harmonic_gain);
  if (s->edge_blur_known)
    DBL ("edge_blur_px", s->edge_blur_px);
  if (s->open_field_dn_per_ms > 0)
    DBL ("open_field_dn_per_ms", s->open_field_dn_per_ms);
  if (s->acceptance_half_angle_deg > 0)
    DBL ("acceptance_half_angle_deg", s->acceptance_half_angle_deg);
  if (s->saturation_dn > 0)
    DBL ("saturation_dn", s->saturation_dn);
  if (s->system_gain > 0) {
    DBL ("gain_dn_per_e", s->system_gain);
    DBL ("read_noise_dn", s->read_noise_dn);
  }
  BOOL ("dark_frame", s->dark_frame);
  INT ("phase_retries", s->phase_retries);
  BOOL ("verify_phase", s->verify_phase);
  BOOL ("detect_motion", s->detect_motion);
  BOOL ("save_phases", s->save_phases && !s->single_frame);
  /* Only in per-frame mode, so that a set's settings read as they always did. */
  if (s->per_frame)
    STR ("results", "per-frame");
  if (s->single_frame) {
    /* The resolution it costs: each pixel is computed from the window of ceil(P) columns
     * around it (proc/single_frame.h). */
    json_builder_set_member_name (b, "single_frame");
    json_builder_begin_object (b);
    STR ("estimator", ds_estimator_name (s->estimator));
    DBL ("period_px", s->period_px);
    INT ("window_px", ds_single_frame_window_px (s->period_px));
    STR ("window_axis", "x");
    json_builder_end_object (b);
  }
  if (s->automatic) {
    json_builder_set_member_name (b, "operating_point");
    json_builder_begin_object (b);
    ds_operating_report_to_json (&s->operating, b);
    json_builder_end_object (b);
  }
  DBL ("phase_tolerance_deg", s->phase_tolerance_deg);
  if (s->roi_width) {
    json_builder_set_member_name (b, "roi");
    json_builder_begin_object (b);
    INT ("x", s->roi_x);
    INT ("y", s->roi_y);
    INT ("width", s->roi_width);
    INT ("height", s->roi_height);
    json_builder_end_object (b);
  }
#undef INT
#undef DBL
#undef STR
#undef BOOL
  json_builder_end_object (b);
  return json_builder_get_root (b);
}

gboolean
ds_capture_settings_equal (const DsCaptureSettings *a, const DsCaptureSettings *b)
{
  return a->phases == b->phases && a->averages == b->averages && a->exposure_us == b->exposure_us &&
         a->gain_db == b->gain_db && a->estimator == b->estimator && a->pattern == b->pattern &&
         a->period_px == b->period_px && a->duty == b->duty && a->black_level == b->black_level &&
         a->harmonic_gain == b->harmonic_gain && a->edge_blur_known == b->edge_blur_known &&
         a->edge_blur_px == b->edge_blur_px && a->open_field_dn_per_ms == b->open_field_dn_per_ms &&
         strcmp (a->open_field_unused, b->open_field_unused) == 0 &&
         a->acceptance_half_angle_deg == b->acceptance_half_angle_deg &&
         a->saturation_dn == b->saturation_dn && a->system_gain == b->system_gain &&
         a->read_noise_dn == b->read_noise_dn &&
         a->dark_frame == b->dark_frame && a->phase_retries == b->phase_retries &&
         a->verify_phase == b->verify_phase && a->phase_tolerance_deg == b->phase_tolerance_deg &&
         a->save_phases == b->save_phases && a->per_frame == b->per_frame &&
         a->single_frame == b->single_frame && a->detect_motion == b->detect_motion;
}

void
ds_capture_settings_note_motion (DsCaptureSettings *s, const DsSeparationMeta *meta)
{
  if (!s->automatic)
    return;
  DsOperatingReport *r = &s->operating;
  r->motion_checked = meta->motion_checked;
  G_STATIC_ASSERT (DS_MASK_MOTION == 1 << 7);
  r->motion_pixels = meta->motion_checked ? meta->flagged[7] : 0;
  /* A declared speed's term is in the prediction already (or its absence marked). */
  if (!r->speed_declared && r->motion_pixels > 0)
    ds_motion_apply (&r->point, NAN, NAN, r->motion_pixels, &r->point.motion_why);
}
