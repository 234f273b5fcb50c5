/* descatterd's configuration parser: defaults, errors that point at the mistake, round trip,
 * and the shipped example (etc/descatterd.conf) documenting every key. */
#include "daemon/acquire/capture_settings.h"
#include "daemon/config/config.h"
#include "proc/calibration_json.h"
#include "tests/common/config_groups.h"

#include <math.h>
#include <glib/gstdio.h>
#include <string.h>

static const char *example_path;

#define SIM "[camera]\nbackend=sim\n[illuminator]\nbackend=sim\n"

/* A configuration composed of SIM and a case's groups, with a group given twice merged into one
 * (ds_config_load_data refuses the repetition itself: /config/groups-given-twice). */
static DsConfig *
load_data (const char *text, const char *name, GError **error)
{
  g_autofree char *grouped = test_config_groups_merge (text);
  return ds_config_load_data (grouped, name, error);
}

static void
test_defaults_are_the_simulated_lab (void)
{
  /* The devices are never chosen by default: only --sim picks the simulated lab. */
  g_autoptr (DsConfig) d = ds_config_new_default ();
  g_assert_null (d->camera_backend);
  g_assert_null (d->illuminator_backend);
  g_autoptr (DsConfig) c = ds_config_new_sim ();
  g_assert_cmpstr (c->camera_backend, ==, "sim");
  g_assert_cmpstr (c->illuminator_backend, ==, "sim");
  g_assert_cmpuint (c->phases, ==, 8);
  g_assert_cmpfloat (c->duty, ==, 0.5);
  g_assert_cmpuint (c->socket_mode, ==, 0660);
  g_assert_null (c->tcp_listen);
  g_assert_true (isnan (c->phase_tolerance_deg));
}

static void
test_values_override_defaults (void)
{
  g_autoptr (GError) error = NULL;
  g_autoptr (DsConfig) c = load_data ("[acquisition]\nphases = 12\nestimator=sine\n"
                                                "[camera]\nbackend=aravis\naddress=10.0.0.2\n"
                                                "[illuminator]\nbackend=modbus\nmodbus-uri=tcp://127.0.0.1:1502\n"
                                                "duty=0.25\n[daemon]\nsocket-mode=0600\n",
                                                "t.conf", &error);
  g_assert_no_error (error);
  g_assert_cmpuint (c->phases, ==, 12);
  g_assert_cmpstr (c->estimator, ==, "sine");
  g_assert_cmpstr (c->modbus_uri, ==, "tcp://127.0.0.1:1502");
  g_assert_cmpfloat (c->duty, ==, 0.25);
  g_assert_cmpuint (c->socket_mode, ==, 0600);
  g_assert_cmpuint (c->averages, ==, 1); /* untouched default */
}

static void
expect_error (const char *text, int code, const char *const *must_contain)
{
  g_autoptr (GError) error = NULL;
  g_autoptr (DsConfig) c = load_data (text, "bad.conf", &error);
  g_assert_null (c);
  g_assert_error (error, DS_CONFIG_ERROR, code);
  g_assert_nonnull (strstr (error->message, "bad.conf"));
  for (guint i = 0; must_contain[i]; i++)
    if (!strstr (error->message, must_contain[i]))
      g_error ("error \"%s\" does not mention \"%s\"", error->message, must_contain[i]);
}

static void
test_errors_name_the_place (void)
{
  expect_error ("[camera]\nbackend=sim\n[cmaera]\nx=1\n", DS_CONFIG_ERROR_UNKNOWN_GROUP,
                (const char *const[]) { "[cmaera]", "line 3", NULL });
  expect_error ("# c\n[acquisition]\n\nphase = 8\n", DS_CONFIG_ERROR_UNKNOWN_KEY,
                (const char *const[]) { "[acquisition]", "\"phase\"", "line 4", NULL });
  expect_error ("[acquisition]\nphases=1\n", DS_CONFIG_ERROR_BAD_VALUE,
                (const char *const[]) { "phases", "2..64", "line 2", NULL });
  expect_error ("[acquisition]\nphases=eight\n", DS_CONFIG_ERROR_BAD_VALUE,
                (const char *const[]) { "phases", "integer", NULL });
  expect_error ("[illuminator]\nduty=1.5\n", DS_CONFIG_ERROR_BAD_VALUE,
                (const char *const[]) { "duty", "0.01..0.99", NULL });
  expect_error ("[illuminator]\nduty=nan\n", DS_CONFIG_ERROR_BAD_VALUE, (const char *const[]) { "duty", NULL });
  expect_error ("[acquisition]\nestimator=median\n", DS_CONFIG_ERROR_BAD_VALUE,
                (const char *const[]) { "estimator", "maxmin|sine|robust", NULL });
  expect_error ("[acquisition]\ndark-frame=yes\n", DS_CONFIG_ERROR_BAD_VALUE,
                (const char *const[]) { "dark-frame", "true or false", NULL });
  expect_error ("[daemon]\nsocket-mode=0999\n", DS_CONFIG_ERROR_BAD_VALUE,
                (const char *const[]) { "socket-mode", "octal", NULL });
  expect_error ("[camera]\nbackend=aravis\n[illuminator]\nbackend=modbus\nmodbus-uri=tcp://a:1\n",
                DS_CONFIG_ERROR_INCONSISTENT, (const char *const[]) { "address", NULL });
  expect_error (SIM "[acquisition]\nestimator=sine\nphases=2\n", DS_CONFIG_ERROR_INCONSISTENT,
                (const char *const[]) { "sine", "phases >= 3", NULL });
  expect_error (SIM "[acquisition]\nresults=per-frame\naverages=2\n", DS_CONFIG_ERROR_INCONSISTENT,
                (const char *const[]) { "results = per-frame", "averages = 1", NULL });
  expect_error (SIM "[daemon]\ntcp-listen=127.0.0.1\n", DS_CONFIG_ERROR_INCONSISTENT,
                (const char *const[]) { "tcp-listen", "IP:PORT", NULL });
  expect_error ("[daemon\nsocket=x\n", DS_CONFIG_ERROR_SYNTAX, (const char *const[]) { NULL });
}

