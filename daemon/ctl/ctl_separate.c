/* `descatterctl separate DIR`: offline separation of a folder of phase images (the ICCP 2013
 * authors' layout, see proc/phase_folder.h). No daemon involved.
 *
 * Outputs (in --out, default DIR itself, which is what the authors' scripts do; a rerun skips
 * them as inputs):
 *   direct.png, global.png   the transmissive and scattered components as 16-bit PNG, scaled
 *                            by the power of two that makes them visible (value = file / scale;
 *                            the scale is in separation.json's "files"), the layout of the
 *                            authors' scripts. Float input gives direct.tiff / global.tiff.
 *   transmissive.tiff, scattered.tiff   float32, unclipped (noise may make them negative;
 *                            the mask says where); tags carry separation.json's metadata
 *   mask.png                 u8 quality flags (proc/separation.h, docs/estimators.md)
 *   transmissive-preview.png, scattered-preview.png   8-bit pictures for people (0.5th..99.5th
 *                            percentile), unless --no-preview; not for measurement
 *   max.tiff, min.tiff, mean.tiff       float32, with --extrema
 *   sigma_transmissive.tiff, sigma_scattered.tiff   with a noise model (--system-gain)
 *   separation.json          inputs, parameters, and the metadata keys of the daemon's results
 *                            (producer, separation, planes, mask_bits; daemon/output/result_meta.h);
 *                            written last, so a folder with it is complete. Every file is written
 *                            atomically. */
#include <errno.h>
#include <glib/gstdio.h>
#include <json-glib/json-glib.h>
#include <math.h>
#include <stdio.h>

#include "daemon/ctl/ctl_separate.h"
#include "daemon/ctl/ctl_globals.h"
#include "daemon/ctl/ctl_folder.h"
#include "daemon/output/result_files.h"
#include "daemon/output/result_meta.h"
#include "daemon/output/tiff_file.h"
#include "proc/phase_folder.h"
#include "proc/preview.h"
#include "proc/proc_error.h"
#include "proc/separation.h"

typedef struct {
  char *estimator;
  char *pattern;
  double duty, black_level, harmonic_gain, system_gain, read_noise, saturation;
  double period, edge_blur;
  int bit_depth;
  char *out;
  gboolean extrema;
  gboolean quiet;
  gboolean no_preview;
  gboolean no_phase_check, strict_phases;
  gboolean detect_motion, no_detect_motion;
  gint64 max_side, max_pixels, max_memory_mib;
} Options;

/* Where the outputs go and what they are: the sidecar lists every file with its kind. */
typedef struct {
  const char *dir;
  JsonNode *meta;      /* the metadata the TIFF tags carry */
  GPtrArray *written;  /* basenames */
  JsonBuilder *files;  /* inside an object: name -> {kind, plane, scale} */
} Outputs;

static void
record (Outputs *o, const char *name, const char *kind, const char *plane, double scale)
{
  g_ptr_array_add (o->written, g_strdup (name));
  json_builder_set_member_name (o->files, name);
  json_builder_begin_object (o->files);
  json_builder_set_member_name (o->files, "kind");
  json_builder_add_string_value (o->files, kind);
  if (plane) {
    json_builder_set_member_name (o->files, "plane");
    json_builder_add_string_value (o->files, plane);
  }
  if (!isnan (scale)) {
    json_builder_set_member_name (o->files, "scale");
    json_builder_add_double_value (o->files, scale);
  }
  json_builder_end_object (o->files);
}

/* Float planes go to TIFF with the metadata in their tags; the rest to PNG. */
static gboolean
write_image (Outputs *o, const DsImage *img, const char *name, const char *plane, GError **error)
{
  g_autofree char *path = g_build_filename (o->dir, name, NULL);
  if (img->type == DS_SAMPLE_F32) {
    g_autoptr (JsonNode) desc = ds_json_deep_copy (o->meta);
    json_object_set_string_member (json_node_get_object (desc), "plane", plane);
    g_autofree char *text = json_to_string (desc, FALSE);
    DsTiffTags tags = { .description = text, .document_name = plane };
    if (!ds_tiff_write (img, path, &tags, error))
      return FALSE;
    record (o, name, "tiff", plane, NAN);
    return TRUE;
  }
  if (!ds_image_write (img, path, error))
    return FALSE;
  record (o, name, "png", plane, NAN);
  return TRUE;
}

/* direct/global as the authors' scripts store them: 16-bit PNG for integer input, scaled so
 * that they are visible (the scale is recorded); float input keeps float TIFF. */
