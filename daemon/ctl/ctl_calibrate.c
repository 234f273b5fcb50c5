/* `descatterctl calibrate [DIR]`: the stripe pattern as the camera sees it, measured on a
 * reference with little scattering (proc/calibration.h): offline on a phase folder DIR, or
 * without DIR by the daemon on the rig (its `calibrate` command takes one phase set and keeps
 * its raw frames). Printed as the configuration lines to use (descatterd.conf's [illuminator]
 * and `descatterctl separate`'s options), or as JSON. Offline, the frames' phase order is
 * checked first, as `separate` checks it. */
#include <json-glib/json-glib.h>
#include <math.h>
#include <stdio.h>

#include "daemon/ctl/ctl_commands.h"
#include "daemon/ctl/ctl_folder.h"
#include "daemon/ctl/ctl_interrupt.h"
#include "daemon/ctl/ctl_session.h"
#include "proc/calibration.h"
#include "proc/calibration_json.h"
#include "proc/proc_error.h"

typedef struct {
  char *pattern, *second;
  double period, saturation, aperture;
  int bit_depth;
  gboolean json, quiet, strict_phases;
  /* the rig's set (text: "not given" told apart from any value, ctl_session.h) */
  char *phases, *averages, *exposure, *gain;
  gboolean no_dark_frame;
  gint64 max_side, max_pixels, max_memory_mib;
} Options;

static void
print_json (const char *key, const char *source, gint64 set_id, const DsCalibration *cal)
{
  g_autoptr (JsonBuilder) b = json_builder_new ();
  json_builder_begin_object (b);
  json_builder_set_member_name (b, key);
  if (source)
    json_builder_add_string_value (b, source);
  else
    json_builder_add_int_value (b, set_id);
  ds_calibration_add_json_members (b, cal);
  json_builder_end_object (b);
  g_autoptr (JsonNode) root = json_builder_get_root (b);
  g_autofree char *text = json_to_string (root, TRUE);
  printf ("%s\n", text);
}

/* open_field_missing: why the open field is not measured, printed where it is absent. */
static void
print_lines (const char *source, const DsCalibration *cal, const char *open_field_missing)
{
  const char *kind = cal->pattern == DS_PATTERN_SINE ? "sine" : "square";
  printf ("calibration of %s: %u phases x %u frames, %" G_GUINT64_FORMAT " lit pixels\n", source, cal->n_phases,
          cal->frames_per_phase, cal->pixels_used);
  printf ("  stripe period   %.4f px (%s)\n", cal->period_px, cal->period_measured ? "measured" : "given");
  printf ("  phase 0 at      %.4f cycles (rms over the phases %.4f)\n", cal->phase_offset_cycles, cal->offset_spread);
  const DsPatternCheck *pc = &cal->pattern_check;
  if (pc->detected)
    printf ("  pattern         %s (rms residual over the stripe contrast: sinusoid %.2f %%, blurred square "
            "%.2f %% at %.2f px, noise %.2f %%)\n",
            kind, 100 * pc->sine_residual, 100 * pc->square_residual, pc->square_blur_px, 100 * pc->noise);
  else
    printf ("  pattern         %s (given)\n", kind);
  if (cal->pattern == DS_PATTERN_SQUARE)
    printf ("  duty            %.4f\n", cal->duty);
  if (cal->pattern == DS_PATTERN_SQUARE)
    printf ("  black level     %.4f\n", cal->black_level);
  else if (cal->black_level_measured)
    printf ("  black level     %.4f (from the contrast at two periods: %.4f at %.4g px, %.4f at %.4g px)\n",
            cal->black_level, cal->contrast, cal->period_px, cal->second_contrast, cal->second_period_px);
  else
    printf ("  black level     %.4f (assumed: one period cannot tell it from blur)\n", cal->black_level);
  printf ("  contrast        %.4f (first harmonic over the mean)\n", cal->contrast);
  printf ("  harmonic gain   %.4f (sharp stripes: %.4f)\n", cal->harmonic_gain, cal->harmonic_gain_theory);
  if (cal->pattern == DS_PATTERN_SQUARE || cal->black_level_measured)
    printf ("  edge blur       %.2f px (Gaussian sigma)\n", cal->edge_blur_px);
  if (cal->open_field_dn_per_ms > 0)
    printf ("  open field      %.6g DN per ms of exposure at 0 dB gain (a fully lit pixel above dark)\n",
            cal->open_field_dn_per_ms);
  else
    printf ("  open field      not measured: %s\n", open_field_missing);
  g_autofree char *lines = ds_calibration_config_lines (cal);
  g_autofree char *level_note = ds_calibration_black_level_note (cal);
  g_autofree char *notice = ds_calibration_pattern_notice (cal);
  g_autofree char *warning = ds_calibration_scatter_warning (cal);
  if (notice)
    printf ("\n# NOTE: %s\n", notice);
  if (level_note)
    printf ("\n# NOTE: %s\n", level_note);
  if (warning)
    printf ("\n# WARNING: %s\n", warning);
  printf ("\n# descatterd.conf\n%s", lines);
  if (cal->pattern == DS_PATTERN_SINE)
    printf ("\n# descatterctl separate\n--pattern sine --period %.4f --black-level %.4f --harmonic-gain %.4f\n",
            cal->period_px, cal->black_level, cal->harmonic_gain);
  else
    printf ("\n# descatterctl separate\n--pattern %s --period %.4f --duty %.4f --black-level %.4f "
            "--harmonic-gain %.4f --edge-blur %.2f\n",
            kind, cal->period_px, cal->duty, cal->black_level, cal->harmonic_gain, cal->edge_blur_px);
}