static void
test_round_trip (void)
{
  g_autoptr (GError) error = NULL;
  g_autoptr (DsConfig) a = load_data ("[camera]\nbackend=sim\nexposure-us=1234.5\nroi=0,0,64,32\n"
                                                "[illuminator]\nbackend=sim\n[sim]\nseed=99\n"
                                                "[acquisition]\nphase-tolerance-deg=10\n",
                                                "a.conf", &error);
  g_assert_no_error (error);
  g_autofree char *text = ds_config_to_data (a);
  g_autoptr (DsConfig) b = load_data (text, "printed", &error);
  g_assert_no_error (error);
  g_autofree char *text2 = ds_config_to_data (b);
  g_assert_cmpstr (text, ==, text2);
  g_assert_cmpfloat (b->exposure_us, ==, 1234.5);
  g_assert_cmpstr (b->roi, ==, "0,0,64,32");
  g_assert_cmpuint (b->sim_seed, ==, 99);
  g_assert_cmpfloat (b->phase_tolerance_deg, ==, 10.0);
  g_autoptr (DsConfig) copy = ds_config_copy (b);
  g_autofree char *text3 = ds_config_to_data (copy);
  g_assert_cmpstr (text, ==, text3);
}

/* SIGHUP's rule comes from the key table: a key the daemon uses only at start (a device's, the
 * operating model and the timing of automatic captures) is named when it changes; a key of the
 * capture defaults is not, and an unset double equals another. */
static void
test_reload_rule (void)
{
  g_autoptr (GError) error = NULL;
  g_autoptr (DsConfig) running = load_data (SIM, "running.conf", &error);
  g_assert_no_error (error);
  g_autoptr (DsConfig) live = load_data (SIM "[acquisition]\nphases=10\nestimator=sine\n"
                                                   "phase-tolerance-deg=20\n[camera]\nexposure-us=700\n",
                                                   "live.conf", &error);
  g_assert_no_error (error);
  g_assert_null (ds_config_restart_keys_changed (running, live));
  g_autoptr (DsConfig) same = ds_config_copy (running);
  g_assert_true (isnan (same->saturation_dn));
  g_assert_null (ds_config_restart_keys_changed (running, same));
  static const char *const restart[][2] = {
    { "[acquisition]\noperating-model=/etc/descatterd/other-model.conf\n", "[acquisition] operating-model" },
    { "[acquisition]\nsettle-ms=7\n", "[acquisition] settle-ms" },
    { "[acquisition]\nlink-mbit=100\n", "[acquisition] link-mbit" },
    { "[camera]\npixel-format=Mono8\n", "[camera] pixel-format" },
    { "[illuminator]\nperiod-px=24\n", "[illuminator] period-px" },
    { "[daemon]\nspool-dir=/var/lib/descatterd\n", "[daemon] spool-dir" },
  };
  for (guint i = 0; i < G_N_ELEMENTS (restart); i++) {
    g_autofree char *text = g_strconcat (SIM, restart[i][0], "[acquisition]\nphases=6\n", NULL);
    g_autoptr (DsConfig) fresh = load_data (text, "fresh.conf", &error);
    g_assert_no_error (error);
    g_autofree char *changed = ds_config_restart_keys_changed (running, fresh);
    g_assert_cmpstr (changed, ==, restart[i][1]);
  }
  g_autoptr (DsConfig) two = load_data (SIM "[camera]\ngain-db=3\nroi=0,0,8,8\n"
                                                  "[acquisition]\nsettle-ms=7\nlink-mbit=100\n",
                                                  "two.conf", &error);
  g_assert_no_error (error);
  g_autofree char *changed = ds_config_restart_keys_changed (running, two);
  g_assert_cmpstr (changed, ==, "[camera] roi; [acquisition] settle-ms, link-mbit");
  g_autofree char *live_keys = ds_config_live_keys ();
  g_assert_cmpstr (live_keys, ==, "[camera] exposure-us, gain-db, gain-dn-per-e, read-noise-dn; [acquisition] "
                                  "phases, averages, estimator, dark-frame, phase-retries, max-failed-sets, results, "
                                  "verify-phase, detect-motion, speed-px-s, phase-tolerance-deg, single-frame");
}

