/* One finished phase set as the daemon publishes it: its metadata and its wire payloads, built
 * lazily on the main thread and shared by every client and the spool. The frame counters it
 * reports are frame_counters.c's. */
#include "daemon/acquire/result.h"
#include "daemon/acquire/result_planes.h"

#include <math.h>
#include <string.h>

#include "daemon/output/phase_folder_write.h"
#include "daemon/output/result_meta.h"

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
  DsLastFrameTimes last_frame;
  gint64 finished_real_us;   /* wall clock when the result was made: dates the monotonic times */
  gboolean have_provenance;
  DsResultProvenance provenance;
  DsRawFrames *raw;
  gboolean have_window;
  DsResultWindow window;
  JsonNode *meta;            /* built once, on the main thread */
  PayloadSet payloads[2][2]; /* [format][extrema] */
  /* The raw frames as payloads, built on demand. */
  GArray *raw_infos;         /* DsPayloadInfo; names in raw_names */
  GPtrArray *raw_bytes, *raw_names;
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
  ds_capture_settings_note_motion (&r->settings, &sep->meta);
  r->counters = *counters;
  r->started_us = started_us;
  r->acquired_us = acquired_us;
  r->finished_us = finished_us;
  r->finished_real_us = g_get_real_time () - (g_get_monotonic_time () - finished_us);
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
  if (result->raw_infos) {
    g_array_unref (result->raw_infos);
    g_ptr_array_unref (result->raw_bytes);
    g_ptr_array_unref (result->raw_names);
  }
  if (result->meta)
    json_node_unref (result->meta);
  ds_raw_frames_free (result->raw);
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

void
ds_result_set_provenance (DsResult *result, const DsResultProvenance *provenance)
{
  g_return_if_fail (result->meta == NULL);
  result->provenance = *provenance;
  result->have_provenance = TRUE;
}

void
ds_result_set_raw_frames (DsResult *result, DsRawFrames *raw)
{
  ds_raw_frames_free (result->raw);
  result->raw = raw;
}

void
ds_result_set_last_frame_times (DsResult *result, const DsLastFrameTimes *times)
{
  result->last_frame = *times;
}

void
ds_result_set_window (DsResult *result, const DsResultWindow *window)
{
  result->window = *window;
  result->have_window = TRUE;
}

gboolean
ds_result_per_frame (const DsResult *result)
{
  return result->have_window;
}

const DsRawFrames *
ds_result_raw_frames (const DsResult *result)
{
  return result->raw;
}

static void
add_string (JsonBuilder *b, const char *key, const char *v)
{
  json_builder_set_member_name (b, key);
  json_builder_add_string_value (b, v);
}

static void
add_int (JsonBuilder *b, const char *key, gint64 v)
{
  json_builder_set_member_name (b, key);
  json_builder_add_int_value (b, v);
}

/* The time of a monotonic instant of this result, on the wall clock. */
static char *
utc_of (const DsResult *r, gint64 monotonic_us)
{
  gint64 us = r->finished_real_us - (r->finished_us - monotonic_us);
  g_autoptr (GDateTime) s = g_date_time_new_from_unix_utc (us / G_USEC_PER_SEC);
  g_autoptr (GDateTime) t = g_date_time_add (s, us % G_USEC_PER_SEC);
  return ds_output_time_string (t);
}

