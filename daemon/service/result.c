#include "daemon/service/result.h"

#include <math.h>

#include "build_info.h"
#include "daemon/service/result_planes.h"

static const char *const drop_names[DS_DROP_N_REASONS] = {
  [DS_DROP_INCOMPLETE] = "incomplete",   [DS_DROP_FRAME_GAP] = "frame_gap",
  [DS_DROP_WRONG_PHASE] = "wrong_phase", [DS_DROP_STALE] = "stale",
  [DS_DROP_UNVERIFIABLE] = "unverifiable", [DS_DROP_ABORTED] = "aborted",
  [DS_DROP_PREVIEW] = "preview",
};

const char *
ds_drop_reason_name (DsDropReason reason)
{
  return (guint) reason < DS_DROP_N_REASONS ? drop_names[reason] : "unknown";
}

void
ds_frame_counters_drop (DsFrameCounters *c, DsDropReason reason, guint64 n)
{
  g_return_if_fail ((guint) reason < DS_DROP_N_REASONS);
  c->dropped += n;
  c->by_reason[reason] += n;
}

void
ds_frame_counters_add (DsFrameCounters *total, const DsFrameCounters *part)
{
  total->acquired += part->acquired;
  total->folded += part->folded;
  total->dropped += part->dropped;
  for (guint i = 0; i < DS_DROP_N_REASONS; i++)
    total->by_reason[i] += part->by_reason[i];
  total->retries += part->retries;
  total->timeouts += part->timeouts;
  total->device_errors += part->device_errors;
}

JsonNode *
ds_frame_counters_to_json (const DsFrameCounters *c)
{
  g_autoptr (JsonBuilder) b = json_builder_new ();
  json_builder_begin_object (b);
  json_builder_set_member_name (b, "acquired");
  json_builder_add_int_value (b, (gint64) c->acquired);
  json_builder_set_member_name (b, "folded");
  json_builder_add_int_value (b, (gint64) c->folded);
  json_builder_set_member_name (b, "retries");
  json_builder_add_int_value (b, (gint64) c->retries);
  json_builder_set_member_name (b, "timeouts");
  json_builder_add_int_value (b, (gint64) c->timeouts);
  json_builder_set_member_name (b, "device_errors");
  json_builder_add_int_value (b, (gint64) c->device_errors);
  json_builder_set_member_name (b, "dropped");
  json_builder_add_int_value (b, (gint64) c->dropped);
  json_builder_set_member_name (b, "dropped_by_reason");
  json_builder_begin_object (b);
  for (guint i = 0; i < DS_DROP_N_REASONS; i++) {
    json_builder_set_member_name (b, drop_names[i]);
    json_builder_add_int_value (b, (gint64) c->by_reason[i]);
  }
  json_builder_end_object (b);
  json_builder_end_object (b);
  return json_builder_get_root (b);
}

typedef struct {
  gboolean built;
  guint n;
  DsPayloadInfo infos[6];
  GBytes *bytes[6];
} PayloadSet;

struct DsResult {
  gint ref;
  guint64 set_id;
  DsResultPlanes *planes;  /* shared with the payloads sent from it */
  const DsSeparation *sep; /* the planes' separation */
  DsCaptureSettings settings;
  DsFrameCounters counters;
  gint64 started_us, acquired_us, finished_us;
  PayloadSet payloads[2][2]; /* [format][extrema] */
};

DsResult *
ds_result_new (guint64 set_id, DsSeparation *sep, DsPlanePool *pool, const DsCaptureSettings *settings,
               const DsFrameCounters *counters, gint64 started_us, gint64 acquired_us, gint64 finished_us)
{
  DsResult *r = g_new0 (DsResult, 1);
  r->ref = 1;
  r->set_id = set_id;
  r->planes = ds_result_planes_new (sep, pool);
  r->sep = sep;
  r->settings = *settings;
  r->counters = *counters;
  r->started_us = started_us;
  r->acquired_us = acquired_us;
  r->finished_us = finished_us;
  return r;
}

DsResult *
ds_result_ref (DsResult *result)
{
  g_atomic_int_inc (&result->ref);
  return result;
}

void
ds_result_unref (DsResult *result)
{
  if (!result || !g_atomic_int_dec_and_test (&result->ref))
    return;
  for (guint f = 0; f < 2; f++)
    for (guint e = 0; e < 2; e++)
      for (guint i = 0; i < result->payloads[f][e].n; i++)
        g_bytes_unref (result->payloads[f][e].bytes[i]);
  ds_result_planes_unref (result->planes);
  g_free (result);
}

guint64
ds_result_set_id (const DsResult *result)
{
  return result->set_id;
}

const DsSeparation *
ds_result_separation (const DsResult *result)
{
  return result->sep;
}

const DsCaptureSettings *
ds_result_settings (const DsResult *result)
{
  return &result->settings;
}

static void
add_double_or_null (JsonBuilder *b, const char *key, double v)
{
  json_builder_set_member_name (b, key);
  if (isfinite (v))
    json_builder_add_double_value (b, v);
  else
    json_builder_add_null_value (b);
}

