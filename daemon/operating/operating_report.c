/* What an automatic capture records about its choice: the result's `settings.operating_point`
 * (docs/protocol.md), from what the probe and the choice stored; no probe math here. */
#include "daemon/operating/operating_point.h"

#include <math.h>

#include "daemon/operating/film_bound.h"

/* The declared speed and what it adds (docs/accuracy.md, "Moving objects"); null where none was
 * declared or the estimator's motion error has no model. */
static void
motion_to_json (const DsOperatingReport *r, JsonBuilder *b)
{
  const DsOperatingPoint *p = &r->point;
  gboolean motion_term = r->speed_declared && isfinite (p->motion_term);
  json_builder_set_member_name (b, "motion");
  json_builder_begin_object (b);
  json_builder_set_member_name (b, "speed_px_s");
  if (!r->speed_declared)
    json_builder_add_null_value (b);
  else
    json_builder_add_double_value (b, r->speed_px_s);
  json_builder_set_member_name (b, "term");
  if (motion_term)
    json_builder_add_double_value (b, p->motion_term);
  else
    json_builder_add_null_value (b);
  json_builder_set_member_name (b, "predicted_error_still");
  json_builder_add_double_value (b, p->predicted_error_still);
  json_builder_set_member_name (b, "set_span_ms");
  json_builder_add_double_value (b, p->motion_span_ms);
  json_builder_set_member_name (b, "checked");
  json_builder_add_boolean_value (b, r->motion_checked);
  json_builder_set_member_name (b, "pixels");
  json_builder_add_int_value (b, (gint64) r->motion_pixels);
  json_builder_end_object (b);
}

/* Which terms of the prediction rest on measurements (the pilot's or a calibration's) and which
 * on an assumption that widens its interval (docs/accuracy.md, "What is measured, what is
 * assumed"). */
static void
terms_to_json (const DsOperatingReport *r, JsonBuilder *b)
{
  const DsOperatingPoint *p = &r->point;
  const DsSceneProbe *pr = &r->probe;
  json_builder_set_member_name (b, "measured");
  json_builder_begin_array (b);
  json_builder_add_string_value (b, "noise");
  json_builder_add_string_value (b, "direct_light");
  if (pr->blur.source != DS_BLUR_ASSUMED_SHARP)
    json_builder_add_string_value (b, pr->blur.source == DS_BLUR_CALIBRATED ? "blur_calibrated" : "blur_fitted");
  if (pr->leak.measured)
    json_builder_add_string_value (b, "scattered_stripes");
  if (pr->loss.known)
    json_builder_add_string_value (b, "open_field_loss");
  if (pr->loss.unexplained && pr->loss.acceptance_deg > 0)
    json_builder_add_string_value (b, "acceptance_angle");
  json_builder_end_array (b);
  json_builder_set_member_name (b, "assumed");
  json_builder_begin_array (b);
  if (p->parts.blur_assumed || pr->blur.source == DS_BLUR_ASSUMED_SHARP)
    json_builder_add_string_value (b, "blur");
  if (p->parts.cancellation > 0)
    json_builder_add_string_value (b, "scattered_stripes_cancellation");
  if (!pr->leak.measured)
    json_builder_add_string_value (b, "scattered_stripes");
  if (pr->narrow.unresolved)
    json_builder_add_string_value (b, "narrow_kernel");
  if (pr->transfer.inconsistent)
    json_builder_add_string_value (b, "transfer");
  if (pr->loss.unexplained)
    json_builder_add_string_value (b, "light_scattered_into_cone");
  /* Its upper end (film_bound.h) rests on single Henyey-Greenstein scattering with g bounded. */
  if (pr->loss.bounded)
    json_builder_add_string_value (b, "film_single_scattering_g_max");
  if (!r->speed_declared)
    json_builder_add_string_value (b, "still_scene");
  json_builder_end_array (b);
}