static void
add_camera (JsonBuilder *b, const DsResult *r)
{
  const DsResultProvenance *p = &r->provenance;
  json_builder_set_member_name (b, "camera");
  json_builder_begin_object (b);
  add_string (b, "backend", p->camera_backend);
  add_string (b, "vendor", p->camera.vendor);
  add_string (b, "model", p->camera.model);
  add_string (b, "serial", p->camera.serial);
  add_string (b, "address", p->camera.address);
  add_string (b, "pixel_format", p->pixel_format);
  /* The ADC's depth, as the separation applied it: the saturation level is 2^depth - 1. */
  double sat = r->sep->meta.saturation_level;
  if (isfinite (sat) && sat >= 1 && sat <= 65535 && fmod (log2 (sat + 1), 1.0) == 0)
    add_int (b, "bit_depth", (gint64) log2 (sat + 1));
  add_int (b, "sensor_width", p->camera.sensor_width);
  add_int (b, "sensor_height", p->camera.sensor_height);
  json_builder_set_member_name (b, "roi");
  json_builder_begin_object (b);
  add_int (b, "x", p->roi_width ? p->roi_x : 0);
  add_int (b, "y", p->roi_width ? p->roi_y : 0);
  add_int (b, "width", r->sep->transmissive->width);
  add_int (b, "height", r->sep->transmissive->height);
  json_builder_end_object (b);
  json_builder_end_object (b);
  json_builder_set_member_name (b, "illuminator");
  json_builder_begin_object (b);
  add_string (b, "backend", p->illuminator_backend);
  ds_json_add_double_or_null (b, "temperature_c", p->illuminator_temperature_c);
  add_string (b, "trigger", p->trigger_backend);
  json_builder_end_object (b);
}

/* The physical scale: optics.{sensor_pixel_pitch_um, pitch_source, magnification} and the
 * object-plane pixel_size_um = pitch / magnification, or null with pixel_size_note saying which
 * of the two is missing (docs/protocol.md, "Result metadata"). */
static void
add_pixel_size (JsonBuilder *b, const DsResult *r)
{
  const DsResultProvenance *p = &r->provenance;
  double pitch = r->have_provenance ? p->pixel_pitch_um : NAN;
  double m = r->have_provenance ? p->magnification : NAN;
  gboolean known = isfinite (pitch) && pitch > 0 && isfinite (m) && m > 0;
  json_builder_set_member_name (b, "optics");
  json_builder_begin_object (b);
  ds_json_add_double_or_null (b, "sensor_pixel_pitch_um", pitch);
  json_builder_set_member_name (b, "pitch_source");
  if (isfinite (pitch))
    json_builder_add_string_value (b, p->pixel_pitch_source);
  else
    json_builder_add_null_value (b);
  ds_json_add_double_or_null (b, "magnification", m);
  json_builder_end_object (b);
  ds_json_add_double_or_null (b, "pixel_size_um", known ? pitch / m : NAN);
  g_autofree char *note = NULL;
  if (known)
    note = g_strdup_printf ("object-plane pixel size = sensor pixel pitch %.6g um (%s) / magnification %.6g", pitch,
                            strcmp (p->pixel_pitch_source, "camera") == 0 ? "the camera's SensorPixelWidth"
                                                                          : "[camera] pixel-pitch-um",
                            m);
  else
    note = g_strdup_printf ("unknown: %s%s%s", isfinite (pitch) ? "" : "no pixel pitch ([camera] pixel-pitch-um unset, "
                                                                        "the camera has no SensorPixelWidth)",
                            !isfinite (pitch) && !isfinite (m) ? " and " : "",
                            isfinite (m) ? "" : "no magnification ([optics] magnification unset)");
  add_string (b, "pixel_size_note", note);
}

static void
add_pattern (JsonBuilder *b, const DsResult *r)
{
  const DsCaptureSettings *s = &r->settings;
  json_builder_set_member_name (b, "pattern");
  json_builder_begin_object (b);
  add_string (b, "kind", s->pattern == DS_PATTERN_SINE ? "sine" : "square");
  ds_json_add_double_or_null (b, "period_px", s->period_px);
  ds_json_add_double_or_null (b, "duty", s->duty);
  ds_json_add_double_or_null (b, "black_level", s->black_level);
  ds_json_add_double_or_null (b, "phase_offset_cycles",
                              r->have_provenance ? r->provenance.phase_offset_cycles : NAN);
  json_builder_end_object (b);
}

static char *raw_payload_name (const DsRawFrames *raw, guint i);