static void
test_example_documents_every_key (void)
{
  g_autofree char *data = NULL;
  g_assert_true (g_file_get_contents (example_path, &data, NULL, NULL));
  g_autoptr (GError) error = NULL;
  /* As shipped it names no device (a lab must choose): refused, saying so. */
  g_assert_null (load_data (data, example_path, &error));
  g_assert_nonnull (strstr (error->message, "backend is not set"));
  g_clear_error (&error);
  g_autofree char *chosen = g_strconcat (data, "\n" SIM, NULL);
  g_autoptr (DsConfig) c = load_data (chosen, example_path, &error);
  g_assert_no_error (error);
  /* Every key of the table appears in the example, set or commented out. */
  g_autofree char *defaults = ds_config_to_data (c);
  g_auto (GStrv) lines = g_strsplit (defaults, "\n", -1);
  for (guint i = 0; lines[i]; i++) {
    char *eq = strchr (lines[i], '=');
    if (!eq || lines[i][0] == '[')
      continue;
    *eq = '\0';
    g_autofree char *set = g_strdup_printf ("\n%s=", lines[i]);
    g_autofree char *commented = g_strdup_printf ("\n#%s=", lines[i]);
    if (!strstr (data, set) && !strstr (data, commented))
      g_error ("%s does not document key \"%s\"", example_path, lines[i]);
  }
}

/* Issue 10: what --check passed and the daemon then refused or, worse, ran with. Each is
 * refused at load, naming the key and what is allowed. */