/* On stderr as well, so that it shows when stdout goes to a file (--quiet leaves it to the
 * output: the comment above the lines, or the JSON's "warning"). */
static void
warn (const DsCalibration *cal, gboolean quiet)
{
  g_autofree char *notice = ds_calibration_pattern_notice (cal);
  g_autofree char *warning = ds_calibration_scatter_warning (cal);
  if (notice && !quiet)
    fprintf (stderr, "descatterctl calibrate: warning: %s\n", notice);
  if (warning && !quiet)
    fprintf (stderr, "descatterctl calibrate: warning: %s\n", warning);
}

/* One folder's calibration; second: it is the second period of a sine's reference (the pattern
 * and the period are measured, nothing else is used). *usage is set when the failure is a bad
 * option value (exit status 2) rather than the data. */
static gboolean
measure_folder (const char *dir, const Options *o, gboolean second, DsCalibration *result, gboolean *usage,
                GError **error)
{
  DsFolderLimits limits;
  *usage = TRUE;
  if (!ds_folder_limits_from_options (&limits, o->max_side, o->max_pixels, o->max_memory_mib, error))
    return FALSE;
  *usage = FALSE;
  g_autoptr (DsPhaseFolder) folder = ds_phase_folder_open (dir, ds_folder_read_sidecar, error);
  if (!folder)
    return FALSE;
  /* Every size is checked before the first decode. Per pixel, at most: the calibrator's sums
   * (a double per phase), its dark frame, result and lit-level planes (16), the stripe-phase
   * measurement's working copy (8) and the frame being read, decoded and converted (16). */
  if (!ds_folder_check_images (folder, &limits, 40.0 + 8.0 * ds_phase_folder_n_phases (folder), "a calibration",
                               error))
    return FALSE;
  *usage = TRUE;
  DsCalibrationHints hints;
  ds_calibration_hints_init (&hints);
  if (folder->sidecar.has_pattern_kind)
    hints.pattern = folder->sidecar.pattern_kind;
  /* what a sine's black level is taken as when one period cannot tell it (calibration_sine.h) */
  if (!isnan (folder->sidecar.black_level))
    hints.black_level = folder->sidecar.black_level;
  if (second) {
    hints.pattern = DS_PATTERN_SINE;
    hints.pattern_forced = TRUE;
  } else if (o->pattern) {
    hints.pattern_forced = TRUE;
    if (g_ascii_strcasecmp (o->pattern, "square") == 0)
      hints.pattern = DS_PATTERN_SQUARE;
    else if (g_ascii_strcasecmp (o->pattern, "sine") == 0)
      hints.pattern = DS_PATTERN_SINE;
    else {
      g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_INVALID_ARGUMENT, "--pattern %s: unknown (square or sine)",
                   o->pattern);
      return FALSE;
    }
  }
  if (!isnan (o->period) && !(o->period > 2)) {
    g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_INVALID_ARGUMENT, "--period %g: must exceed 2 pixels", o->period);
    return FALSE;
  }
  if (o->bit_depth && !ds_phase_folder_set_bit_depth (folder, (guint) o->bit_depth, error)) {
    g_prefix_error (error, "--bit-depth: ");
    return FALSE;
  }
  hints.saturation_level = !isnan (o->saturation) ? o->saturation
                           : !isnan (folder->sidecar.saturation_dn) ? folder->sidecar.saturation_dn
                                                                    : 0;
  if (!isnan (o->aperture))
    hints.pixel_aperture = o->aperture;
  *usage = FALSE;

  g_auto (DsFolderPhases) phases = { 0 };
  if (!ds_folder_phases_find (folder, second ? NAN : o->period, TRUE, o->strict_phases, &phases, error))
    return FALSE;
  if (phases.notice && !o->quiet)
    fprintf (stderr, "descatterctl calibrate: %s\n", phases.notice);
  if (!isnan (phases.period_px))
    hints.period_px = phases.period_px;
  hints.period_estimated = phases.period_source && g_str_equal (phases.period_source, "detected");
  if (folder->sidecar.has_phase_offset) {
    hints.phase_offset_known = TRUE;
    hints.phase_offset_cycles = folder->sidecar.phase_offset_cycles;
  }
  g_autoptr (DsCalibrator) cal = NULL;
  for (guint i = 0; i < ds_phase_folder_n_frames (folder); i++) {
    g_autoptr (DsImage) frame = ds_phase_folder_read (folder, i, error);
    if (!frame)
      return FALSE;
    if (!cal && !(cal = ds_calibrator_new (ds_phase_folder_n_phases (folder), frame->width, frame->height, error)))
      return FALSE;
    if (!ds_calibrator_add (cal, phases.fold_phase[i], frame, error)) {
      g_prefix_error (error, "%s: ", ds_phase_folder_frame (folder, i)->file);
      return FALSE;
    }
  }
  if (folder->black_file) {
    g_autoptr (DsImage) black = ds_phase_folder_read_black (folder, error);
    if (!black || !ds_calibrator_set_dark (cal, black, error))
      return FALSE;
  }
  if (!ds_calibrator_finish (cal, &hints, result, error)) {
    g_prefix_error (error, "%s: ", dir);
    return FALSE;
  }
  /* the period came from ds_folder_phases_find: measured there unless given */
  result->period_measured = phases.period_source && g_str_equal (phases.period_source, "detected");
  return TRUE;
}