static gboolean
write_like_input (Outputs *o, const DsImage *component, const DsPhaseFolder *folder, const char *stem,
                  const char *plane, GError **error)
{
  if (folder->type == DS_SAMPLE_F32) {
    g_autofree char *name = g_strconcat (stem, ".tiff", NULL);
    return write_image (o, component, name, plane, error);
  }
  double scale;
  g_autoptr (DsImage) img = ds_png16_scaled (component, &scale, error);
  if (!img)
    return FALSE;
  g_autofree char *name = g_strconcat (stem, ".png", NULL);
  g_autofree char *path = g_build_filename (o->dir, name, NULL);
  if (!ds_image_write (img, path, error))
    return FALSE;
  record (o, name, "png16", plane, scale);
  return TRUE;
}

/* The metadata of the outputs, with the keys of the daemon's results where they say the same
 * thing (daemon/output/result_meta.h); the list of files is added once they are written. */
static JsonNode *
build_sidecar (const DsPhaseFolder *folder, const DsSeparationParams *params, const DsSeparation *sep)
{
  g_autoptr (JsonBuilder) b = json_builder_new ();
  json_builder_begin_object (b);
  json_builder_set_member_name (b, "format");
  json_builder_add_string_value (b, DS_RESULT_FORMAT);
  json_builder_set_member_name (b, "version");
  json_builder_add_int_value (b, DS_RESULT_FORMAT_VERSION);
  json_builder_set_member_name (b, "tool");
  json_builder_add_string_value (b, "descatterctl separate");
  json_builder_set_member_name (b, "producer");
  json_builder_add_value (b, ds_output_producer_json ("descatterctl separate"));
  g_autoptr (GDateTime) now = g_date_time_new_now_utc ();
  g_autofree char *stamp = ds_output_time_string (now);
  json_builder_set_member_name (b, "processed_utc");
  json_builder_add_string_value (b, stamp);
  json_builder_set_member_name (b, "width");
  json_builder_add_int_value (b, sep->transmissive->width);
  json_builder_set_member_name (b, "height");
  json_builder_add_int_value (b, sep->transmissive->height);
  /* A phase folder holds no optics: the files get index axes and no resolution tags. */
  json_builder_set_member_name (b, "pixel_size_um");
  json_builder_add_null_value (b);
  json_builder_set_member_name (b, "pixel_size_note");
  json_builder_add_string_value (b, "unknown: descatterctl separate reads no pixel pitch or magnification");

  json_builder_set_member_name (b, "inputs");
  json_builder_begin_object (b);
  json_builder_set_member_name (b, "folder");
  json_builder_add_string_value (b, folder->dir);
  json_builder_set_member_name (b, "phases");
  json_builder_begin_array (b);
  for (guint k = 0; k < folder->phase_files->len; k++)
    json_builder_add_string_value (b, folder->phase_files->pdata[k]);
  json_builder_end_array (b);
  json_builder_set_member_name (b, "black");
  if (folder->black_file)
    json_builder_add_string_value (b, folder->black_file);
  else
    json_builder_add_null_value (b);
  json_builder_set_member_name (b, "skipped");
  json_builder_begin_array (b);
  for (guint i = 0; i < folder->skipped->len; i++)
    json_builder_add_string_value (b, folder->skipped->pdata[i]);
  if (folder->white_file)
    json_builder_add_string_value (b, folder->white_file);
  json_builder_end_array (b);
  json_builder_set_member_name (b, "width");
  json_builder_add_int_value (b, folder->width);
  json_builder_set_member_name (b, "height");
  json_builder_add_int_value (b, folder->height);
  json_builder_set_member_name (b, "sample_type");
  json_builder_add_string_value (b, ds_sample_type_name (folder->type));
  json_builder_set_member_name (b, "bit_depth");
  json_builder_add_int_value (b, folder->ref_bit_depth);
  json_builder_end_object (b);

  json_builder_set_member_name (b, "params");
  json_builder_begin_object (b);
  json_builder_set_member_name (b, "estimator");
  json_builder_add_string_value (b, ds_estimator_name (params->estimator));
  json_builder_set_member_name (b, "pattern");
  json_builder_add_string_value (b, params->pattern == DS_PATTERN_SINE ? "sine" : "square");
  json_builder_set_member_name (b, "duty");
  json_builder_add_double_value (b, params->duty);
  json_builder_set_member_name (b, "black_level");
  json_builder_add_double_value (b, params->black_level);
  json_builder_set_member_name (b, "harmonic_gain");
  json_builder_add_double_value (b, params->harmonic_gain);
  json_builder_set_member_name (b, "saturation_level");
  json_builder_add_double_value (b, params->saturation_level);
  json_builder_set_member_name (b, "system_gain");
  json_builder_add_double_value (b, params->system_gain);
  json_builder_set_member_name (b, "read_noise_dn");
  json_builder_add_double_value (b, params->read_noise_dn);
  json_builder_set_member_name (b, "period_px");
  if (params->geometry.period_px > 0)
    json_builder_add_double_value (b, params->geometry.period_px);
  else
    json_builder_add_null_value (b);
  json_builder_set_member_name (b, "edge_blur_px");
  if (params->geometry.edge_blur_known)
    json_builder_add_double_value (b, params->geometry.edge_blur_px);
  else
    json_builder_add_null_value (b);
  json_builder_end_object (b);

  json_builder_set_member_name (b, "separation");
  json_builder_add_value (b, ds_output_separation_json (&sep->meta));
  const char *planes[] = { "transmissive", "f32", "scattered", "f32", "mask", "u8", "max", "f32", "min", "f32",
                           "mean", "f32", "sigma_transmissive", "f32", "sigma_scattered", "f32", NULL };
  json_builder_set_member_name (b, "planes");
  json_builder_add_value (b, ds_output_planes_json (planes));
  json_builder_set_member_name (b, "mask_bits");
  json_builder_add_value (b, ds_output_mask_bits_json ());
  json_builder_end_object (b);
  return json_builder_get_root (b);
}