static void
test_refusals (void)
{
  const struct { const char *text; int code; const char *must[3]; } cases[] = {
    /* no device chosen: never simulated by omission */
    { "[acquisition]\nphases=8\n", DS_CONFIG_ERROR_INCONSISTENT, { "[camera] backend is not set", "--sim" } },
    { "[camera]\nbackend=sim\n", DS_CONFIG_ERROR_INCONSISTENT, { "[illuminator] backend is not set" } },
    /* contradictions, with both keys named */
    { "[camera]\nbackend=aravis\naddress=10.0.0.2\n[illuminator]\nbackend=sim\n", DS_CONFIG_ERROR_INCONSISTENT,
      { "[camera] backend = aravis", "[illuminator] backend = sim" } },
    { "[camera]\nbackend=sim\n[illuminator]\nbackend=modbus\nmodbus-uri=tcp://a:1\n", DS_CONFIG_ERROR_INCONSISTENT,
      { "[camera] backend = sim", "[illuminator] backend = modbus" } },
    { "[camera]\nbackend=aravis\naddress=10.0.0.2\ntrigger=line0\n[illuminator]\nbackend=modbus\nmodbus-uri=tcp://a:1\n",
      DS_CONFIG_ERROR_INCONSISTENT, { "[camera] trigger = line0", "[trigger] backend = software" } },
    { SIM "[camera]\ntrigger=line1\n[trigger]\nbackend=gpio\ngpio-line=4\n[illuminator]\ngpio-chip=gpiochip0\n",
      DS_CONFIG_ERROR_INCONSISTENT, { "[trigger] backend = gpio", "simulated camera" } },
    { "[camera]\nbackend=aravis\naddress=10.0.0.2\ntrigger=line0\n[trigger]\nbackend=gpio\ngpio-line=0\n"
      "[illuminator]\nbackend=modbus\nmodbus-uri=tcp://a:1\ngpio-chip=labsim:run/gpio.sock\n",
      DS_CONFIG_ERROR_INCONSISTENT, { "gpio-chip = \"labsim:run/gpio.sock\"", "absolute path" } },
    { "[camera]\nbackend=aravis\naddress=10.0.0.2\n[illuminator]\nbackend=modbus\nmodbus-uri=tcp://a:1\n"
      "[sim]\nfaults=stale=0.1\n", DS_CONFIG_ERROR_INCONSISTENT, { "[sim] faults", "no device is simulated" } },
    /* roi */
    { "[camera]\nbackend=sim\nroi=1,2,3\n[illuminator]\nbackend=sim\n", DS_CONFIG_ERROR_BAD_VALUE,
      { "roi = \"1,2,3\"", "x,y,width,height" } },
    { "[camera]\nbackend=sim\nroi=0,0,0,0\n[illuminator]\nbackend=sim\n", DS_CONFIG_ERROR_BAD_VALUE,
      { "roi = \"0,0,0,0\"", "above 0" } },
    { "[camera]\nbackend=sim\nroi=1,2,3,4,5\n[illuminator]\nbackend=sim\n", DS_CONFIG_ERROR_BAD_VALUE, { "roi" } },
    { "[camera]\nbackend=sim\nroi=-1,0,10,10\n[illuminator]\nbackend=sim\n", DS_CONFIG_ERROR_BAD_VALUE, { "roi" } },
    { "[camera]\nbackend=sim\nroi=a,b,c,d\n[illuminator]\nbackend=sim\n", DS_CONFIG_ERROR_BAD_VALUE, { "roi" } },
    /* paths */
    { SIM "[daemon]\nsocket=run/descatterd.sock\n", DS_CONFIG_ERROR_INCONSISTENT, { "[daemon] socket", "absolute" } },
    { SIM "[daemon]\nspool-dir=spool\n", DS_CONFIG_ERROR_INCONSISTENT, { "[daemon] spool-dir", "absolute" } },
    { SIM "[daemon]\ntcp-token-file=token\n", DS_CONFIG_ERROR_INCONSISTENT, { "tcp-token-file", "absolute" } },
    { SIM "[sim]\nscene=milk.scene\n", DS_CONFIG_ERROR_INCONSISTENT, { "[sim] scene", "absolute" } },
    { SIM "[acquisition]\noperating-model=model.csv\n", DS_CONFIG_ERROR_INCONSISTENT, { "operating-model", "absolute" } },
    { SIM "[daemon]\nsocket=/run/descatterd/a-socket-path-that-is-far-too-long-for-the-sun-path-field-"
          "of-sockaddr-un-which-holds-108-bytes.sock\n", DS_CONFIG_ERROR_INCONSISTENT, { "[daemon] socket", "at most 107" } },
    /* TCP */
    { SIM "[daemon]\ntcp-listen=localhost:7420\n", DS_CONFIG_ERROR_INCONSISTENT, { "tcp-listen", "numeric" } },
    { SIM "[daemon]\ntcp-listen=127.0.0.1:99999\n", DS_CONFIG_ERROR_INCONSISTENT, { "tcp-listen" } },
    { SIM "[daemon]\nmax-clients=8\nmax-tcp-clients=8\n", DS_CONFIG_ERROR_INCONSISTENT, { "max-tcp-clients", "below" } },
    /* what GKeyFile passed over: a key given twice kept its last value */
    { SIM "[acquisition]\nphases=8\nphases=4\n", DS_CONFIG_ERROR_SYNTAX, { "[acquisition] phases", "lines 6 and 7" } },
    { SIM "[acquisition]\nphases=8\n[acquisition]\nphases = 4\n", DS_CONFIG_ERROR_SYNTAX, { "set twice" } },
    /* a locale key was kept beside the key and never read; a key without a name stored as "" */
    { SIM "[camera]\nbackend[fr]=aravis\n", DS_CONFIG_ERROR_SYNTAX, { "line 3", "backend[fr]", "localized" } },
    { SIM "[acquisition]\n =8\n", DS_CONFIG_ERROR_SYNTAX, { "line 6", "without a key name" } },
    { SIM "[acquisition]\nphases=\xff\n", DS_CONFIG_ERROR_SYNTAX, { "line 6", "UTF-8" } },
  };
  for (guint i = 0; i < G_N_ELEMENTS (cases); i++) {
    g_autoptr (GError) error = NULL;
    g_autoptr (DsConfig) c = load_data (cases[i].text, "lab.conf", &error);
    if (c)
      g_error ("case %u accepted:\n%s", i, cases[i].text);
    if (!g_error_matches (error, DS_CONFIG_ERROR, cases[i].code))
      g_error ("case %u: code %d instead of %d: %s", i, error->code, cases[i].code, error->message);
    g_assert_nonnull (strstr (error->message, "lab.conf"));
    for (guint k = 0; k < G_N_ELEMENTS (cases[i].must) && cases[i].must[k]; k++)
      if (!strstr (error->message, cases[i].must[k]))
        g_error ("case %u: \"%s\" does not mention \"%s\"", i, error->message, cases[i].must[k]);
  }
}

/* A NUL byte ended GKeyFile's text: the keys after it, even invalid ones, were ignored; and
 * --check read /dev/zero without end. */
static void
test_file_limits (void)
{
  g_autoptr (GError) error = NULL;
  g_autofree char *dir = g_dir_make_tmp ("ds-config-XXXXXX", &error);
  g_assert_no_error (error);
  g_autofree char *path = g_build_filename (dir, "nul.conf", NULL);
  const char text[] = SIM "\0[acquisition]\nphases=1\n";
  g_assert_true (g_file_set_contents (path, text, sizeof text - 1, NULL));
  g_assert_null (ds_config_load_file (path, &error));
  g_assert_error (error, DS_CONFIG_ERROR, DS_CONFIG_ERROR_SYNTAX);
  g_assert_nonnull (strstr (error->message, "line 5: NUL"));
  g_clear_error (&error);
  /* Over the size limit (a regular file and a device that never ends). */
  g_autofree char *big = g_strnfill (DS_CONFIG_MAX_BYTES + 1, '#');
  g_assert_true (g_file_set_contents (path, big, -1, NULL));
  g_assert_null (ds_config_load_file (path, &error));
  g_assert_error (error, DS_CONFIG_ERROR, DS_CONFIG_ERROR_IO);
  g_clear_error (&error);
  g_assert_null (ds_config_load_file ("/dev/zero", &error));
  g_assert_error (error, DS_CONFIG_ERROR, DS_CONFIG_ERROR_IO);
  g_assert_nonnull (strstr (error->message, "not a configuration file"));
  g_clear_error (&error);
  g_unlink (path);
  g_rmdir (dir);
}