void
ds_operating_report_to_json (const DsOperatingReport *r, JsonBuilder *b)
{
#define DBL(k, v) (json_builder_set_member_name (b, k), json_builder_add_double_value (b, v))
#define STR(k, v) (json_builder_set_member_name (b, k), json_builder_add_string_value (b, v))
#define BOOL(k, v) (json_builder_set_member_name (b, k), json_builder_add_boolean_value (b, v))
  const DsOperatingPoint *p = &r->point;
  const DsSceneProbe *pr = &r->probe;
  DBL ("target_error", r->target_error);
  DBL ("time_budget_ms", r->time_budget_ms);
  DBL ("predicted_error", p->predicted_error);
  /* The upper end the pilot bounds (docs/protocol.md): null where it bounds none, also for a lower
   * bound whose interval is the prediction alone: a number equal to the prediction would read as an
   * error known exactly. */
  json_builder_set_member_name (b, "predicted_error_upper");
  if (p->upper_bounded && isfinite (p->predicted_error_upper))
    json_builder_add_double_value (b, p->predicted_error_upper);
  else
    json_builder_add_null_value (b);
  DBL ("predicted_error_uncertainty", p->uncertainty);
  BOOL ("target_may_be_missed", p->target_may_be_missed);
  /* accepted: the upper end meets the target (or no target); undetermined: only the lower end does */
  STR ("decision", p->undetermined ? "undetermined" : "accepted");
  STR ("target_note", p->target_note);
  DBL ("predicted_time_ms", p->predicted_time_ms);
  DBL ("scale", r->scale);
  json_builder_set_member_name (b, "parts");
  json_builder_begin_object (b);
  DBL ("noise", p->parts.noise);
  DBL ("systematic", p->parts.systematic);
  DBL ("sampling", p->parts.sampling);
  DBL ("scattered_stripes", p->parts.scattered_stripes);
  DBL ("cancellation", p->parts.cancellation);
  json_builder_end_object (b);
  /* What the prediction contains: noise and the pattern's sampling always; the blur when it was
   * calibrated or measured; the scattered stripes when measured at two periods. Saturated
   * pixels are excluded from the error (and from the result's valid pixels), never chosen into. */
  json_builder_set_member_name (b, "contains");
  json_builder_begin_array (b);
  json_builder_add_string_value (b, "noise");
  json_builder_add_string_value (b, "sampling");
  if (pr->blur.source != DS_BLUR_ASSUMED_SHARP)
    json_builder_add_string_value (b, "blur");
  if (pr->leak.measured)
    json_builder_add_string_value (b, "scattered_stripes");
  json_builder_add_string_value (b, "saturation");
  /* The term exists only where a speed was declared (a point made otherwise has none). */
  gboolean motion_term = r->speed_declared && isfinite (p->motion_term);
  if (motion_term)
    json_builder_add_string_value (b, "motion");
  json_builder_end_array (b);
  terms_to_json (r, b);
  BOOL ("lower_bound", p->lower_bound);
  json_builder_set_member_name (b, "lower_bound_reasons");
  json_builder_begin_array (b);
  if (!pr->leak.measured)
    json_builder_add_string_value (b, pr->leak.note);
  if (pr->narrow.unresolved)
    json_builder_add_string_value (b, pr->narrow.note);
  if (pr->transfer.inconsistent)
    json_builder_add_string_value (b, pr->transfer.note);
  if (pr->loss.unexplained)
    json_builder_add_string_value (b, pr->loss.note);
  if (p->motion_why)
    json_builder_add_string_value (b, p->motion_why);
  json_builder_end_array (b);
  motion_to_json (r, b);
  json_builder_set_member_name (b, "assumptions");
  json_builder_begin_array (b);
  if (pr->blur.source == DS_BLUR_ASSUMED_SHARP) {
    g_autofree char *note = g_strdup_printf (
      "stripe blur neither calibrated (descatterctl calibrate) nor measurable from the pilot frames at %g px: "
      "sharp stripes for the prediction, a blur of %g px for its upper end",
      pr->geometry.period_px, MIN (DS_ERROR_MODEL_UNKNOWN_BLUR_PX, pr->geometry.period_px / 8));
    json_builder_add_string_value (b, note);
  }
  if (r->pattern_assumption[0])
    json_builder_add_string_value (b, r->pattern_assumption);
  if (pr->loss.unexplained && pr->loss.bounded) {
    g_autofree char *note = g_strdup_printf (
      "light a film scatters into the lens, with faces of index >= %.2f (refraction narrows the cone inside): "
      "%s; the upper end adds it to the prediction's",
      DS_FILM_MIN_INDEX, pr->loss.bound_note);
    json_builder_add_string_value (b, note);
  } else if (pr->loss.unexplained) {
    json_builder_add_string_value (b, pr->loss.bound_note);
  }
  json_builder_end_array (b);
  json_builder_set_member_name (b, "scene");
  json_builder_begin_object (b);
  DBL ("direct_dn", pr->light.ld_mean);
  DBL ("direct_spread", pr->light.ld_spread);
  DBL ("scattered_dn", pr->light.lg_mean);
  DBL ("noise_dn", pr->noise.at_mean_dn);
  DBL ("blur_px", pr->geometry.blur_px);
  STR ("blur_source", ds_blur_source_name (pr->blur.source));
  DBL ("scattered_stripes_at_period", pr->leak.at_period);
  STR ("scattered_stripes_note", pr->leak.note);
  DBL ("finest_period_px", pr->transfer.finest_period_px);
  DBL ("narrow_kernel_px", pr->narrow.kernel_px);
  DBL ("narrow_scattered_fraction", pr->narrow.fraction);
  STR ("narrow_kernel_note", pr->narrow.note);
  json_builder_set_member_name (b, "direct_dn_lower");
  if (pr->interval.set && pr->interval.unbounded)
    json_builder_add_null_value (b);
  else
    json_builder_add_double_value (b, pr->interval.set ? pr->interval.ld_lower : pr->light.ld_mean);
  STR ("direct_interval_note", pr->interval.set ? pr->interval.note : "");
  json_builder_set_member_name (b, "open_field_transmittance");
  if (pr->loss.known)
    json_builder_add_double_value (b, pr->loss.transmittance);
  else
    json_builder_add_null_value (b);
  STR ("open_field_note", pr->loss.note);
  /* The upper end of the bias a flagged film adds (film_bound.h); null where none. */
  json_builder_set_member_name (b, "film_bias_upper");
  if (pr->loss.unexplained && pr->loss.bounded)
    json_builder_add_double_value (b, pr->loss.bias_upper);
  else
    json_builder_add_null_value (b);
  STR ("film_bound_note", pr->loss.bound_note);
  DBL ("clip_dn", pr->clip.saturation_dn);
  BOOL ("clip_known", pr->clip.known);
  DBL ("saturated_fraction", pr->clip.saturated_fraction);
  DBL ("exposure_us", pr->exposure_us);
  json_builder_end_object (b);
  json_builder_set_member_name (b, "pilot_frames");
  json_builder_add_int_value (b, r->pilot_frames);
  DBL ("pilot_ms", r->pilot_ms);
#undef DBL
#undef STR
#undef BOOL
}