/* The separation's parameters: frames.json's where it has them, the options over them. */
static gboolean
make_params (const DsPhaseFolder *folder, const Options *o, DsSeparationParams *params, GError **error)
{
  const DsPhaseFolderSidecar *sc = &folder->sidecar;
  ds_separation_params_init (params, ds_phase_folder_n_phases (folder));
  if (o->detect_motion && o->no_detect_motion) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_INVALID_ARGUMENT,
                 "--detect-motion and --no-detect-motion: give one of them");
    return FALSE;
  }
  const char *estimator = o->estimator ? o->estimator : sc->estimator;
  if (estimator && !ds_estimator_from_name (estimator, &params->estimator)) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_INVALID_ARGUMENT, "%s %s: unknown (maxmin, sine or robust)",
                 o->estimator ? "--estimator" : "frames.json settings.estimator", estimator);
    return FALSE;
  }
  if (sc->has_pattern_kind)
    params->pattern = sc->pattern_kind;
  if (o->pattern) {
    if (g_ascii_strcasecmp (o->pattern, "square") == 0)
      params->pattern = DS_PATTERN_SQUARE;
    else if (g_ascii_strcasecmp (o->pattern, "sine") == 0)
      params->pattern = DS_PATTERN_SINE;
    else {
      g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_INVALID_ARGUMENT,
                   "--pattern %s: unknown (square or sine)", o->pattern);
      return FALSE;
    }
  }
  params->duty = !isnan (o->duty) ? o->duty : !isnan (sc->duty) ? sc->duty : params->duty;
  params->black_level = !isnan (o->black_level)    ? o->black_level
                        : !isnan (sc->black_level) ? sc->black_level
                                                   : params->black_level;
  params->saturation_level = !isnan (o->saturation) ? o->saturation : !isnan (sc->saturation_dn) ? sc->saturation_dn : 0;
  if (!isnan (o->harmonic_gain))
    params->harmonic_gain = o->harmonic_gain;
  else if (!isnan (sc->harmonic_gain))
    params->harmonic_gain = sc->harmonic_gain;
  if (!isnan (o->system_gain))
    params->system_gain = o->system_gain;
  if (!isnan (o->read_noise))
    params->read_noise_dn = o->read_noise;
  double blur = !isnan (o->edge_blur) ? o->edge_blur : sc->edge_blur_px;
  if (!isnan (blur)) {
    params->geometry.edge_blur_px = blur;
    params->geometry.edge_blur_known = TRUE;
  }
  params->keep_extrema = o->extrema;
  /* as the acquisition did (frames.json), so that a daemon's folder separates to its result */
  params->detect_motion = o->detect_motion || (!o->no_detect_motion && sc->has_detect_motion && sc->detect_motion);
  return TRUE;
}