/* The lines `descatterctl calibrate` prints for descatterd.conf (proc/calibration_json.c) load
 * as they are, and what they say reaches the separation (h for sine) and the automatic operating
 * point's probe; [camera] saturation-dn reaches the separation's clip level. */
static void
test_calibration_lines_and_clip_level (void)
{
  DsCalibration cal = { .pattern = DS_PATTERN_SQUARE, .period_px = 9.5, .duty = 0.3, .black_level = 0.1,
                        .harmonic_gain = 0.4123, .edge_blur_px = 1.07 };
  g_autofree char *lines = ds_calibration_config_lines (&cal);
  g_autofree char *text = g_strconcat (lines, "backend=sim\n[camera]\nbackend=sim\npixel-format=Mono12\n"
                                       "saturation-dn=2118\n", NULL);
  g_autoptr (GError) error = NULL;
  g_autoptr (DsConfig) c = load_data (text, "calibrated.conf", &error);
  g_assert_no_error (error);
  g_assert_cmpfloat (c->harmonic_gain, ==, 0.4123);
  g_assert_cmpfloat (c->edge_blur_px, ==, 1.07);
  g_assert_cmpfloat (c->period_px, ==, 9.5);
  g_assert_cmpfloat (c->saturation_dn, ==, 2118);
  DsCaptureSettings s;
  ds_capture_settings_from_config (&s, c);
  g_assert_true (s.edge_blur_known);
  g_assert_cmpfloat (s.edge_blur_px, ==, 1.07);
  DsSeparationParams p;
  ds_capture_settings_separation_params (&s, &p);
  g_assert_cmpfloat (p.harmonic_gain, ==, 0.4123);
  g_assert_cmpfloat (p.saturation_level, ==, 2118);
  g_assert_true (p.geometry.edge_blur_known);
  g_assert_cmpfloat (p.geometry.edge_blur_px, ==, 1.07);
  /* Unset: the separation's own defaults (theory's h, the frames' top), blur not known. */
  g_autoptr (DsConfig) d = load_data (SIM, "plain.conf", &error);
  g_assert_no_error (error);
  g_assert_true (isnan (d->harmonic_gain) && isnan (d->edge_blur_px) && isnan (d->saturation_dn));
  ds_capture_settings_from_config (&s, d);
  g_assert_false (s.edge_blur_known);
  ds_capture_settings_separation_params (&s, &p);
  g_assert_cmpfloat (p.harmonic_gain, ==, 0);
  g_assert_cmpfloat (p.saturation_level, ==, 0);
  g_assert_false (p.geometry.edge_blur_known);
  /* Refusals name the key and what is wrong. */
  expect_error ("[illuminator]\nharmonic-gain=0\n", DS_CONFIG_ERROR_BAD_VALUE,
                (const char *const[]) { "harmonic-gain", "0.001..1", NULL });
  expect_error ("[illuminator]\nharmonic-gain=1.2\n", DS_CONFIG_ERROR_BAD_VALUE,
                (const char *const[]) { "harmonic-gain", NULL });
  expect_error ("[illuminator]\nedge-blur-px=-0.5\n", DS_CONFIG_ERROR_BAD_VALUE,
                (const char *const[]) { "edge-blur-px", "0..2048", NULL });
  expect_error (SIM "[illuminator]\nperiod-px=8\nedge-blur-px=4\n", DS_CONFIG_ERROR_INCONSISTENT,
                (const char *const[]) { "edge-blur-px", "half the period", NULL });
  expect_error ("[camera]\nsaturation-dn=0\n", DS_CONFIG_ERROR_BAD_VALUE,
                (const char *const[]) { "saturation-dn", "1..65535", NULL });
  expect_error (SIM "[camera]\npixel-format=Mono12p\nsaturation-dn=5000\n", DS_CONFIG_ERROR_INCONSISTENT,
                (const char *const[]) { "saturation-dn", "Mono12p", "4095", NULL });
  /* At the format's top exactly: accepted (a full well that reaches it). */
  g_autoptr (DsConfig) top = load_data (SIM "[camera]\npixel-format=Mono8\nsaturation-dn=255\n", "top.conf",
                                                  &error);
  g_assert_no_error (error);
  g_assert_cmpfloat (top->saturation_dn, ==, 255);
}