static gboolean
calibrate (const char *dir, const Options *o, gboolean *usage, GError **error)
{
  DsCalibration result, second;
  if (!measure_folder (dir, o, FALSE, &result, usage, error))
    return FALSE;
  if (o->second) {
    if (result.pattern != DS_PATTERN_SINE) {
      *usage = TRUE;
      g_set_error (error, DS_PROC_ERROR, DS_PROC_ERROR_INVALID_ARGUMENT,
                   "--second %s: the stripes are square; their black level is measured from one period", o->second);
      return FALSE;
    }
    if (!measure_folder (o->second, o, TRUE, &second, usage, error) ||
        !ds_calibration_add_second_period (&result, &second, isnan (o->aperture) ? 1.0 : o->aperture, error))
      return FALSE;
  }
  if (o->json)
    print_json ("folder", dir, 0, &result);
  else
    print_lines (dir, &result, "a folder's frames do not say how they were lit (calibrate on the rig)");
  warn (&result, o->quiet);
  return TRUE;
}

/* One phase set on the rig, measured by the daemon. */
static int
calibrate_on_rig (const DsCtlTarget *target, const Options *o)
{
  if (!isnan (o->saturation) || o->bit_depth || o->strict_phases || o->second) {
    fprintf (stderr, "descatterctl calibrate: --saturation, --bit-depth, --strict-phases and --second are for a "
                     "folder; "
                     "the daemon knows its camera\n");
    return 2;
  }
  g_autoptr (JsonObject) args = json_object_new ();
  if (!ds_ctl_args_int (args, "calibrate", "phases", "phases", o->phases) ||
      !ds_ctl_args_int (args, "calibrate", "averages", "averages", o->averages) ||
      !ds_ctl_args_double (args, "calibrate", "exposure-us", "exposure_us", o->exposure) ||
      !ds_ctl_args_double (args, "calibrate", "gain-db", "gain_db", o->gain))
    return 2;
  if (!isnan (o->period))
    json_object_set_double_member (args, "period_px", o->period);
  if (!isnan (o->aperture))
    json_object_set_double_member (args, "pixel_aperture", o->aperture);
  if (o->no_dark_frame)
    json_object_set_boolean_member (args, "dark_frame", FALSE);
  g_autoptr (DsClient) c = ds_ctl_connect (target, "calibrate");
  if (!c)
    return 1;
  /* Ctrl-C cancels the calibrate in the daemon as well (ctl_interrupt.h). */
  ds_ctl_interrupt_begin (target, "calibrate");
  g_autoptr (DsMessage) m = ds_ctl_call (c, "calibrate", args, NULL, NULL);
  if (ds_ctl_interrupt_end ())
    return DS_CTL_EXIT_INTERRUPTED;
  if (!m)
    return 1;
  DsCalibration cal;
  g_autoptr (GError) error = NULL;
  JsonObject *body = m->reply->body && JSON_NODE_HOLDS_OBJECT (m->reply->body) ? json_node_get_object (m->reply->body)
                                                                              : NULL;
  if (!body || !ds_calibration_from_json (body, &cal, &error)) {
    fprintf (stderr, "descatterctl calibrate: the daemon's reply: %s\n", error ? error->message : "not an object");
    return 1;
  }
  gint64 set_id = json_object_get_int_member_with_default (body, "set_id", 0);
  const char *second_error = json_object_get_string_member_with_default (body, "second_period_error", NULL);
  if (second_error && !o->quiet)
    fprintf (stderr, "descatterctl calibrate: the set at twice the period: %s\n", second_error);
  if (o->json) {
    print_json ("set_id", NULL, set_id, &cal);
  } else {
    g_autofree char *source = g_strdup_printf ("set %" G_GINT64_FORMAT " on the rig (%s)", set_id, target->address);
    print_lines (source, &cal, o->no_dark_frame ? "no dark frame (--no-dark-frame)" : "the set had no dark frame");
  }
  warn (&cal, o->quiet);
  return 0;
}