/* The folder, its images' sizes checked against the limits before any decode. Per pixel, at
 * most: the accumulator's float path (min, max, raw max: 12; sums and phase sums in double:
 * 16; cosine and sine sums: 16; one float plane per phase; a non-finite flag), the outputs
 * (transmissive, scattered, extrema, sigmas in float: 28; mask and previews: 3), and the frame
 * and dark frame being read, each decoded and converted (16). */
static DsPhaseFolder *
open_folder (const char *dir, const Options *o, gboolean *usage, GError **error)
{
  DsFolderLimits limits;
  *usage = TRUE;
  if (!ds_folder_limits_from_options (&limits, o->max_side, o->max_pixels, o->max_memory_mib, error))
    return NULL;
  *usage = FALSE;
  g_autoptr (DsPhaseFolder) folder = ds_phase_folder_open (dir, ds_folder_read_sidecar, error);
  if (!folder ||
      !ds_folder_check_images (folder, &limits, 92.0 + 4.0 * ds_phase_folder_n_phases (folder), "a separation", error))
    return NULL;
  return g_steal_pointer (&folder);
}

/* *usage is set when the failure is a bad option value (exit status 2) rather than the data. */
static gboolean
separate (const char *dir, const Options *o, gboolean *usage, GError **error)
{
  g_autoptr (DsPhaseFolder) folder = open_folder (dir, o, usage, error);
  if (!folder)
    return FALSE;
  guint n = ds_phase_folder_n_phases (folder), nf = ds_phase_folder_n_frames (folder);
  *usage = TRUE;
  if (o->bit_depth && !ds_phase_folder_set_bit_depth (folder, (guint) o->bit_depth, error)) {
    g_prefix_error (error, "--bit-depth: ");
    return FALSE;
  }
  DsSeparationParams params;
  if (!make_params (folder, o, &params, error) || !ds_separation_params_validate (&params, error))
    return FALSE;
  *usage = FALSE;

  /* The stripes: the period (given, frames.json's or detected) and the phase every frame shows,
   * measured as the daemon verifies its frames. */
  g_auto (DsFolderPhases) phases = { 0 };
  if (!ds_folder_phases_find (folder, o->period, !o->no_phase_check, o->strict_phases, &phases, error))
    return FALSE;
  if (phases.notice)
    fprintf (stderr, "descatterctl separate: %s\n", phases.notice);
  if (!isnan (phases.period_px) && phases.period_px <= 1e6) {
    params.geometry.period_px = phases.period_px;
    if (!isnan (phases.offset_cycles)) {
      params.geometry.phase_offset_known = TRUE;
      params.geometry.phase_offset_cycles = phases.offset_cycles;
    }
  }
  DsSamplingCheck check;
  if (!ds_separation_check_sampling (&params, &check, error))
    return FALSE;
  if (check.warning[0])
    fprintf (stderr, "descatterctl separate: warning: %s\n", check.warning);

  /* Frames are read and folded one at a time, phase by phase (phase 0 first, as the daemon does,
   * unless another phase has more frames: averaging is decided by the first phase folded). */
  g_autofree guint *count = g_new0 (guint, n);
  for (guint i = 0; i < nf; i++)
    count[phases.fold_phase[i]]++;
  guint start = 0;
  for (guint k = 1; k < n; k++)
    if (count[k] > count[start])
      start = k;
  if (count[0] == count[start])
    start = 0;
  g_autoptr (DsPhaseSet) set = NULL;
  for (guint kk = 0; kk < n; kk++) {
    guint k = (start + kk) % n;
    for (guint i = 0; i < nf; i++) {
      if (phases.fold_phase[i] != k)
        continue;
      g_autoptr (DsImage) frame = ds_phase_folder_read (folder, i, error);
      if (!frame)
        return FALSE;
      if (!set) {
        set = ds_phase_set_new (&params, frame->width, frame->height, error);
        if (!set)
          return FALSE;
        if (folder->black_file) {
          g_autoptr (DsImage) black = ds_phase_folder_read_black (folder, error);
          if (!black || !ds_phase_set_set_dark (set, black, error))
            return FALSE;
        }
      }
      if (!ds_phase_set_accumulate (set, k, frame, error)) {
        g_prefix_error (error, "%s: ", ds_phase_folder_frame (folder, i)->file);
        return FALSE;
      }
    }
  }
  g_autoptr (DsSeparation) sep = ds_phase_set_finalize (set, error);
  if (!sep)
    return FALSE;

  const char *out = o->out ? o->out : dir;
  if (g_mkdir_with_parents (out, 0755) != 0) {
    int e = errno;
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_IO, "%s: cannot create folder: %s", out, g_strerror (e));
    return FALSE;
  }
  g_autoptr (GPtrArray) written = g_ptr_array_new_with_free_func (g_free);
  g_autoptr (JsonNode) root = build_sidecar (folder, &params, sep);
  g_autoptr (JsonBuilder) files = json_builder_new ();
  json_builder_begin_object (files);
  Outputs w = { .dir = out, .meta = root, .written = written, .files = files };
  if (!write_like_input (&w, sep->transmissive, folder, "direct", "transmissive", error) ||
      !write_like_input (&w, sep->scattered, folder, "global", "scattered", error) ||
      !write_image (&w, sep->transmissive, "transmissive.tiff", "transmissive", error) ||
      !write_image (&w, sep->scattered, "scattered.tiff", "scattered", error) ||
      !write_image (&w, sep->mask, "mask.png", "mask", error))
    return FALSE;
  if (!o->no_preview) {
    g_autoptr (DsImage) pt = ds_preview_u8 (sep->transmissive, 0.5, 99.5, error);
    if (!pt || !write_image (&w, pt, "transmissive-preview.png", "transmissive", error))
      return FALSE;
    g_autoptr (DsImage) ps = ds_preview_u8 (sep->scattered, 0.5, 99.5, error);
    if (!ps || !write_image (&w, ps, "scattered-preview.png", "scattered", error))
      return FALSE;
  }
  if (o->extrema && sep->max && sep->min && sep->mean &&
      (!write_image (&w, sep->max, "max.tiff", "max", error) ||
       !write_image (&w, sep->min, "min.tiff", "min", error) ||
       !write_image (&w, sep->mean, "mean.tiff", "mean", error)))
    return FALSE;
  if (sep->sigma_transmissive && sep->sigma_scattered &&
      (!write_image (&w, sep->sigma_transmissive, "sigma_transmissive.tiff", "sigma_transmissive", error) ||
       !write_image (&w, sep->sigma_scattered, "sigma_scattered.tiff", "sigma_scattered", error)))
    return FALSE;

  /* The list of files completes the sidecar. */
  JsonObject *ro = json_node_get_object (root);
  JsonArray *outputs = json_array_new ();
  for (guint i = 0; i < written->len; i++)
    json_array_add_string_element (outputs, written->pdata[i]);
  json_object_set_array_member (ro, "outputs", outputs);
  json_builder_end_object (files);
  json_object_set_member (ro, "files", json_builder_get_root (files));
  g_autoptr (JsonGenerator) gen = json_generator_new ();
  json_generator_set_pretty (gen, TRUE);
  json_generator_set_root (gen, root);
  g_autofree char *text = json_generator_to_data (gen, NULL);
  g_autofree char *jpath = g_build_filename (out, "separation.json", NULL);
  if (!g_file_set_contents_full (jpath, text, -1,
                                 G_FILE_SET_CONTENTS_CONSISTENT | G_FILE_SET_CONTENTS_DURABLE, 0644,
                                 error))
    return FALSE;

  if (!o->quiet) {
    printf ("separated %u phases (%s, a = %g, b = %g%s) of %ux%u %s: %s\n", n,
            ds_estimator_name (params.estimator), params.duty, params.black_level,
            folder->black_file ? ", black subtracted" : "", folder->width, folder->height,
            ds_sample_type_name (folder->type), out);
    if (phases.checked) {
      /* No stripes measured (the reason went to stderr): no offset to print, not "nan". */
      g_autofree char *offset = isfinite (phases.offset_cycles)
                                    ? g_strdup_printf ("phase 0 at %.3f cycles", phases.offset_cycles)
                                    : g_strdup ("phase 0 unknown");
      printf ("  stripe period %g px (%s), %s, phase order %s\n", phases.period_px, phases.period_source, offset,
              phases.verdict == DS_PHASE_ORDER_OK          ? "verified"
              : phases.verdict == DS_PHASE_ORDER_REORDERED ? "corrected"
                                                           : "not verified");
    }
    for (int i = 0; i < DS_MASK_N_BITS; i++)
      if (sep->meta.flagged[i])
        printf ("  flagged %-15s %" G_GUINT64_FORMAT " pixels\n", ds_mask_bit_name (i), sep->meta.flagged[i]);
  }
  return TRUE;
}