/* The open field's lit level travels as the other calibration lines do: printed by calibrate where
 * measured (and in its JSON, read back), loaded by the parser into the capture settings; absent, 0
 * (not measured); a value that is no positive number is refused naming the key, range and line. */
static void
test_open_field_line (void)
{
  DsCalibration cal = { .pattern = DS_PATTERN_SINE, .period_px = 12, .black_level = 0.05, .harmonic_gain = 0.45,
                        .open_field_dn_per_ms = 123.25 };
  g_autofree char *lines = ds_calibration_config_lines (&cal);
  g_assert_nonnull (strstr (lines, "\nopen-field-dn-per-ms=123.25\n"));
  g_autofree char *text = g_strconcat (lines, "backend=sim\n[camera]\nbackend=sim\n", NULL);
  g_autoptr (GError) error = NULL;
  g_autoptr (DsConfig) c = load_data (text, "calibrated.conf", &error);
  g_assert_no_error (error);
  g_assert_cmpfloat (c->open_field_dn_per_ms, ==, 123.25);
  DsCaptureSettings s;
  ds_capture_settings_from_config (&s, c);
  g_assert_cmpfloat (s.open_field_dn_per_ms, ==, 123.25);
  /* The calibration's JSON carries it, and refuses a bad one. */
  g_autoptr (JsonBuilder) b = json_builder_new ();
  json_builder_begin_object (b);
  ds_calibration_add_json_members (b, &cal);
  json_builder_end_object (b);
  g_autoptr (JsonNode) root = json_builder_get_root (b);
  DsCalibration back;
  g_assert_true (ds_calibration_from_json (json_node_get_object (root), &back, &error));
  g_assert_no_error (error);
  g_assert_cmpfloat (back.open_field_dn_per_ms, ==, 123.25);
  json_object_set_double_member (json_node_get_object (root), "open_field_dn_per_ms", -1);
  g_assert_false (ds_calibration_from_json (json_node_get_object (root), &back, &error));
  g_assert_nonnull (strstr (error->message, "open_field_dn_per_ms"));
  g_clear_error (&error);
  /* Not measured: no line, and a configuration without it knows no open field. */
  cal.open_field_dn_per_ms = 0;
  g_autofree char *without = ds_calibration_config_lines (&cal);
  g_assert_null (strstr (without, "open-field"));
  g_autoptr (DsConfig) d = load_data (SIM, "plain.conf", &error);
  g_assert_no_error (error);
  g_assert_true (isnan (d->open_field_dn_per_ms));
  ds_capture_settings_from_config (&s, d);
  g_assert_cmpfloat (s.open_field_dn_per_ms, ==, 0);
  expect_error ("[camera]\nbackend=sim\n[illuminator]\nopen-field-dn-per-ms=0\n", DS_CONFIG_ERROR_BAD_VALUE,
                (const char *const[]) { "open-field-dn-per-ms", "1e-06..1e+09", "line 4", NULL });
  expect_error ("[illuminator]\nopen-field-dn-per-ms=-3\n", DS_CONFIG_ERROR_BAD_VALUE,
                (const char *const[]) { "open-field-dn-per-ms", "line 2", NULL });
  expect_error ("[illuminator]\nopen-field-dn-per-ms=bright\n", DS_CONFIG_ERROR_BAD_VALUE,
                (const char *const[]) { "open-field-dn-per-ms", NULL });
}

/* The open field in the settings a capture takes from `text` (the rig's groups) and lines. */
static void
open_field_settings (const char *rig, const char *lines, DsCaptureSettings *s)
{
  g_autofree char *text = g_strconcat (rig, lines, NULL);
  g_autoptr (GError) error = NULL;
  g_autoptr (DsConfig) c = load_data (text, "format.conf", &error);
  g_assert_no_error (error);
  ds_capture_settings_from_config (s, c);
}

/* The open field's DN are the pixel format's it was measured in: calibrate names the format (in its
 * lines and its JSON), and under another [camera] pixel-format the settings carry no open field but
 * the reason, naming both; under the same one (in any case), or where the lines do not say (older
 * lines), it is used. The simulated camera's format is "simulated", whatever pixel-format says. */