static void
add_raw_frames (JsonBuilder *b, const DsRawFrames *raw)
{
  json_builder_set_member_name (b, "raw_frames");
  json_builder_begin_object (b);
  add_int (b, "n_phases", raw->n_phases);
  json_builder_set_member_name (b, "frames");
  json_builder_begin_array (b);
  for (guint i = 0; i < raw->frames->len; i++) {
    const DsRawFrame *f = raw->frames->pdata[i];
    g_autofree char *name = raw_payload_name (raw, i);
    json_builder_begin_object (b);
    add_string (b, "payload", name);
    add_int (b, "phase", f->phase);
    add_int (b, "frame_id", (gint64) f->frame_id);
    add_int (b, "timestamp_ns", (gint64) f->timestamp_ns);
    add_int (b, "bit_depth", f->image->bit_depth);
    json_builder_end_object (b);
  }
  json_builder_end_array (b);
  json_builder_set_member_name (b, "black_frame_ids");
  json_builder_begin_array (b);
  for (guint i = 0; i < raw->black_ids->len; i++)
    json_builder_add_int_value (b, (gint64) g_array_index (raw->black_ids, guint64, i));
  json_builder_end_array (b);
  if (raw->black)
    add_int (b, "black_bit_depth", raw->black->bit_depth);
  json_builder_end_object (b);
}

static JsonNode *
build_meta (DsResult *r)
{
  const DsResultProvenance *p = &r->provenance;
  g_autoptr (JsonBuilder) b = json_builder_new ();
  json_builder_begin_object (b);
  add_string (b, "format", DS_RESULT_FORMAT);
  add_int (b, "version", DS_RESULT_FORMAT_VERSION);
  add_int (b, "set_id", (gint64) r->set_id);
  g_autofree char *start = utc_of (r, r->started_us);
  g_autofree char *end = utc_of (r, r->acquired_us ? r->acquired_us : r->finished_us);
  add_string (b, "time_utc", start);
  add_string (b, "time_utc_end", end);
  add_int (b, "width", r->sep->transmissive->width);
  add_int (b, "height", r->sep->transmissive->height);
  g_autoptr (JsonNode) producer = ds_output_producer_json (p->program[0] ? p->program : "descatterd");
  if (r->have_provenance)
    json_object_set_string_member (json_node_get_object (producer), "config_sha256", p->config_sha256);
  json_builder_set_member_name (b, "producer");
  json_builder_add_value (b, g_steal_pointer (&producer));
  if (r->have_provenance)
    add_camera (b, r);
  add_pixel_size (b, r);
  add_pattern (b, r);
  json_builder_set_member_name (b, "settings");
  json_builder_add_value (b, ds_capture_settings_to_json (&r->settings));
  json_builder_set_member_name (b, "separation");
  json_builder_add_value (b, ds_output_separation_json (&r->sep->meta));
  const char *planes[] = { "transmissive", "f32", "scattered", "f32", "mask", "u8",
                           r->sep->max ? "max" : NULL, "f32", "min", "f32", "mean", "f32", NULL };
  json_builder_set_member_name (b, "planes");
  json_builder_add_value (b, ds_output_planes_json (planes));
  json_builder_set_member_name (b, "mask_bits");
  json_builder_add_value (b, ds_output_mask_bits_json ());
  json_builder_set_member_name (b, "frames");
  json_builder_add_value (b, ds_frame_counters_to_json (&r->counters));
  json_builder_set_member_name (b, "timing_ms");
  json_builder_begin_object (b);
  json_builder_set_member_name (b, "acquisition");
  json_builder_add_double_value (b, (double) (r->acquired_us - r->started_us) / 1000.0);
  json_builder_set_member_name (b, "compute_after_last_frame");
  json_builder_add_double_value (b, (double) (r->finished_us - r->acquired_us) / 1000.0);
  const DsLastFrameTimes *lf = &r->last_frame;
  /* A camera that does not stamp its frames' arrival leaves the collect's time as the last
   * frame's, after its job: no parts then. */
  gboolean lf_known = lf->verify_started_us > 0 && lf->verify_started_us >= r->acquired_us;
  if (lf_known) {
    /* The parts of compute_after_last_frame: what remains is the copy of the last raw frame
     * when they are kept, the set's finalize when not folded on it, its phase check as a
     * whole, and the bookkeeping. */
    json_builder_set_member_name (b, "last_frame_wait");
    json_builder_add_double_value (b, (double) (lf->verify_started_us - r->acquired_us) / 1000.0);
    json_builder_set_member_name (b, "last_frame_verify");
    json_builder_add_double_value (b, (double) (lf->verified_us - lf->verify_started_us) / 1000.0);
    json_builder_set_member_name (b, "last_frame_fold");
    json_builder_add_double_value (b, (double) (lf->folded_us - lf->verified_us) / 1000.0);
  }
  json_builder_end_object (b);
  /* CLOCK_MONOTONIC is one clock for the whole machine: a local client can measure the
   * latency from the last frame to its own receipt of the result. */
  json_builder_set_member_name (b, "monotonic_us");
  json_builder_begin_object (b);
  add_int (b, "started", r->started_us);
  add_int (b, "last_frame", r->acquired_us);
  if (lf_known) {
    add_int (b, "last_frame_verify_started", lf->verify_started_us);
    add_int (b, "last_frame_verified", lf->verified_us);
    add_int (b, "last_frame_folded", lf->folded_us);
  }
  add_int (b, "finished", r->finished_us);
  json_builder_end_object (b);
  if (r->raw)
    add_raw_frames (b, r->raw);
  if (r->have_window) {
    json_builder_set_member_name (b, "window");
    json_builder_begin_object (b);
    add_int (b, "frames", r->window.frames);
    add_int (b, "span", (gint64) r->window.span);
    add_int (b, "newest_frame_id", (gint64) r->window.newest_frame_id);
    add_int (b, "since_break", (gint64) r->window.since_break);
    add_int (b, "breaks", (gint64) r->window.breaks);
    add_string (b, "last_break", r->window.last_break);
    json_builder_end_object (b);
  }
  json_builder_end_object (b);
  return json_builder_get_root (b);
}