int
ds_ctl_separate (int argc, char **argv)
{
  Options o = { .duty = NAN, .black_level = NAN, .harmonic_gain = NAN, .system_gain = NAN,
                .read_noise = NAN, .saturation = NAN, .period = NAN, .edge_blur = NAN };
  GOptionEntry entries[] = {
    { "estimator", 0, 0, G_OPTION_ARG_STRING, &o.estimator, "maxmin (default), sine or robust", "NAME" },
    { "pattern", 0, 0, G_OPTION_ARG_STRING, &o.pattern, "stripe profile: square (default) or sine", "KIND" },
    { "duty", 0, 0, G_OPTION_ARG_DOUBLE, &o.duty, "lit fraction of a period (default 0.5)", "A" },
    { "black-level", 'b', 0, G_OPTION_ARG_DOUBLE, &o.black_level, "off-stripe leakage relative to on (default 0)", "B" },
    { "harmonic-gain", 0, 0, G_OPTION_ARG_DOUBLE, &o.harmonic_gain, "first-harmonic gain h for sine (default: theory)", "H" },
    { "system-gain", 0, 0, G_OPTION_ARG_DOUBLE, &o.system_gain, "sensor gain K in DN per electron (enables uncertainty)", "K" },
    { "read-noise", 0, 0, G_OPTION_ARG_DOUBLE, &o.read_noise, "temporal dark noise in DN", "DN" },
    { "saturation", 0, 0, G_OPTION_ARG_DOUBLE, &o.saturation, "lowest clipped level in DN: full well or ADC maximum (default: frames.json's saturation_dn, else 2^depth - 1)", "DN" },
    { "bit-depth", 0, 0, G_OPTION_ARG_INT, &o.bit_depth, "significant bits of the integer images, 1..16 (default: frames.json's, else the file's)", "BITS" },
    { "period", 0, 0, G_OPTION_ARG_DOUBLE, &o.period, "stripe period in pixels (default: frames.json's, else detected in the frames)", "PX" },
    { "edge-blur", 0, 0, G_OPTION_ARG_DOUBLE, &o.edge_blur, "Gaussian sigma of the stripe edges in pixels (descatterctl calibrate), for the sampling check and robust's windows (default unknown: sharp for the check, one phase of margin for robust)", "PX" },
    { "no-phase-check", 0, 0, G_OPTION_ARG_NONE, &o.no_phase_check, "do not measure which phase each frame shows", NULL },
    { "strict-phases", 0, 0, G_OPTION_ARG_NONE, &o.strict_phases, "refuse frames that show other phases than given instead of folding them as they show", NULL },
    { "detect-motion", 0, 0, G_OPTION_ARG_NONE, &o.detect_motion, "flag pixels whose phase samples show the scene moved (mask bit motion; default: frames.json's settings.detect_motion, else off)", NULL },
    { "no-detect-motion", 0, 0, G_OPTION_ARG_NONE, &o.no_detect_motion, "do not judge the motion bit", NULL },
    { "out", 'o', 0, G_OPTION_ARG_FILENAME, &o.out, "output folder (default: DIR)", "OUT" },
    { "extrema", 0, 0, G_OPTION_ARG_NONE, &o.extrema, "also write max, min and mean (float32 TIFF)", NULL },
    { "no-preview", 0, 0, G_OPTION_ARG_NONE, &o.no_preview, "do not write the 8-bit preview pictures", NULL },
    { "quiet", 'q', 0, G_OPTION_ARG_NONE, &o.quiet, "print nothing on success", NULL },
    DS_FOLDER_LIMIT_OPTIONS (&o.max_side, &o.max_pixels, &o.max_memory_mib),
    { NULL },
  };
  g_autoptr (GOptionContext) ctx = g_option_context_new ("DIR - separate a folder of phase images");
  g_option_context_set_summary (ctx, "Writes direct.png, global.png, transmissive.tiff, scattered.tiff, "
                                     "mask.png and separation.json.");
  g_option_context_add_main_entries (ctx, entries, NULL);
  ds_ctl_describe_globals (ctx);
  g_autoptr (GError) error = NULL;
  int status;
  gboolean usage = FALSE;
  if (!g_option_context_parse (ctx, &argc, &argv, &error)) {
    fprintf (stderr, "descatterctl separate: %s\n", error->message);
    status = 2;
  } else if (argc != 2) {
    fprintf (stderr, "descatterctl separate: expected one folder, got %d arguments\n", argc - 1);
    status = 2;
  } else if (!separate (argv[1], &o, &usage, &error)) {
    fprintf (stderr, "descatterctl separate: %s\n", error->message);
    status = usage ? 2 : 1;
  } else {
    status = 0;
  }
  g_free (o.estimator);
  g_free (o.pattern);
  g_free (o.out);
  return status;
}