static void
test_open_field_format (void)
{
  DsCalibration cal = { .pattern = DS_PATTERN_SQUARE, .period_px = 12, .duty = 0.5, .harmonic_gain = 0.6,
                        .open_field_dn_per_ms = 80.5 };
  g_strlcpy (cal.open_field_pixel_format, "Mono16", sizeof cal.open_field_pixel_format);
  g_autofree char *lines = ds_calibration_config_lines (&cal);
  g_assert_nonnull (strstr (lines, "\nopen-field-dn-per-ms=80.5\nopen-field-pixel-format=Mono16\n"));
#define ARAVIS(format)                                                                                            \
  "[camera]\nbackend=aravis\naddress=10.0.0.2\npixel-format=" format                                           \
  "\n[illuminator]\nbackend=modbus\nmodbus-uri=tcp://127.0.0.1:1502\n"
  const char *mono16 = ARAVIS ("Mono16"), *mono8 = ARAVIS ("Mono8");
#undef ARAVIS
  g_autofree char *body = g_strdup (strchr (lines, '\n') + 1); /* the lines without their group */
  DsCaptureSettings s;
  open_field_settings (mono16, body, &s);
  g_assert_cmpfloat (s.open_field_dn_per_ms, ==, 80.5);
  g_assert_cmpstr (s.open_field_unused, ==, "");
  open_field_settings (mono8, body, &s);
  g_assert_cmpfloat (s.open_field_dn_per_ms, ==, 0);
  g_assert_nonnull (strstr (s.open_field_unused, "measured in Mono16 and the camera delivers Mono8"));
  g_assert_nonnull (strstr (s.open_field_unused, "calibrate again in Mono8"));
  open_field_settings (mono16, "open-field-dn-per-ms=80.5\nopen-field-pixel-format=mono16\n", &s);
  g_assert_cmpfloat (s.open_field_dn_per_ms, ==, 80.5);
  open_field_settings (mono8, "open-field-dn-per-ms=80.5\n", &s);
  g_assert_cmpfloat (s.open_field_dn_per_ms, ==, 80.5);
  g_assert_cmpstr (s.open_field_unused, ==, "");
  open_field_settings (SIM, "[illuminator]\nopen-field-dn-per-ms=80.5\nopen-field-pixel-format=simulated\n", &s);
  g_assert_cmpfloat (s.open_field_dn_per_ms, ==, 80.5);
  open_field_settings (SIM "[camera]\npixel-format=Mono16\n",
                       "[illuminator]\nopen-field-dn-per-ms=80.5\nopen-field-pixel-format=Mono16\n", &s);
  g_assert_cmpfloat (s.open_field_dn_per_ms, ==, 0);
  g_assert_nonnull (strstr (s.open_field_unused, "camera delivers simulated"));
  /* The JSON carries the format and refuses one that is not a name. */
  g_autoptr (JsonBuilder) b = json_builder_new ();
  json_builder_begin_object (b);
  ds_calibration_add_json_members (b, &cal);
  json_builder_end_object (b);
  g_autoptr (JsonNode) root = json_builder_get_root (b);
  g_autoptr (GError) error = NULL;
  DsCalibration back;
  g_assert_true (ds_calibration_from_json (json_node_get_object (root), &back, &error));
  g_assert_no_error (error);
  g_assert_cmpstr (back.open_field_pixel_format, ==, "Mono16");
  json_object_set_int_member (json_node_get_object (root), "open_field_pixel_format", 16);
  g_assert_false (ds_calibration_from_json (json_node_get_object (root), &back, &error));
  g_assert_nonnull (strstr (error->message, "open_field_pixel_format"));
  /* Not said (an older daemon's JSON): "" */
  json_object_remove_member (json_node_get_object (root), "open_field_pixel_format");
  g_clear_error (&error);
  g_assert_true (ds_calibration_from_json (json_node_get_object (root), &back, &error));
  g_assert_cmpstr (back.open_field_pixel_format, ==, "");
}

/* The lens's acceptance angle: loaded, written back and loaded again to the same value, carried
 * by the capture settings (and their JSON) to the probe; absent, 0 (not known); a value outside
 * (0, 90] degrees or no number is refused naming the key, the range and the line. */
static void
test_acceptance_angle (void)
{
  g_autoptr (GError) error = NULL;
  g_autoptr (DsConfig) c =
    load_data ("[camera]\nbackend=sim\nacceptance-half-angle-deg=7.5\n[illuminator]\nbackend=sim\n", "lens.conf", &error);
  g_assert_no_error (error);
  g_assert_cmpfloat (c->acceptance_half_angle_deg, ==, 7.5);
  g_autofree char *text = ds_config_to_data (c);
  g_autoptr (DsConfig) back = load_data (text, "written.conf", &error);
  g_assert_no_error (error);
  g_assert_cmpfloat (back->acceptance_half_angle_deg, ==, 7.5);
  DsCaptureSettings s;
  ds_capture_settings_from_config (&s, back);
  g_assert_cmpfloat (s.acceptance_half_angle_deg, ==, 7.5);
  g_autoptr (JsonNode) json = ds_capture_settings_to_json (&s);
  g_assert_cmpfloat (json_object_get_double_member (json_node_get_object (json), "acceptance_half_angle_deg"), ==, 7.5);
  g_autoptr (DsConfig) d = load_data (SIM, "plain.conf", &error);
  g_assert_no_error (error);
  g_assert_true (isnan (d->acceptance_half_angle_deg));
  ds_capture_settings_from_config (&s, d);
  g_assert_cmpfloat (s.acceptance_half_angle_deg, ==, 0);
  expect_error ("[camera]\nbackend=sim\nacceptance-half-angle-deg=0\n", DS_CONFIG_ERROR_BAD_VALUE,
                (const char *const[]) { "acceptance-half-angle-deg", "0.01..90", "line 3", NULL });
  expect_error ("[camera]\nacceptance-half-angle-deg=95\n", DS_CONFIG_ERROR_BAD_VALUE,
                (const char *const[]) { "acceptance-half-angle-deg", "line 2", NULL });
  expect_error ("[camera]\nacceptance-half-angle-deg=wide\n", DS_CONFIG_ERROR_BAD_VALUE,
                (const char *const[]) { "acceptance-half-angle-deg", NULL });
}