JsonNode *
ds_result_to_json (DsResult *r)
{
  const DsSeparationMeta *m = &r->sep->meta;
  g_autoptr (JsonBuilder) b = json_builder_new ();
  json_builder_begin_object (b);
  json_builder_set_member_name (b, "set_id");
  json_builder_add_int_value (b, (gint64) r->set_id);
  /* Which build made the result: a figure is traced to the code that computed it. */
  json_builder_set_member_name (b, "software");
  json_builder_begin_object (b);
  json_builder_set_member_name (b, "name");
  json_builder_add_string_value (b, "descatterd");
  json_builder_set_member_name (b, "version");
  json_builder_add_string_value (b, DS_VERSION);
  json_builder_set_member_name (b, "build");
  json_builder_add_string_value (b, DS_GIT_DESCRIBE);
  json_builder_end_object (b);
  json_builder_set_member_name (b, "width");
  json_builder_add_int_value (b, r->sep->transmissive->width);
  json_builder_set_member_name (b, "height");
  json_builder_add_int_value (b, r->sep->transmissive->height);
  json_builder_set_member_name (b, "settings");
  json_builder_add_value (b, ds_capture_settings_to_json (&r->settings));
  json_builder_set_member_name (b, "separation");
  json_builder_begin_object (b);
  json_builder_set_member_name (b, "estimator");
  json_builder_add_string_value (b, ds_estimator_name (m->estimator));
  json_builder_set_member_name (b, "phases");
  json_builder_add_int_value (b, m->n_phases);
  json_builder_set_member_name (b, "frames_per_phase");
  json_builder_add_int_value (b, m->frames_per_phase);
  add_double_or_null (b, "duty", m->duty);
  add_double_or_null (b, "black_level", m->black_level);
  add_double_or_null (b, "pattern_mean", m->pattern_mean);
  add_double_or_null (b, "harmonic_gain", m->harmonic_gain);
  json_builder_set_member_name (b, "dark_subtracted");
  json_builder_add_boolean_value (b, m->dark_subtracted);
  add_double_or_null (b, "noise_dn", m->noise_dn);
  json_builder_set_member_name (b, "valid_pixels");
  json_builder_add_int_value (b, (gint64) m->valid_pixels);
  static const char *const bit_names[DS_MASK_N_BITS] = { "saturated", "dark", "low_modulation",
                                                         "nonfinite", "negative", "dark_exceeds" };
  json_builder_set_member_name (b, "flagged");
  json_builder_begin_object (b);
  for (guint i = 0; i < DS_MASK_N_BITS; i++) {
    json_builder_set_member_name (b, bit_names[i]);
    json_builder_add_int_value (b, (gint64) m->flagged[i]);
  }
  json_builder_end_object (b);
  json_builder_end_object (b);
  json_builder_set_member_name (b, "frames");
  json_builder_add_value (b, ds_frame_counters_to_json (&r->counters));
  json_builder_set_member_name (b, "timing_ms");
  json_builder_begin_object (b);
  json_builder_set_member_name (b, "acquisition");
  json_builder_add_double_value (b, (double) (r->acquired_us - r->started_us) / 1000.0);
  json_builder_set_member_name (b, "compute_after_last_frame");
  json_builder_add_double_value (b, (double) (r->finished_us - r->acquired_us) / 1000.0);
  json_builder_end_object (b);
  /* CLOCK_MONOTONIC is one clock for the whole machine: a local client can measure the
   * latency from the last frame to its own receipt of the result. */
  json_builder_set_member_name (b, "monotonic_us");
  json_builder_begin_object (b);
  json_builder_set_member_name (b, "started");
  json_builder_add_int_value (b, r->started_us);
  json_builder_set_member_name (b, "last_frame");
  json_builder_add_int_value (b, r->acquired_us);
  json_builder_set_member_name (b, "finished");
  json_builder_add_int_value (b, r->finished_us);
  json_builder_end_object (b);
  json_builder_end_object (b);
  return json_builder_get_root (b);
}

/* f32 planes and the mask go out as they are (GBytes over the planes, no copy); u16 is a
 * conversion, made once per result and format. */
static void
add_payload (DsResult *r, PayloadSet *ps, const char *name, const DsImage *img, DsOutputFormat format)
{
  DsPayloadInfo *info = &ps->infos[ps->n];
  info->name = name;
  info->width = img->width;
  info->height = img->height;
  if (format == DS_OUTPUT_U16 && img->type == DS_SAMPLE_F32) {
    DsImage *converted = ds_image_convert_f32_clamped (img, DS_SAMPLE_U16, 65535.0, NULL);
    gsize row = (gsize) converted->width * 2;
    if (converted->stride == row)
      ps->bytes[ps->n] = g_bytes_new_with_free_func (converted->data, row * converted->height,
                                                     (GDestroyNotify) ds_image_free, converted);
    else {
      ps->bytes[ps->n] = ds_image_to_packed_bytes (converted);
      ds_image_free (converted);
    }
    info->dtype = "u16";
  } else {
    ps->bytes[ps->n] = ds_result_planes_bytes (r->planes, img);
    info->dtype = img->type == DS_SAMPLE_F32 ? "f32" : img->type == DS_SAMPLE_U16 ? "u16" : "u8";
  }
  info->bytes = g_bytes_get_size (ps->bytes[ps->n]);
  ps->n++;
}

guint
ds_result_payloads (DsResult *r, DsOutputFormat format, gboolean extrema, const DsPayloadInfo **infos,
                    GBytes *const **bytes)
{
  extrema = extrema && r->sep->max != NULL;
  PayloadSet *ps = &r->payloads[format == DS_OUTPUT_U16][extrema ? 1 : 0];
  if (!ps->built) {
    add_payload (r, ps, "transmissive", r->sep->transmissive, format);
    add_payload (r, ps, "scattered", r->sep->scattered, format);
    add_payload (r, ps, "mask", r->sep->mask, format);
    if (extrema) {
      add_payload (r, ps, "max", r->sep->max, format);
      add_payload (r, ps, "min", r->sep->min, format);
      add_payload (r, ps, "mean", r->sep->mean, format);
    }
    ps->built = TRUE;
  }
  *infos = ps->infos;
  *bytes = ps->bytes;
  return ps->n;
}