int
ds_ctl_calibrate (const DsCtlTarget *target, int argc, char **argv)
{
  Options o = { .period = NAN, .saturation = NAN, .aperture = NAN };
  GOptionEntry entries[] = {
    { "pattern", 0, 0, G_OPTION_ARG_STRING, &o.pattern, "take the stripes as square or sine without telling them apart (default: told from the profile)", "KIND" },
    { "second", 0, 0, G_OPTION_ARG_FILENAME, &o.second, "sine stripes: the same reference at another period (1.25x or more apart, e.g. twice), to tell the black level from blur", "DIR2" },
    { "period", 0, 0, G_OPTION_ARG_DOUBLE, &o.period, "the stripe period in pixels when known (default: measured)", "PX" },
    { "saturation", 0, 0, G_OPTION_ARG_DOUBLE, &o.saturation, "lowest clipped level in DN; clipped pixels are left out", "DN" },
    { "bit-depth", 0, 0, G_OPTION_ARG_INT, &o.bit_depth, "significant bits of the integer images, 1..16", "BITS" },
    { "pixel-aperture", 0, 0, G_OPTION_ARG_DOUBLE, &o.aperture, "sensitive width of a pixel in pixels, for the blur model (default 1)", "PX" },
    { "strict-phases", 0, 0, G_OPTION_ARG_NONE, &o.strict_phases, "refuse frames that show other phases than given", NULL },
    { "phases", 'n', 0, G_OPTION_ARG_STRING, &o.phases, "without DIR: phases of the rig's set (3..64; default: the daemon's)", "N" },
    { "averages", 'm', 0, G_OPTION_ARG_STRING, &o.averages, "without DIR: frames averaged per phase (1..64)", "M" },
    { "exposure-us", 'e', 0, G_OPTION_ARG_STRING, &o.exposure, "without DIR: exposure (µs, 1..1e7)", "E" },
    { "gain-db", 'g', 0, G_OPTION_ARG_STRING, &o.gain, "without DIR: gain (dB, 0..48)", "G" },
    { "no-dark-frame", 0, 0, G_OPTION_ARG_NONE, &o.no_dark_frame, "without DIR: no dark frame subtracted", NULL },
    { "json", 'j', 0, G_OPTION_ARG_NONE, &o.json, "print the measurements as JSON", NULL },
    { "quiet", 'q', 0, G_OPTION_ARG_NONE, &o.quiet, "no notices on stderr", NULL },
    DS_FOLDER_LIMIT_OPTIONS (&o.max_side, &o.max_pixels, &o.max_memory_mib),
    { NULL },
  };
  g_autoptr (GOptionContext) ctx = g_option_context_new ("[DIR] - measure the stripe pattern on a reference with little scattering");
  g_option_context_set_summary (ctx, "DIR holds a phase set of a reference with little scattering (descatter-sim "
                                     "render, capture --save-phases, or the ICCP 2013 layout); without DIR the daemon "
                                     "takes one phase set of the reference in front of the rig. Prints the stripe "
                                     "period, phase offset, duty, black level, harmonic gain and edge blur, and the "
                                     "configuration lines that use them.");
  g_option_context_add_main_entries (ctx, entries, NULL);
  ds_ctl_describe_globals (ctx);
  g_autoptr (GError) error = NULL;
  int status;
  gboolean usage = FALSE;
  if (!g_option_context_parse (ctx, &argc, &argv, &error)) {
    fprintf (stderr, "descatterctl calibrate: %s\n", error->message);
    status = 2;
  } else if (argc > 2) {
    fprintf (stderr, "descatterctl calibrate: expected one folder or none (the rig), got %d arguments\n", argc - 1);
    status = 2;
  } else if (argc == 1) {
    status = calibrate_on_rig (target, &o);
  } else if (o.phases || o.averages || o.exposure || o.gain || o.no_dark_frame) {
    fprintf (stderr, "descatterctl calibrate: --phases, --averages, --exposure-us, --gain-db and --no-dark-frame "
                     "are for the rig (no DIR)\n");
    status = 2;
  } else if (!calibrate (argv[1], &o, &usage, &error)) {
    fprintf (stderr, "descatterctl calibrate: %s\n", error->message);
    status = usage ? 2 : 1;
  } else {
    status = 0;
  }
  g_free (o.pattern);
  g_free (o.second);
  g_free (o.phases);
  g_free (o.averages);
  g_free (o.exposure);
  g_free (o.gain);
  return status;
}