JsonNode *
ds_result_to_json (DsResult *r)
{
  if (!r->meta)
    r->meta = build_meta (r);
  return json_node_ref (r->meta);
}

void
ds_result_to_output (DsResult *r, DsOutputResult *planes)
{
  g_autoptr (JsonNode) meta = ds_result_to_json (r);
  *planes = (DsOutputResult){
    .transmissive = r->sep->transmissive, .scattered = r->sep->scattered, .mask = r->sep->mask,
    .max = r->sep->max, .min = r->sep->min, .mean = r->sep->mean,
    .sigma_transmissive = r->sep->sigma_transmissive, .sigma_scattered = r->sep->sigma_scattered,
    .raw = r->raw, .meta = ds_json_deep_copy (meta),
  };
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

static char *
raw_payload_name (const DsRawFrames *raw, guint i)
{
  /* The phase folder's file name without ".png": a client writes the folder from the names. */
  g_autofree char *file = ds_phase_folder_frame_name (raw, i);
  return g_strndup (file, strlen (file) - strlen (".png"));
}

static void
add_raw_payload (DsResult *r, char *name, const DsImage *img)
{
  DsPayloadInfo info = { 0 };
  g_ptr_array_add (r->raw_names, name);
  info.name = name;
  info.dtype = img->type == DS_SAMPLE_U16 ? "u16" : "u8";
  info.width = img->width;
  info.height = img->height;
  GBytes *bytes = ds_image_to_packed_bytes (img);
  info.bytes = g_bytes_get_size (bytes);
  g_ptr_array_add (r->raw_bytes, bytes);
  g_array_append_val (r->raw_infos, info);
}

guint
ds_result_raw_payloads (DsResult *r, const DsPayloadInfo **infos, GBytes *const **bytes)
{
  if (!r->raw)
    return 0;
  if (!r->raw_infos) {
    r->raw_infos = g_array_new (FALSE, FALSE, sizeof (DsPayloadInfo));
    r->raw_bytes = g_ptr_array_new_with_free_func ((GDestroyNotify) g_bytes_unref);
    r->raw_names = g_ptr_array_new_with_free_func (g_free);
    for (guint i = 0; i < r->raw->frames->len; i++)
      add_raw_payload (r, raw_payload_name (r->raw, i), ((const DsRawFrame *) r->raw->frames->pdata[i])->image);
    if (r->raw->black)
      add_raw_payload (r, g_strdup ("black"), r->raw->black);
  }
  *infos = (const DsPayloadInfo *) r->raw_infos->data;
  *bytes = (GBytes *const *) r->raw_bytes->pdata;
  return r->raw_infos->len;
}