/* The camera's noise model reaches the separation's per-pixel noise (system_gain > 0 turns it
 * on), and a declared speed the automatic operating point's settings; unset, neither is there. */
static void
test_noise_model_and_speed (void)
{
  g_autoptr (GError) error = NULL;
  g_autoptr (DsConfig) c = load_data (SIM "[camera]\ngain-dn-per-e=0.35\nread-noise-dn=2.5\n"
                                          "[acquisition]\nspeed-px-s=120\n", "noise.conf", &error);
  g_assert_no_error (error);
  DsCaptureSettings s;
  ds_capture_settings_from_config (&s, c);
  DsSeparationParams p;
  ds_capture_settings_separation_params (&s, &p);
  g_assert_cmpfloat (p.system_gain, ==, 0.35);
  g_assert_cmpfloat (p.read_noise_dn, ==, 2.5);
  g_assert_true (s.speed_declared);
  g_assert_cmpfloat (s.speed_px_s, ==, 120);
  /* The gain alone: read noise 0 (a camera whose shot noise dominates). */
  g_autoptr (DsConfig) g = load_data (SIM "[camera]\ngain-dn-per-e=2\n", "gain.conf", &error);
  g_assert_no_error (error);
  ds_capture_settings_from_config (&s, g);
  ds_capture_settings_separation_params (&s, &p);
  g_assert_cmpfloat (p.system_gain, ==, 2);
  g_assert_cmpfloat (p.read_noise_dn, ==, 0);
  g_autoptr (DsConfig) d = load_data (SIM, "plain.conf", &error);
  g_assert_no_error (error);
  ds_capture_settings_from_config (&s, d);
  ds_capture_settings_separation_params (&s, &p);
  g_assert_cmpfloat (p.system_gain, ==, 0);
  g_assert_cmpfloat (p.read_noise_dn, ==, 0);
  g_assert_false (s.speed_declared);
  expect_error (SIM "[camera]\nread-noise-dn=3\n", DS_CONFIG_ERROR_INCONSISTENT,
                (const char *const[]) { "read-noise-dn", "gain-dn-per-e", NULL });
  expect_error ("[camera]\ngain-dn-per-e=0\n", DS_CONFIG_ERROR_BAD_VALUE,
                (const char *const[]) { "gain-dn-per-e", NULL });
  expect_error ("[acquisition]\nspeed-px-s=-5\n", DS_CONFIG_ERROR_BAD_VALUE,
                (const char *const[]) { "speed-px-s", "0..1e+06", NULL });
}

/* GKeyFile merges a group given twice; descatterd refuses it with both lines, so that what a
 * reader finds in the file's first copy of a group is all of it. */
static void
test_groups_given_twice (void)
{
  g_autoptr (GError) error = NULL;
  g_autoptr (DsConfig) c = ds_config_load_data (SIM "[acquisition]\nphases=8\n[camera]\nexposure-us=700\n",
                                                "lab.conf", &error);
  g_assert_null (c);
  g_assert_error (error, DS_CONFIG_ERROR, DS_CONFIG_ERROR_SYNTAX);
  g_assert_nonnull (strstr (error->message, "lab.conf: line 7: group [camera] appears twice (first at line 1)"));
}

int
main (int argc, char **argv)
{
  g_test_init (&argc, &argv, NULL);
  example_path = argc > 1 ? argv[1] : "etc/descatterd.conf";
  g_test_add_func ("/config/defaults", test_defaults_are_the_simulated_lab);
  g_test_add_func ("/config/override", test_values_override_defaults);
  g_test_add_func ("/config/errors", test_errors_name_the_place);
  g_test_add_func ("/config/round-trip", test_round_trip);
  g_test_add_func ("/config/example", test_example_documents_every_key);
  g_test_add_func ("/config/reload-rule", test_reload_rule);
  g_test_add_func ("/config/refusals", test_refusals);
  g_test_add_func ("/config/calibration-lines-and-clip-level", test_calibration_lines_and_clip_level);
  g_test_add_func ("/config/file-limits", test_file_limits);
  g_test_add_func ("/config/noise-model-and-speed", test_noise_model_and_speed);
  g_test_add_func ("/config/open-field-line", test_open_field_line);
  g_test_add_func ("/config/open-field-format", test_open_field_format);
  g_test_add_func ("/config/acceptance-angle", test_acceptance_angle);
  g_test_add_func ("/config/groups-given-twice", test_groups_given_twice);
  return g_test_run ();
}
